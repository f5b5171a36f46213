"""The thread calibration on synthetic photos of a full-size sheet: the width error table.

Each case renders the sheet of ``--machine`` (default grbl-ring: 300 pins on 500 mm) as a camera would
see it (benchmarks/calibration_photos.py: a perspective, sharp opaque threads of a known width, uneven
light, blur, noise, 8-bit sRGB; some cases JPEG, a thread that lets light through, a sheet laid off
the pins), writes it, and runs ``stringbot calibrate fit`` on it in its own process, as a maker would.
It prints one row per case: the true and fitted width, the error, the board's and thread's
reflectances (true / fitted) and the fit's RMS.

    python benchmarks/bench_calibrate.py                 # the table
    python benchmarks/bench_calibrate.py --quick         # four cases
    python benchmarks/bench_calibrate.py --photo sheet-photo.png --width-mm 0.3   # one photo, to try the fit
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from calibration_photos import camera, render_photo  # noqa: E402
from firmware_protocol.machine import load_machine  # noqa: E402
from stringbot.planner.calibration.sheet import design_sheet  # noqa: E402

SHAPE = (1800, 2400)
#: (width mm, camera, light, extras): camera = (tilt lr, tilt tb, turn deg), light = (gradient, direction, vignette).
#: "Front" views are turned half a degree: the renderer samples points, and a thread lying exactly along a
#: row of samples would come out a whole number of samples wide (a sensor integrates; it would not).
CASES = [
    (0.15, (0.00, 0.00, 0.5), (0.0, 0.0, 0.0), {}),
    (0.15, (0.10, -0.06, -8.0), (0.5, 30.0, 0.3), {}),
    (0.20, (-0.12, 0.08, 5.0), (0.6, 200.0, 0.4), {"noise": 0.02}),
    (0.25, (0.08, 0.10, 90.0), (0.4, 300.0, 0.3), {}),
    (0.25, (0.10, -0.06, -8.0), (0.5, 30.0, 0.3), {"jpeg": 85}),
    (0.25, (0.10, -0.06, -8.0), (0.5, 30.0, 0.3), {"shape": (900, 1200)}),
    (0.25, (0.10, -0.06, -8.0), (0.5, 30.0, 0.3), {"offset_mm": (1.5, 2.5)}),
    (0.30, (0.15, 0.00, 178.0), (0.7, 90.0, 0.4), {"blur": 1.6}),
    (0.35, (-0.05, -0.12, 12.0), (0.5, 150.0, 0.3), {"thread": 0.12, "board": 0.6}),
    (0.40, (0.10, -0.06, -8.0), (0.5, 30.0, 0.3), {"opacity": 0.75}),
    (0.50, (0.12, 0.12, -20.0), (0.6, 250.0, 0.5), {}),
    (0.50, (0.00, 0.00, 0.5), (0.0, 0.0, 0.0), {"jpeg": 85, "noise": 0.02}),
]
QUICK = [0, 3, 6, 10]


def make_photo(path, machine, width, cam, light, extra, *, rng=0):
    """Write one synthetic photo of ``machine``'s sheet; returns the true (board, thread) relative to paper."""
    m = load_machine(machine)
    sheet = design_sheet(pins=m.pins, diameter_mm=m["ring.diameter_mm"], pin_diameter_mm=m["ring.pin_diameter_mm"],
                         thread_mm=m["thread.diameter_mm"])
    extra = dict(extra)
    shape = extra.pop("shape", SHAPE)
    jpeg = extra.pop("jpeg", None)
    tilt_lr, tilt_tb, turn = cam
    fill = 0.9 / (abs(np.cos(np.radians(turn))) + abs(np.sin(np.radians(turn)))) / (1 + max(abs(tilt_lr),
                                                                                         abs(tilt_tb)))
    tf = camera(sheet, shape, tilt=(tilt_lr, tilt_tb), turn=turn, fill=fill)
    kw = dict(board=0.80, thread=0.03, paper=0.95, k=3 if max(shape) <= 2400 else 2)
    kw.update(extra)
    img = render_photo(sheet, tf, shape, width_mm=width, gradient=light[:2], vignette=light[2], rng=rng, **kw)
    if jpeg:
        Image.fromarray(img).save(path, quality=jpeg)
    else:
        Image.fromarray(img).save(path)
    return kw["board"] / kw["paper"], kw["thread"] / kw["paper"]


def fit(photo, machine, out):
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", "calibrate", "fit",
                        str(photo), "--machine", machine, "-o", str(out)], capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if p.returncode:
        return None, p.stderr.strip(), seconds
    return load_machine(out), p.stdout, seconds


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--machine", default="grbl-ring")
    ap.add_argument("--quick", action="store_true", help="four cases only")
    ap.add_argument("--photo", help="write one synthetic photo here and stop")
    ap.add_argument("--width-mm", type=float, default=0.3, help="the thread of --photo")
    args = ap.parse_args()
    if args.photo:
        board, thread = make_photo(args.photo, args.machine, args.width_mm, CASES[1][1], CASES[1][2], {})
        print(f"a synthetic photo of {args.machine}'s calibration sheet, thread {args.width_mm:g} mm, board "
              f"{board:.4f}, thread {thread:.4f} (linear, paper = 1) -> {args.photo}")
        return
    from stringbot.planner.colour.palette import to_linear

    cases = [CASES[i] for i in QUICK] if args.quick else CASES
    print(f"machine {args.machine}; photos {SHAPE[1]} x {SHAPE[0]} unless said; reflectances linear, paper = 1")
    print(f"{'width':>6} {'fitted':>7} {'error':>7}  {'board':>13}  {'thread':>13}  {'RMS':>6}  {'s':>5}  case")
    errors = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (width, cam, light, extra) in enumerate(cases):
            photo = Path(tmp) / (f"p{k}.jpg" if "jpeg" in extra else f"p{k}.png")
            board, thread = make_photo(photo, args.machine, width, cam, light, extra, rng=k)
            m, text, seconds = fit(photo, args.machine, Path(tmp) / f"m{k}.toml")
            what = (f"tilt {cam[0]:+.2f},{cam[1]:+.2f} turn {cam[2]:+.0f}; light {light[0]:.1f}@{light[1]:.0f} "
                    f"vignette {light[2]:.1f}" + "".join(f"; {key} {val}" for key, val in extra.items()))
            if m is None:
                print(f"{width:>6.3f} {'--':>7} {'--':>7}  {'':>13}  {'':>13}  {'':>6}  {seconds:>5.1f}  {what}: {text}")
                continue
            w = m["thread.effective_mm"]
            want = width * extra.get("opacity", 1.0)
            err = 100 * (w / want - 1)
            errors.append(abs(err))
            b, t = (float(to_linear(m[f"thread.{key}"])) for key in ("board_gray", "thread_gray"))
            rms = next(line.split()[2] for line in text.splitlines() if line.startswith("fit "))
            print(f"{want:>6.3f} {w:>7.4f} {err:>+6.2f}%  {board:.3f} / {b:.3f}  {thread:.3f} / {t:.3f}  {rms:>6}  "
                  f"{seconds:>5.1f}  {what}")
    if errors:
        print(f"largest width error {max(errors):.2f} %, mean {np.mean(errors):.2f} % over {len(errors)} photos "
              f"(a thread of opacity o is expected to fit as o x its width)")


if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    main()
