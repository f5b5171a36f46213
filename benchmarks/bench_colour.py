"""Colour thread paintings: quality against black-only and a per-channel baseline, time, dry runs.

For each colour picture (the colour ones of the shared test set and pictures
read from ``skimage.data`` at run time), through the command line as a user
runs it:

* ``stringbot plan PIC --colors auto:N`` (whole command, wall time, fresh
  process, warm chord cache), then ``stringbot score`` (mean CIEDE2000 as
  woven, blurred; luminance SSIM, plain and blurred);
* black only: ``stringbot plan PIC --lines K`` (the default one-thread
  planner) with K the colour plan's line count, scored in colour
  (``score --colour``: black thread on a white board, as woven); and, for
  reference, ``stringbot plan PIC`` at its own (automatic) line count;
* per channel: each thread of the colour plan planned alone by the default
  one-thread planner against its own share of the picture (the picture
  unmixed into the threads' coverages, :func:`stringbot.planner.colour.model.unmix`,
  each coverage map read as a gray picture), with the colour plan's lines
  shared in proportion to the coverage, the layers stacked in the colour
  plan's order and scored the same way (library calls: there is no command
  for it).

Then a 3-colour plan wound dry (``stringbot wind --yes --record``) on every
bundled machine: the record must hold every layer's pins, in order, each with
its layer's thread; the spool changes counted in the journal, the world's
record and (G-code machines) the ``M0`` pauses of ``stringbot gcode``.

    python benchmarks/bench_colour.py                  # everything (~15 min on 2 busy cores)
    python benchmarks/bench_colour.py --wind-only      # the dry runs
    python benchmarks/bench_colour.py --pictures chelsea,rocket --no-wind
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SHARED = Path("/work/shared/images")
SHARED_COLOUR = ["astronaut", "chelsea", "coffee", "logo"]
EXTRA = ["rocket", "immunohistochemistry", "colorwheel"]     # skimage.data, read at run time
MACHINES = ["grbl-ring", "grblhal-ring", "fluidnc-ring", "marlin-ring", "dynamixel-ring"]


def stringbot(*args, check=True):
    """Run a stringbot command in a fresh process: (result, wall seconds, CPU seconds of the process)."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", *map(str, args)],
                          capture_output=True, text=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    done.cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if check and done.returncode != 0:
        raise SystemExit(f"stringbot {' '.join(map(str, args))} failed ({done.returncode}): {done.stderr.strip()}")
    return done, wall


def picture_path(name, folder):
    if (SHARED / f"{name}.png").exists():
        return SHARED / f"{name}.png"
    import skimage.data
    from PIL import Image

    img = getattr(skimage.data, name)()
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3]
    path = folder / f"{name}.png"
    Image.fromarray(np.asarray(img, dtype=np.uint8)).save(path)
    return path


def per_channel(pic_path, plan):
    """Each thread planned alone (default one-thread planner) on its unmixed share; layers stacked."""
    from stringbot.planner.build import plan_picture
    from stringbot.planner.colour.model import unmix
    from stringbot.planner.colour.palette import hex_to_rgb, to_linear
    from stringbot.planner.colour.render import SCORE_SIZE, colour_score
    from stringbot.planner.model.chords import frame_mask
    from stringbot.planner.picture.read import Picture, read_picture

    size = plan.parameters["size"]
    pic = read_picture(pic_path, size=size, crop=plan.crop, gray="luminance")
    mask = frame_mask(size, plan.frame)
    colors = np.array([to_linear(hex_to_rgb(c)) for c in plan.colors])
    alpha, _, _ = unmix(to_linear(pic.rgb.reshape(-1, 3)), to_linear(hex_to_rgb(plan.background)), colors)
    alpha = alpha.reshape(len(colors), size, size) * mask
    total = plan.stats["lines"]
    mass = alpha.reshape(len(colors), -1).sum(axis=1)
    share = np.maximum(1, np.round(total * mass / max(mass.sum(), 1e-9))).astype(int)
    layers = []
    for color, a, k in zip(plan.colors, alpha, share):
        gray = Picture(np.clip(255.0 * (1.0 - a), 0, 255).astype(np.float32), plan.crop, pic.source, "gray")
        p = plan_picture(pic_path, pins=plan.pins, frame=plan.frame, size=size, lines=int(k), picture=gray,
                         reference=gray)
        layers.append((color, p.chord_list()))
    ref = read_picture(pic_path, size=SCORE_SIZE, crop=plan.crop, gray="luminance")
    width = plan.thread_model().fraction
    return colour_score(layers, plan.pin_xy, ref.rgb, frame=plan.frame, background=plan.background, width=width)


def quality(names, n, work):
    from stringbot.planner import read_plan
    from stringbot.planner.colour.palette import color_name

    rows = []
    for name in names:
        pic = picture_path(name, work)
        cplan = work / f"{name}-c.json"
        done, wall = stringbot("plan", pic, "-o", cplan, "--colors", f"auto:{n}")
        plan = read_plan(cplan)
        sc = json.loads(stringbot("score", cplan, pic, "--json")[0].stdout)
        k = plan.stats["lines"]
        bplan = work / f"{name}-b.json"
        stringbot("plan", pic, "-o", bplan, "--lines", k)
        sb = json.loads(stringbot("score", bplan, pic, "--colour", "--json")[0].stdout)
        aplan = work / f"{name}-a.json"
        stringbot("plan", pic, "-o", aplan)
        sa = json.loads(stringbot("score", aplan, pic, "--colour", "--json")[0].stdout)
        sp = per_channel(pic, plan)
        rows.append({"picture": name, "threads": " > ".join(color_name(c) for c in plan.colors),
                     "lines": k, "per_layer": [lay["lines"] for lay in plan.stats["layers"]],
                     "colour": sc, "black": sb, "black_auto": sa, "channel": sp,
                     "changes": plan.stats["spool_changes"], "plan_s": wall, "plan_cpu": done.cpu,
                     "planner_s": plan.stats["seconds"]})
        print(f"  {name}: done ({wall:.1f} s)", file=sys.stderr, flush=True)
    return rows


def dry_runs(name, n, lines, work):
    from stringbot.planner import read_plan
    from stringbot.winding.journal import read_journal
    from stringbot.winding.layers import layer_problems

    pic = picture_path(name, work)
    path = work / f"dry-{name}.json"
    stringbot("plan", pic, "-o", path, "--colors", f"auto:{n}", "--lines", lines)
    plan = read_plan(path)
    out = []
    for machine in MACHINES:
        record = work / f"dry-{machine}.rec.json"
        journal = work / f"dry-{machine}.journal"
        # one plan for every machine (--force: marlin-ring's thread is thinner for its ring than the plan's)
        done, wall = stringbot("wind", path, "--machine", machine, "--yes", "--force", "--record", record,
                               "--journal", journal, check=False)
        rec = json.loads(record.read_text())
        pins_ok = [w["pin"] for w in rec["wraps"]] == plan.sequence
        exact = pins_ok and layer_problems(plan, rec["wraps"]) is None and not rec["collisions"]
        changes_journal = len(read_journal(journal).layers) - 1
        changes_world = len(rec.get("spools", [])) - 1
        pauses = "-"
        if machine != "dynamixel-ring":
            g = work / f"dry-{machine}.gcode"
            stringbot("gcode", path, "--machine", machine, "--force", "-o", g)
            pauses = sum(1 for line in g.read_text().splitlines() if line == "M0")
        out.append({"machine": machine, "exit": done.returncode, "exact": exact, "wraps": len(rec["wraps"]),
                    "collisions": len(rec["collisions"]), "changes_journal": changes_journal,
                    "changes_world": changes_world, "gcode_pauses": pauses, "wall": wall,
                    "layers": len(plan.colors)})
    return plan, out


def table(rows):
    print("\n| picture | threads (winding order) | lines | CIEDE2000 colour / black only / per channel "
          "(black at its own line count) | luminance SSIM colour / black / channel (own) "
          "| blurred SSIM colour / black / channel (own) | spool changes | plan: wall, CPU (planner) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        c, b, p, a = r["colour"], r["black"], r["channel"], r["black_auto"]
        print(f"| {r['picture']} | {r['threads']} ({'/'.join(map(str, r['per_layer']))}) | {r['lines']} "
              f"| **{c['delta_e']:.2f}** / {b['delta_e']:.2f} / {p['delta_e']:.2f} ({a['delta_e']:.2f} at {a['lines']}) "
              f"| {c['ssim']:.3f} / {b['ssim']:.3f} / {p['ssim']:.3f} ({a['ssim']:.3f}) "
              f"| {c['ssim_blurred']:.3f} / {b['ssim_blurred']:.3f} / {p['ssim_blurred']:.3f} ({a['ssim_blurred']:.3f}) "
              f"| {r['changes']} | {r['plan_s']:.1f} s, {r['plan_cpu']:.1f} s ({r['planner_s']:.1f} s) |")
    avg = {k: np.mean([r[k]["delta_e"] for r in rows]) for k in ("colour", "black", "channel", "black_auto")}
    print(f"| **mean** | | | **{avg['colour']:.2f}** / {avg['black']:.2f} / {avg['channel']:.2f} "
          f"({avg['black_auto']:.2f}) | | | | |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pictures", default=",".join(SHARED_COLOUR + EXTRA[:2]))
    ap.add_argument("--colors", type=int, default=3, help="threads per plan (auto:N)")
    ap.add_argument("--no-wind", action="store_true", help="skip the dry runs")
    ap.add_argument("--wind-picture", default="coffee")
    ap.add_argument("--wind-lines", type=int, default=1500)
    ap.add_argument("--wind-only", action="store_true", help="only the dry runs")
    args = ap.parse_args()
    print(f"# load average before: {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores)")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        stringbot("plan", SHARED / "camera.png", "-o", work / "warm.json")   # fill the chord cache
        if not args.wind_only:
            table(quality(args.pictures.split(","), args.colors, work))
            print(f"# load average after: {os.getloadavg()[0]:.2f}")
        if args.no_wind:
            return
        plan, out = dry_runs(args.wind_picture, args.colors, args.wind_lines, work)
        print(f"\ndry runs of {args.wind_picture} --colors auto:{args.colors} --lines {args.wind_lines}: "
              f"{len(plan.colors)} layers ({', '.join(plan.colors)}), {len(plan.sequence)} pins\n")
        print("| machine | exit | record = every layer (pins, order, thread) | wraps | collisions "
              "| spool changes: journal / world | G-code pauses (M0) | wall |")
        print("|---|---|---|---|---|---|---|---|")
        for o in out:
            print(f"| {o['machine']} | {o['exit']} | {'yes' if o['exact'] else 'NO'} | {o['wraps']} | {o['collisions']} "
                  f"| {o['changes_journal']} / {o['changes_world']} | {o['gcode_pauses']} | {o['wall']:.1f} s |")


if __name__ == "__main__":
    main()
