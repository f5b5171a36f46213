"""Quality: stringbot's methods against the peers' real plans, all scored by one neutral yardstick.

For each test picture the peers' plans (``../shared/reference/peers/``:
ThreadTone, the paper's greedy baseline, with its own stopping rule;
marco-giunta/stringart at ThreadTone's line count; Prem-Dharshan/string-art
with the real 0.25 mm thread on 500 mm, its own line count) are read from
their JSON (``pin_xy``, ``crop``, ``sequence``) and every plan, theirs and
ours, is scored exactly as ``stringbot score`` scores it by default: against
the picture's luminance (``skimage.color.rgb2gray``'s weights, cropped as the
plan says, the target the peers plan against), the paper's SSIM (section
4.1) with Wang et al.'s Gaussian window and scikit-image's default window,
plain and blurred, and the as-woven error (the reference rendering at 512
px, both blurred by sigma 2 px, RMS over the frame; lower is better).
stringbot's methods run at ThreadTone's line count on the same picture (300
pins, 401 px, the default crop): ``fitness`` (the paper, style auto),
``greedy`` (ThreadTone as published, at its own 1001 px and gray) and
``residual`` (the default planner).  ``woven`` adds ``stringbot plan IMG
--machine grbl-ring`` as a user gets it (auto lines): its as-woven error is
compared with the best of the three peers.

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
sys.path.insert(0, str(ROOT))
from stringbot.planner.methods import METHODS  # noqa: E402
DEFAULT_PEERS = SHARED / "reference" / "peers"
PEERS = ("threadtone", "giunta", "premdharshan")
KEYS = ("ssim", "ssim_blurred", "ssim_uniform", "ssim_uniform_blurred", "woven_error")


def peer_plan(path):
    """A peer's plan-like JSON as a :class:`Plan` (only pins, frame, pin_xy, crop and sequence count)."""
    from stringbot.planner.plan_file import Plan

    d = json.loads(Path(path).read_text())
    return Plan(pins=d["pins"], frame=d.get("frame", "circle"), pin_xy=np.asarray(d["pin_xy"], dtype=float),
                crop=d["crop"], sequence=[int(p) for p in d["sequence"]], method=d.get("method", "peer"),
                stats={"seconds": d.get("seconds")})


def score_plan(plan, image):
    """Score a plan against its picture as `stringbot score` does: its own crop, the picture's luminance."""
    from stringbot.planner.model.scoring import score_picture

    return score_picture(plan, image, target="luminance")


def short_share(plan, fraction=30):
    """Share of chords spanning fewer than pins / fraction pins (10 of 300): the rim crowd."""
    c = np.asarray(plan.chord_list())
    d = np.abs(c[:, 0] - c[:, 1])
    return float(np.mean(np.minimum(d, plan.pins - d) < plan.pins / fraction))


def sheet_tile(plan, side):
    from skimage.transform import resize

    from stringbot.planner.model.scoring import woven_drawing

    return resize(woven_drawing(plan.chord_list(), plan.pin_xy, thread_fraction=plan.thread_model().fraction),
                  (side, side), anti_aliasing=True)


def source_tile(image, crop, side):
    from stringbot.planner.model.chords import frame_mask
    from stringbot.planner.model.scoring import LUMINANCE
    from stringbot.planner.picture.read import read_picture

    g = read_picture(image, size=side, crop=crop, gray="luminance", weights=LUMINANCE).gray / 255.0
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


def run_methods(path, methods, k, pins, size):
    """stringbot's plans of one picture at ``k`` lines (and ``woven``: as a user gets it), each method reading
    the picture as it does by default."""
    from stringbot.planner.build import plan_picture

    plans = {}
    for m in methods:
        t = time.perf_counter()
        if m == "woven":  # `stringbot plan IMG --machine grbl-ring`: the default method, auto lines, 500 / 0.25 mm
            p = plan_picture(path, pins=pins, size=size, diameter_mm=500.0, thread_mm=0.25)
        elif METHODS[m].size:  # its own working size (greedy: ThreadTone's 1001 px)
            p = plan_picture(path, pins=pins, lines=k, method=m)
        else:
            p = plan_picture(path, pins=pins, size=size, lines=k, method=m)
        p.stats["bench_seconds"] = round(time.perf_counter() - t, 2)
        plans[m] = p
    return plans


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", default=str(DEFAULT_IMAGES))
    ap.add_argument("--peers", default=str(DEFAULT_PEERS))
    ap.add_argument("--methods", default=",".join(METHODS) + ",woven",
                    help="stringbot methods to run (comma-separated): " + ", ".join(METHODS) + " (each at "
                         "ThreadTone's line count), woven (the default method as `stringbot plan IMG "
                         "--machine grbl-ring` makes it: auto lines)")
    ap.add_argument("--only", default=None, help="comma-separated picture names (default: all)")
    ap.add_argument("--pins", type=int, default=300)
    ap.add_argument("--size", type=int, default=401)
    ap.add_argument("--sheet", default=None, help="write a contact sheet PNG here (source | ThreadTone | giunta | "
                                                  "Prem-Dharshan | stringbot, all as woven)")
    ap.add_argument("--json", action="store_true")
    opts = ap.parse_args()

    from stringbot.planner.picture.read import read_picture

    methods = [m for m in opts.methods.split(",") if m]
    paths = sorted(p for p in Path(opts.images).iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg"))
    if opts.only:
        keep = set(opts.only.split(","))
        paths = [p for p in paths if p.stem in keep]
    results, rows, names = [], [], []
    for path in paths:
        crop = read_picture(path, size=32).crop  # the default crop (the source tile's)
        peers = {name: peer_plan(Path(opts.peers) / f"{name}_{path.stem}.json") for name in PEERS}
        k = len(peers["threadtone"].sequence) - 1
        plans = dict(peers)
        plans.update(run_methods(path, methods, k, opts.pins, opts.size))
        row = {"image": path.stem, "lines": k}
        for name, plan in plans.items():
            s = score_plan(plan, path)
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
            tiles = [source_tile(path, crop, 260)]
            tiles += [sheet_tile(plans[m], 260) for m in PEERS + ("woven",) if m in plans]
            rows.append(tiles)
            names.append(f"{path.stem}: " + ", ".join(f"{plans[m].stats.get('lines', len(plans[m].chord_list()))}"
                                                      for m in PEERS + ("woven",) if m in plans) + " lines")
    summary = {}
    for name in list(PEERS) + methods:
        if name == "woven":
            continue
        summary[name] = {key: round(float(np.mean([r[name][key] for r in results])), 4) for key in KEYS}
    for m in methods:
        if m == "woven":
            continue
        for peer in PEERS:
            summary[f"{m} - {peer}"] = {}
            for key in ("ssim", "ssim_uniform", "ssim_blurred", "ssim_uniform_blurred"):
                d = [r[m][key] - r[peer][key] for r in results]
                summary[f"{m} - {peer}"].update({f"{key}_mean": round(float(np.mean(d)), 4),
                                                 f"{key}_min": round(float(min(d)), 4)})
    if "woven" in methods:
        summary["woven / best peer"] = {r["image"]: round(r["woven"]["woven_error"] / min(
            r[p]["woven_error"] for p in PEERS), 3) for r in results}
        summary["best peer"] = {r["image"]: min(PEERS, key=lambda p: r[p]["woven_error"]) for r in results}
    if opts.json:
        print(json.dumps({"rows": results, "summary": summary}, indent=1))
    else:
        for name, v in summary.items():
            print(f"{name:<22} {v}")
    if opts.sheet:
        contact_sheet(rows, names, ["source (luminance)", "ThreadTone", "giunta", "Prem-Dharshan",
                                    "stringbot (auto lines)"], opts.sheet)
        if not opts.json:
            print(f"contact sheet -> {opts.sheet}")


if __name__ == "__main__":
    main()
