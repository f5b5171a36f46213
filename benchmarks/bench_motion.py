"""Figures of the motion layer: the camera plan at 300 pins on a machine.

Prints G-code lines, estimated machine time, ring travel against the
shortest-arc lower bound (target <= 1.02), thread length, and the result of
replaying the G-code against the simulator's physical world.

    python benchmarks/bench_motion.py [--machine grbl-ring] [--plan PLAN.json] [--image PICTURE]

Without ``--plan`` it plans ``--image`` (default: the shared camera picture,
else examples/camera.png) with ``stringbot plan``; if the planner is not
available it falls back to a stand-in plan of 2500 random chords and says so.
"""

import argparse
import json
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from firmware_protocol.machine import bundled_machines, load_machine  # noqa: E402
from firmware_protocol.world import World  # noqa: E402
from stringbot.motion import estimate, format_duration, gcode_job  # noqa: E402
from stringbot.planner import read_plan  # noqa: E402


def camera_plan(image, workdir):
    """(plan, how it was made)."""
    out = Path(workdir) / "camera.json"
    cmd = [sys.executable, "-m", "stringbot.cli", "plan", str(image), "-o", str(out), "--pins", "300"]
    try:
        done = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", *cmd[3:]],
                              cwd=ROOT, capture_output=True, text=True, timeout=600)
    except subprocess.TimeoutExpired:
        done = None
    if done is not None and done.returncode == 0 and out.exists():
        return read_plan(out), f"stringbot plan {image} ({done.stdout.strip()})"
    from test_gcode_replay import make_plan, random_sequence
    why = "planner timed out" if done is None else (done.stderr.strip().splitlines() or ["failed"])[-1]
    return make_plan(random_sequence(2501, seed=2016)), f"STAND-IN: 2500 random chords ({why})"


def replay_counts(text, machine):
    from gcode_replay import replay
    world, (lo, hi) = replay(text, machine, world=World(machine))
    return world, lo, hi


def emulated_seconds(text, machine):
    """Send the job line by line to the simulated firmware: (virtual seconds, refused lines, world)."""
    from firmware_protocol.emulators.factory import build_emulator
    from test_gcode_on_emulators import send
    emu, world = build_emulator(machine)
    for _ in range(100):            # let it boot (banner)
        if not emu.busy:
            break
        emu.advance(None)
    emu.transmit()
    t0, refused = emu.now, 0
    for raw in text.splitlines():
        line = raw.split(";", 1)[0].strip()
        if line:
            answer = send(emu, line).lower()
            refused += "error" in answer or "unknown command" in answer or "ok" not in answer
    return emu.now - t0, refused, world


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machine", default="grbl-ring")
    ap.add_argument("--plan", default=None)
    default_image = Path("/work/shared/images/camera.png")
    ap.add_argument("--image", default=str(default_image if default_image.exists() else ROOT / "examples/camera.png"))
    ap.add_argument("--all-machines", action="store_true", help="also print the figures on every G-code machine")
    ap.add_argument("--emulate", action="store_true", help="also run the job on the emulated firmware")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        if args.plan:
            plan, how = read_plan(args.plan), f"plan file {args.plan}"
        else:
            plan, how = camera_plan(args.image, tmp)
    print(f"plan: {how}")
    print(f"      {plan.pins} pins, {len(plan.sequence)} pins in the sequence ({len(plan.sequence) - 1} chords)")
    names = [args.machine]
    if args.all_machines:
        names += [n for n in bundled_machines() if n != args.machine
                  and load_machine(n)["controller.kind"] == "gcode"]
    for name in names:
        machine = load_machine(name)
        t0 = time.perf_counter()
        text = gcode_job(plan, machine)
        t_gcode = time.perf_counter() - t0
        est = estimate(plan, machine)
        world, lo, hi = replay_counts(text, machine)
        exact = [w.pin for w in world.wraps] == list(plan.sequence)
        print(f"\nmachine: {name}")
        print(f"  G-code lines          {text.count(chr(10))} ({len(text) / 1e6:.2f} MB, written in {t_gcode:.2f} s)")
        print(f"  estimated time        {format_duration(est.seconds)} ({est.seconds:.0f} s)")
        print(f"  ring travel           {est.ring_travel_deg:.0f} deg; shortest-arc lower bound "
              f"{est.lower_bound_deg:.0f} deg; ratio {est.travel_ratio:.4f} (target <= 1.02)")
        print(f"  thread                {est.thread_m:.1f} m (of which round pins {est.wrap_m:.2f} m)")
        print(f"  ring axis range       {lo:.1f} .. {hi:.1f} deg (bound +-{machine['ring.travel_deg']:g})")
        print(f"  replay on the world   {len(world.wraps)} wraps, exactly the plan: {exact}; "
              f"collisions: {len(world.collisions)}")
        if args.emulate:
            t0 = time.perf_counter()
            secs, refused, ew = emulated_seconds(text, machine)
            print(f"  emulated firmware     {format_duration(secs)} of virtual time ({secs:.0f} s; estimate "
                  f"{est.seconds:.0f} s); lines refused: {refused}; wraps exact: "
                  f"{[w.pin for w in ew.wraps] == list(plan.sequence)}; collisions: {len(ew.collisions)} "
                  f"({time.perf_counter() - t0:.1f} s wall)")
        print("  json " + json.dumps({"machine": name, "gcode_lines": text.count("\n"), **est.as_dict(),
                                      "collisions": len(world.collisions), "exact": exact}))


if __name__ == "__main__":
    main()
