"""Quality: fitness vs greedy on every test picture, SSIM as in the paper's section 4.1.

For each picture: greedy with the paper's automatic line count, then fitness
(and, with --disconnected, its chord-set variant) with exactly as many lines
as greedy drew; both scored by SSIM (plain and blurred).  Fitness runs with
its default style (auto: the better of detail and fill); the table also gives
which style was kept and the detail style alone (the paper's knobs as given).  Prints a table, the
average margins, the share of short chords (span < pins / 30, the rim
crowd the beta term is there to prevent) and the share of each drawing's
thread pixels (at the working size) lying on white (gray > 230) parts of the
picture, against the white share of the picture itself; with --sheet PATH writes a contact sheet
(source | greedy | fitness) for the README.

Usage: python benchmarks/quality_table.py [--images DIR] [--sheet docs/contact-sheet.png] [--json]
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_IMAGES = ROOT.parent / "shared" / "images"


def short_share(plan, fraction=30):
    """Share of chords spanning fewer than pins / fraction pins (10 of 300): the rim crowd."""
    c = np.asarray(plan.chord_list())
    d = np.abs(c[:, 0] - c[:, 1])
    span = np.minimum(d, plan.pins - d)
    return float(np.mean(span < plan.pins / fraction))


def white_share(plan, gray, level=230):
    """Share of the drawing's thread pixels (at the working size) lying on white (gray > level) picture pixels."""
    from stringbot.planner.render import draw

    thread = draw(plan, size=gray.shape[0]) == 0
    return float(np.mean(gray[thread] > level)) if thread.any() else 0.0


def row_images(pic_gray, plans, frame, side):
    from skimage.transform import resize

    from stringbot.planner.fitness import frame_mask
    from stringbot.planner.render import draw

    g = np.where(frame_mask(pic_gray.shape[0], frame), pic_gray / 255.0, 1.0)
    tiles = [resize(g, (side, side), anti_aliasing=True)]
    tiles += [resize(draw(p, size=1001) / 255.0, (side, side), anti_aliasing=True) for p in plans]
    return tiles


def contact_sheet(rows, names, titles, path, side=260):
    from PIL import Image, ImageDraw

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
    from stringbot._files import write_atomic
    write_atomic(path, buf.getvalue())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", default=str(DEFAULT_IMAGES))
    ap.add_argument("--pins", type=int, default=300)
    ap.add_argument("--size", type=int, default=401)
    ap.add_argument("--disconnected", action="store_true", help="also score the disconnected variant")
    ap.add_argument("--sheet", default=None, help="write a contact sheet PNG here")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--greedy-literal", action="store_true",
                    help="greedy lowers 15 per thread at the working size (not scaled from ThreadTone's 500-px radius)")
    opts = ap.parse_args()

    from stringbot.planner.build import plan_picture
    from stringbot.planner.fitness import frame_mask
    from stringbot.planner.image import read_picture
    from stringbot.planner.render import score

    paths = sorted(p for p in Path(opts.images).iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg"))
    results, rows, names = [], [], []
    for path in paths:
        pic = read_picture(path, size=opts.size)
        t = time.perf_counter()
        greedy = plan_picture(path, pins=opts.pins, size=opts.size, method="greedy", picture=pic,
                              greedy_reference_radius=None if opts.greedy_literal else 500.0)
        k = greedy.stats["lines"]
        ref = read_picture(path, size=201, weights=pic.weights)  # as `stringbot score` reads it
        fitness = plan_picture(path, pins=opts.pins, size=opts.size, lines=k, picture=pic, reference=ref)
        plans = [greedy, fitness]
        if opts.disconnected:
            plans.append(plan_picture(path, pins=opts.pins, size=opts.size, lines=k, disconnected=True, picture=pic,
                                      reference=ref))
        scores = [score(p, ref.gray) for p in plans]
        style = fitness.parameters["style"]
        detail = scores[1] if style == "detail" else score(
            plan_picture(path, pins=opts.pins, size=opts.size, lines=k, picture=pic, style="detail"), ref.gray)
        r = {"image": path.name, "lines_auto": greedy.parameters["lines_target"], "lines": k,
             "short_greedy": short_share(greedy), "short_fitness": short_share(fitness),
             "white_picture": float(np.mean(pic.gray[frame_mask(opts.size, "circle")] > 230)),
             "white_greedy": white_share(greedy, pic.gray), "white_fitness": white_share(fitness, pic.gray),
             "greedy": scores[0]["ssim"], "fitness": scores[1]["ssim"],
             "greedy_blurred": scores[0]["ssim_blurred"], "fitness_blurred": scores[1]["ssim_blurred"],
             "style": style, "detail": detail["ssim"], "detail_blurred": detail["ssim_blurred"],
             "seconds": round(time.perf_counter() - t, 2)}
        if opts.disconnected:
            r.update(disconnected=scores[2]["ssim"], disconnected_blurred=scores[2]["ssim_blurred"])
        results.append(r)
        if opts.sheet:
            rows.append(row_images(pic.gray, plans, "circle", 260))
            names.append(f"{path.name}: {k} lines")
        if not opts.json:
            extra = (f"  disc {r['disconnected']:.3f} {r['disconnected_blurred']:.3f}" if opts.disconnected else "")
            print(f"{path.name:<16} lines {k:5d}  SSIM greedy {r['greedy']:.3f} fitness {r['fitness']:.3f} "
                  f"({r['fitness'] - r['greedy']:+.3f})  blurred greedy {r['greedy_blurred']:.3f} "
                  f"fitness {r['fitness_blurred']:.3f} ({r['fitness_blurred'] - r['greedy_blurred']:+.3f})  "
                  f"short chords greedy {100 * r['short_greedy']:.0f}% fitness {100 * r['short_fitness']:.0f}%  "
                  f"thread on white greedy {100 * r['white_greedy']:.0f}% fitness {100 * r['white_fitness']:.0f}% "
                  f"(picture {100 * r['white_picture']:.0f}%)  style {style} (detail alone {r['detail']:.3f} "
                  f"{r['detail_blurred']:.3f}){extra}")
            sys.stdout.flush()
    plain = np.mean([r["fitness"] - r["greedy"] for r in results])
    blurred = np.mean([r["fitness_blurred"] - r["greedy_blurred"] for r in results])
    wins = sum(r["fitness"] > r["greedy"] and r["fitness_blurred"] > r["greedy_blurred"] for r in results)
    d_plain = np.mean([r["detail"] - r["greedy"] for r in results])
    d_blurred = np.mean([r["detail_blurred"] - r["greedy_blurred"] for r in results])
    if opts.json:
        print(json.dumps({"rows": results, "margin": plain, "margin_blurred": blurred, "wins": wins,
                          "detail_margin": d_plain, "detail_margin_blurred": d_blurred}, indent=1))
    else:
        print(f"average margin (fitness - greedy): SSIM {plain:+.3f}, blurred {blurred:+.3f}; "
              f"fitness wins both on {wins} of {len(results)} pictures\n"
              f"detail style alone (the paper's knobs): SSIM {d_plain:+.3f}, blurred {d_blurred:+.3f}")
    if opts.sheet:
        titles = ["source", "greedy", "fitness"] + (["disconnected"] if opts.disconnected else [])
        contact_sheet(rows, names, titles, opts.sheet)
        if not opts.json:
            print(f"contact sheet -> {opts.sheet}")


if __name__ == "__main__":
    main()
