"""Colour thread paintings against Prem-Dharshan/string-art's colour plans, time, the contact sheet, dry runs.

Every plan, ours and the peer's, is scored the same way, as ``stringbot score``
scores a colour plan (:func:`stringbot.planner.colour.render.colour_score`):
drawn as it will hang by the reference rendering in colour (the real 0.25 mm
thread on a 500 mm ring, sharp, a later thread hiding what it covers) at
512 x 512, against the picture's crop read at 512 x 512 (the crop each plan
records), both blurred sigma 2 px in linear light; the mean CIEDE2000 over
the frame, and the SSIM of the luminances (plain and blurred, Wang's window).

* ``peers``: Prem-Dharshan's colour plans (``../shared/reference/peers/
  premdharshan_colour_*.json``: ``--colors 3``, its defaults; 33 and 67 runs)
  against ``stringbot plan PIC --colors auto:3 --lines L --crop ...
  --spool-changes B`` at its line count L, for budgets B = 2, 8, 32 (a fresh
  process each: wall and CPU time of the whole command, the load average
  noted).
* ``default``: ``stringbot plan PIC --colors auto:3`` as it comes (its own
  line count, 8 spool changes) on the colour pictures, with its time, and the
  default one-thread planner at the same line count scored in colour (black
  thread on a white board).
* ``sheet``: ``docs/colour-sheet.png``: source | Prem-Dharshan | stringbot (the
  plan of the ``peers`` table with 8 spool changes), each drawn by the
  reference rendering in colour.
* ``wind``: a colour plan in runs (a colour coming back) wound dry
  (``stringbot wind --yes --record``) on every bundled machine: the record
  must hold every run's pins, in order, each with its thread; the spool
  changes counted in the journal, the world's record and (G-code machines)
  the ``M0`` pauses of ``stringbot gcode``.

    python benchmarks/bench_colour.py                       # everything (~10 min on 2 busy cores)
    python benchmarks/bench_colour.py --only peers,sheet
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
SHARED = next((d / "shared" for d in ROOT.parents if (d / "shared" / "images").is_dir()), ROOT.parent / "shared")
IMAGES = SHARED / "images"
PEERS = SHARED / "reference" / "peers"
COLOUR_PICTURES = ["astronaut", "chelsea", "coffee", "logo"]
PEER_PICTURES = ["chelsea", "coffee"]
BUDGETS = (2, 8, 32)
MACHINES = ["grbl-ring", "grblhal-ring", "fluidnc-ring", "marlin-ring", "dynamixel-ring"]
SECTIONS = ("peers", "default", "sheet", "wind")


def stringbot(*args, check=True):
    """Run a stringbot command in a fresh process: (result, wall seconds); ``result.cpu``: its CPU seconds."""
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


def peer_plan(name):
    """Prem-Dharshan's colour plan of ``name`` as a :class:`Plan` (its runs as layers)."""
    from stringbot.planner.plan_file import Layer, Plan

    d = json.loads((PEERS / f"premdharshan_colour_{name}.json").read_text())
    layers = [Layer(lay["color"], [int(p) for p in lay["sequence"]]) for lay in d["layers"]]
    return Plan.from_layers(layers, background=d["background"], pins=d["pins"], frame=d.get("frame", "circle"),
                            pin_xy=np.asarray(d["pin_xy"], dtype=float), crop=d["crop"], method="prem-dharshan",
                            stats=d.get("stats", {}))


def score(plan, image):
    """The colour score of ``plan`` against ``image``, as ``stringbot score`` gives it."""
    from stringbot.planner.colour.render import SCORE_SIZE, colour_score, plan_layers
    from stringbot.planner.picture.read import read_picture

    pic = read_picture(image, size=SCORE_SIZE, crop=plan.crop, gray="luminance")
    return colour_score(plan_layers(plan), plan.pin_xy, pic.rgb, frame=plan.frame, background=plan.background,
                        thread_fraction=plan.thread_model().fraction)


def plan_cmd(image, out, *args):
    """``stringbot plan IMAGE -o OUT --colors auto:3 ARGS``: (plan, wall, CPU)."""
    from stringbot.planner import read_plan

    done, wall = stringbot("plan", image, "-o", out, "--colors", "auto:3", "--force", *args)
    return read_plan(out), wall, done.cpu


def fmt(s):
    return f"{s['delta_e']:.2f} / {s['ssim']:.3f} / {s['ssim_blurred']:.3f}"


def runs_text(plan):
    from stringbot.planner.colour.palette import color_name

    per = {c: sum(len(lay.sequence) - 1 for lay in plan.layers if lay.color == c) for c in dict.fromkeys(plan.colors)}
    return ", ".join(f"{color_name(c)} {n}" for c, n in per.items())


def peers(work):
    print("\n## Against Prem-Dharshan's colour plans, at its line count\n")
    print("| picture | plan | threads (lines) | runs | CIEDE2000 / SSIM / blurred SSIM | CIEDE2000 / Prem's "
          "| whole command: wall, CPU (load) |")
    print("|---|---|---|---|---|---|---|")
    out = {}
    for name in PEER_PICTURES:
        image = IMAGES / f"{name}.png"
        prem = peer_plan(name)
        ps = score(prem, image)
        lines = len(prem.chord_list())
        print(f"| {name} | Prem-Dharshan ({lines} lines) | {runs_text(prem)} | {len(prem.colors)} | {fmt(ps)} | 1 "
              f"| its own: {prem.stats.get('process_s', '?')} s |")
        crop = prem.crop
        for budget in BUDGETS:
            load = os.getloadavg()[0]
            plan, wall, cpu = plan_cmd(image, work / f"{name}-{budget}.json", "--lines", lines, "--crop",
                                       f"{crop['cx']:g},{crop['cy']:g},{crop['r']:g}", "--spool-changes", budget)
            s = score(plan, image)
            out[(name, budget)] = plan
            print(f"| {name} | stringbot, --spool-changes {budget} | {runs_text(plan)} | {len(plan.colors)} "
                  f"| **{fmt(s)}** | {s['delta_e'] / ps['delta_e']:.2f} | {wall:.1f} s, {cpu:.1f} s ({load:.1f}) |")
    return out


def default(work):
    print("\n## stringbot plan PIC --colors auto:3, as it comes\n")
    print("| picture | threads (lines) | runs | lines | CIEDE2000 / SSIM / blurred SSIM | black only at that count "
          "| whole command: wall, CPU (load) |")
    print("|---|---|---|---|---|---|---|")
    from stringbot.planner import read_plan

    for name in COLOUR_PICTURES:
        image = IMAGES / f"{name}.png"
        load = os.getloadavg()[0]
        plan, wall, cpu = plan_cmd(image, work / f"{name}-auto.json")
        s = score(plan, image)
        lines = len(plan.chord_list())
        stringbot("plan", image, "-o", work / f"{name}-black.json", "--lines", lines, "--crop",
                  f"{plan.crop['cx']:g},{plan.crop['cy']:g},{plan.crop['r']:g}", "--force")
        b = score(read_plan(work / f"{name}-black.json"), image)
        print(f"| {name} | {runs_text(plan)} | {len(plan.colors)} | {lines} | **{fmt(s)}** | {fmt(b)} "
              f"| {wall:.1f} s, {cpu:.1f} s ({load:.1f}) |")


def sheet(plans, path, side=360):
    from PIL import Image, ImageDraw

    from stringbot._files import write_atomic
    from stringbot.planner.colour.render import plan_layers, to_uint8, woven_rgb
    from stringbot.planner.model.chords import frame_mask
    from stringbot.planner.picture.read import read_picture

    titles = ["source", "Prem-Dharshan (its runs)", "stringbot, 8 spool changes"]
    pad, head = 8, 22
    rows = PEER_PICTURES
    img = Image.new("RGB", (len(titles) * (side + pad) + pad, head + len(rows) * (side + pad + 16) + pad), "white")
    d = ImageDraw.Draw(img)
    for k, t in enumerate(titles):
        d.text((pad + k * (side + pad) + side // 2 - 3 * len(t), 6), t, fill=(0, 0, 0))
    for r, name in enumerate(rows):
        prem, ours = peer_plan(name), plans[(name, 8)]
        src = read_picture(IMAGES / f"{name}.png", size=side, crop=prem.crop, gray="luminance").rgb
        src = np.where(frame_mask(side, "circle")[..., None], src, 1.0)
        tiles = [to_uint8(src)] + [to_uint8(woven_rgb(plan_layers(p), p.pin_xy, background=p.background, size=side,
                                                     thread_fraction=p.thread_model().fraction)) for p in (prem, ours)]
        y = head + r * (side + pad + 16)
        d.text((pad, y), f"{name}: {len(prem.chord_list())} lines each; Prem-Dharshan {len(prem.colors)} runs, "
                         f"stringbot {len(ours.colors)}", fill=(0, 0, 0))
        for k, tile in enumerate(tiles):
            img.paste(Image.fromarray(tile), (pad + k * (side + pad), y + 14))
    import io

    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=True)
    write_atomic(path, buf.getvalue())
    print(f"\ncontact sheet -> {path}")


def wind(work, name="coffee", lines=1500):
    from stringbot.planner import read_plan
    from stringbot.winding.journal import read_journal
    from stringbot.winding.layers import layer_problems

    path = work / f"dry-{name}.json"
    stringbot("plan", IMAGES / f"{name}.png", "-o", path, "--colors", "auto:3", "--lines", lines, "--force")
    plan = read_plan(path)
    print(f"\n## Dry runs of {name} --colors auto:3 --lines {lines}: {len(plan.colors)} runs of "
          f"{len(set(plan.colors))} colours ({runs_text(plan)}), {len(plan.sequence)} pins\n")
    print("| machine | exit | record = every run (pins, order, thread) | wraps | collisions "
          "| spool changes: journal / world | G-code pauses (M0) | wall |")
    print("|---|---|---|---|---|---|---|---|")
    for machine in MACHINES:
        record, journal = work / f"dry-{machine}.rec.json", work / f"dry-{machine}.journal"
        # one plan for every machine (--force: marlin-ring's thread is thinner for its ring than the plan's)
        done, wall = stringbot("wind", path, "--machine", machine, "--yes", "--force", "--record", record,
                               "--journal", journal, check=False)
        rec = json.loads(record.read_text())
        exact = ([w["pin"] for w in rec["wraps"]] == plan.sequence and layer_problems(plan, rec["wraps"]) is None
                 and not rec["collisions"])
        pauses = "-"
        if machine != "dynamixel-ring":
            g = work / f"dry-{machine}.gcode"
            stringbot("gcode", path, "--machine", machine, "--force", "-o", g)
            pauses = sum(1 for line in g.read_text().splitlines() if line == "M0")
        print(f"| {machine} | {done.returncode} | {'yes' if exact else 'NO'} | {len(rec['wraps'])} "
              f"| {len(rec['collisions'])} | {len(read_journal(journal).layers) - 1} / "
              f"{len(rec.get('spools', [])) - 1} | {pauses} | {wall:.1f} s |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=",".join(SECTIONS), help=f"sections, comma-separated: {', '.join(SECTIONS)}")
    ap.add_argument("--sheet", default=str(ROOT / "docs" / "colour-sheet.png"))
    args = ap.parse_args()
    only = args.only.split(",")
    print(f"# load average before: {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores)")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        stringbot("plan", IMAGES / "chelsea.png", "-o", work / "warm.json", "--colors", "auto:3", "--lines", 50)
        plans = peers(work) if "peers" in only or "sheet" in only else {}
        if "sheet" in only:
            sheet(plans, Path(args.sheet))
        if "default" in only:
            default(work)
        if "wind" in only:
            wind(work)
    print(f"\n# load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
