"""Quality: stringbot's methods against the peers' real plans, all scored by one scorer.

For each test picture the peers' plans (``../shared/reference/peers/``:
ThreadTone, the paper's greedy baseline, with its own stopping rule, and
marco-giunta/stringart at ThreadTone's line count) are read from their JSON
(``pin_xy``, ``crop``, ``sequence``) and scored exactly as ``stringbot
score`` scores a plan: the paper's SSIM (section 4.1) with Wang et al.'s
Gaussian window and scikit-image's default window, plain and blurred, and the
as-woven error (lower is better).  stringbot's methods run at ThreadTone's
line count on the same picture (300 pins, 401 px, the default crop):
``fitness`` (the paper, style auto), ``greedy`` (ThreadTone as published, at
its own 1001 px and luminance gray) and ``residual`` (the default planner).  ``woven`` adds ``stringbot plan IMG
--machine grbl-ring`` as a user gets it (auto lines): its as-woven error is
compared with the better of the two peers.

Usage: python benchmarks/quality_table.py [--methods fitness,greedy,residual,woven] [--images DIR]
           [--sheet docs/contact-sheet.png] [--json]
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = next((d / "shared" for d in ROOT.parents if (d / "shared" / "images").is_dir()), ROOT.parent / "shared")
DEFAULT_IMAGES = SHARED / "images"
DEFAULT_PEERS = SHARED / "reference" / "peers"
PEERS = ("threadtone", "giunta")
KEYS = ("ssim", "ssim_blurred", "ssim_uniform", "ssim_uniform_blurred", "woven_error")


def peer_plan(path):
    """A peer's plan-like JSON as a :class:`Plan` (only pins, frame, pin_xy, crop and sequence count)."""
    from stringbot.planner.plan_file import Plan

    d = json.loads(Path(path).read_text())
    return Plan(pins=d["pins"], frame=d.get("frame", "circle"), pin_xy=np.asarray(d["pin_xy"], dtype=float),
                crop=d["crop"], sequence=[int(p) for p in d["sequence"]], method=d.get("method", "peer"),
                stats={"seconds": d.get("seconds")})


def score_plan(plan, image, weights):
    """Score a plan against its picture as `stringbot score` does (its own crop, the picture's gray)."""
    from stringbot.planner.image import read_picture
    from stringbot.planner.scoring import SCORE_SIZE, WOVEN_SIZE, score

    ref = read_picture(image, size=SCORE_SIZE, crop=plan.crop, weights=weights)
    woven = read_picture(image, size=WOVEN_SIZE, crop=plan.crop, weights=weights)
    return score(plan, ref.gray, woven_gray=woven.gray)


def short_share(plan, fraction=30):
    """Share of chords spanning fewer than pins / fraction pins (10 of 300): the rim crowd."""
    c = np.asarray(plan.chord_list())
    d = np.abs(c[:, 0] - c[:, 1])
    return float(np.mean(np.minimum(d, plan.pins - d) < plan.pins / fraction))


def sheet_tile(plan, side):
    from skimage.transform import resize

    from stringbot.planner.scoring import woven_drawing

    return resize(woven_drawing(plan.chord_list(), plan.pin_xy, thread_fraction=plan.thread_model().fraction),
                  (side, side), anti_aliasing=True)


def source_tile(image, crop, weights, side):
    from stringbot.planner.fitness import frame_mask
    from stringbot.planner.image import read_picture

    g = read_picture(image, size=side, crop=crop, weights=weights).gray / 255.0
    return np.where(frame_mask(side, "circle"), g, 1.0)


def contact_sheet(rows, names, titles, path, side=260):
    from PIL import Image, ImageDraw

    from stringbot._files import write_atomic

    pad, head = 8, 22
    w = len(titles) * (side + pad) + pad
    h = head + len(rows) * (side + pad + 16) + pad
    sheet = Image.new("L", (w, h), 255)
    d = ImageDraw.Draw(sheet)
    for k, t in enumerate(titles):
        d.text((pad + k * (side + pad) + side // 2 - 3 * len(t), 6), t, fill=0)
    for r, (tiles, name) in enumerate(zip(rows, names)):
        y = head + r * (side + pad + 16)
        d.text((pad, y), name, fill=0)
        for k, tile in enumerate(tiles):
            sheet.paste(Image.fromarray((np.clip(tile, 0, 1) * 255).astype(np.uint8)), (pad + k * (side + pad), y + 14))
    buf = __import__("io").BytesIO()
    # 16 gray levels (4-bit PNG): a third of the size, no visible difference for thread drawings
    small = sheet.quantize(colors=16, method=Image.Quantize.MEDIANCUT)
    small.save(buf, format="PNG", optimize=True, bits=4)
    write_atomic(path, buf.getvalue())


def run_methods(path, methods, k, pic, pins, size):
    """stringbot's plans of one picture at ``k`` lines (and ``woven``: as a user gets it)."""
    from stringbot.planner.build import plan_picture

    plans = {}
    for m in methods:
        t = time.perf_counter()
        if m == "woven":  # `stringbot plan IMG --machine grbl-ring`: the default method, auto lines, 500 / 0.25 mm
            p = plan_picture(path, pins=pins, size=size, picture=pic, diameter_mm=500.0, thread_mm=0.25)
        elif m == "greedy":  # ThreadTone's own working size and gray (1001 px, luminance)
            p = plan_picture(path, pins=pins, lines=k, method=m)
        else:
            p = plan_picture(path, pins=pins, size=size, lines=k, method=m, picture=pic)
        p.stats["bench_seconds"] = round(time.perf_counter() - t, 2)
        plans[m] = p
    return plans


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", default=str(DEFAULT_IMAGES))
    ap.add_argument("--peers", default=str(DEFAULT_PEERS))
    ap.add_argument("--methods", default="fitness,greedy,residual,woven",
                    help="stringbot methods to run (comma-separated): fitness, greedy, residual (the default "
                         "method at ThreadTone's line count), woven (the default method as `stringbot plan IMG "
                         "--machine grbl-ring` makes it: auto lines)")
    ap.add_argument("--only", default=None, help="comma-separated picture names (default: all)")
    ap.add_argument("--pins", type=int, default=300)
    ap.add_argument("--size", type=int, default=401)
    ap.add_argument("--sheet", default=None, help="write a contact sheet PNG here (source | ThreadTone | fitness | "
                                                  "default, as woven)")
    ap.add_argument("--json", action="store_true")
    opts = ap.parse_args()

    from stringbot.planner.image import read_picture

    methods = [m for m in opts.methods.split(",") if m]
    paths = sorted(p for p in Path(opts.images).iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg"))
    if opts.only:
        keep = set(opts.only.split(","))
        paths = [p for p in paths if p.stem in keep]
    results, rows, names = [], [], []
    for path in paths:
        pic = read_picture(path, size=opts.size)
        peers = {name: peer_plan(Path(opts.peers) / f"{name}_{path.stem}.json") for name in PEERS}
        k = len(peers["threadtone"].sequence) - 1
        plans = dict(peers)
        plans.update(run_methods(path, methods, k, pic, opts.pins, opts.size))
        row = {"image": path.stem, "lines": k}
        for name, plan in plans.items():
            s = score_plan(plan, path, pic.weights)
            row[name] = {key: round(s[key], 4) for key in KEYS}
            row[name].update(lines=s["lines"], short=round(short_share(plan), 3),
                             seconds=plan.stats.get("bench_seconds", plan.stats.get("seconds")))
        results.append(row)
        if not opts.json:
            print(f"{path.stem} ({k} lines at ThreadTone's count)")
            for name in plans:
                r = row[name]
                print(f"  {name:<11} lines {r['lines']:5d}  SSIM {r['ssim']:.3f} / {r['ssim_blurred']:.3f}  "
                      f"7x7 {r['ssim_uniform']:.3f} / {r['ssim_uniform_blurred']:.3f}  woven {r['woven_error']:.4f}"
                      f"  short {100 * r['short']:.0f}%  {r['seconds']} s")
            sys.stdout.flush()
        if opts.sheet:
            tiles = [source_tile(path, pic.crop, pic.weights, 260)]
            tiles += [sheet_tile(plans[m], 260) for m in ("threadtone", "fitness", "woven") if m in plans]
            rows.append(tiles)
            names.append(f"{path.stem}: {k} lines")
    summary = {}
    for name in list(PEERS) + methods:
        if name == "woven":
            continue
        summary[name] = {key: round(float(np.mean([r[name][key] for r in results])), 4) for key in KEYS}
    for m in methods:
        if m == "woven":
            continue
        for peer in PEERS:
            d = [r[m]["ssim"] - r[peer]["ssim"] for r in results]
            summary[f"{m} - {peer}"] = {"ssim_mean": round(float(np.mean(d)), 4), "ssim_min": round(float(min(d)), 4),
                                        "ssim_blurred_mean": round(float(np.mean(
                                            [r[m]["ssim_blurred"] - r[peer]["ssim_blurred"] for r in results])), 4)}
    if "woven" in methods:
        summary["woven / best peer"] = {r["image"]: round(r["woven"]["woven_error"] / min(
            r[p]["woven_error"] for p in PEERS), 3) for r in results}
    if opts.json:
        print(json.dumps({"rows": results, "summary": summary}, indent=1))
    else:
        for name, v in summary.items():
            print(f"{name:<22} {v}")
    if opts.sheet:
        contact_sheet(rows, names, ["source", "ThreadTone", "paper fitness", "default (auto lines)"], opts.sheet)
        if not opts.json:
            print(f"contact sheet -> {opts.sheet}")


if __name__ == "__main__":
    main()
