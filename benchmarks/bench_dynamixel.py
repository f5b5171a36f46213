"""Pins per second wound through the real dynamixel_sdk on the emulator's pty, at full speed.

    python benchmarks/bench_dynamixel.py [--pins-wound 300] [--plan plan.json] [--machine dynamixel-ring]

Every byte crosses a pseudo-terminal: hooking steps -> DynamixelLink ->
dynamixel_sdk -> pty -> DynamixelEmulator (fast mode: virtual time) -> World,
the emulator in its own process as ``stringbot simulate`` runs it.
Prints wall-clock pins per second, exchanges per pin, the machine time the
winding would take at the machine file's profile (virtual seconds), and checks
that the world's wraps equal the plan with no collision.
"""

import argparse
import logging
import multiprocessing
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from firmware_protocol.emulators.dynamixel import DynamixelEmulator  # noqa: E402
from firmware_protocol.machine import load_machine  # noqa: E402
from firmware_protocol.pty import PtyServer  # noqa: E402
from firmware_protocol.world import World  # noqa: E402
from stringbot.links.dynamixel import DynamixelLink  # noqa: E402
from stringbot.motion import hook_steps  # noqa: E402
from stringbot.planner import Plan, read_plan  # noqa: E402


def _serve(machine_path, path, conn):
    """Child process: ``stringbot simulate``'s pty server with the emulator (fast mode) until told
    to stop; then sends (virtual seconds, the world's record)."""
    machine = load_machine(machine_path)
    world = World(machine)
    emu = DynamixelEmulator(machine, world=world)
    server = PtyServer(emu, path).start()
    stop = threading.Event()
    conn.send("ready")
    threading.Thread(target=lambda: (conn.recv(), stop.set()), daemon=True).start()
    try:
        server.serve(stop)
    finally:
        server.close()
    conn.send((emu.now, world.record()))


def random_plan(n, pins, seed=7):
    rng = np.random.default_rng(seed)
    seq = [int(rng.integers(pins))]
    while len(seq) < n:
        p = int(rng.integers(pins))
        if p != seq[-1]:
            seq.append(p)
    a = np.arange(pins) * 2 * np.pi / pins
    xy = np.stack([0.5 + 0.5 * np.sin(a), 0.5 - 0.5 * np.cos(a)], axis=1)
    return Plan(pins=pins, frame="circle", pin_xy=xy, crop={"cx": 1, "cy": 1, "r": 1}, sequence=seq,
                method="random", parameters={}, stats={},
                source={"path": "-", "sha256": "0" * 64, "width": 2, "height": 2})


def wind_once(machine, plan, tmp):
    """One winding on a fresh emulator in its own process (as `stringbot simulate` runs):
    (wall seconds, steps, polls, virtual seconds, world record)."""
    parent, child = multiprocessing.Pipe()
    path = os.path.join(tmp, "dxl")
    server = multiprocessing.Process(target=_serve, args=(machine.path, path, child), daemon=True)
    server.start()
    parent.recv()
    link = DynamixelLink(machine, path)
    try:
        link.connect()
        steps = hook_steps(plan, machine, start_ring_deg=link.prepare()[0])
        polls0 = link.polls
        t0 = time.perf_counter()
        for step in steps:
            link.run_step(step)
        wall = time.perf_counter() - t0
    finally:
        link.close()
        parent.send("stop")
        virtual, record = parent.recv()
        server.join(5)
    return wall, len(steps), link.polls - polls0, virtual, record


def main():
    logging.basicConfig(level=logging.ERROR)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machine", default="dynamixel-ring")
    ap.add_argument("--plan", help="a plan file (default: a random sequence)")
    ap.add_argument("--pins-wound", type=int, default=300, help="pins of a random sequence")
    ap.add_argument("--repeat", type=int, default=3, help="runs (the median is reported)")
    args = ap.parse_args()
    machine = load_machine(args.machine)
    plan = read_plan(args.plan) if args.plan else random_plan(args.pins_wound, machine.pins)
    with tempfile.TemporaryDirectory() as tmp:
        runs = sorted((wind_once(machine, plan, tmp) for _ in range(max(1, args.repeat))), key=lambda r: r[0])
    wall, n, polls, virtual, world = runs[len(runs) // 2]
    ok = all([w["pin"] for w in r[4]["wraps"]] == list(plan.sequence) and not r[4]["collisions"]
             for r in runs)
    print(f"machine          {machine.name} ({len(plan.sequence)} pins wound, {plan.pins}-pin ring)")
    print(f"wall clock       {wall:.2f} s median of {len(runs)}  ->  {n / wall:.1f} pins/s through the SDK "
          f"on the pty (best {n / runs[0][0]:.1f}, worst {n / runs[-1][0]:.1f})")
    print(f"polls            {polls / n:.1f} position polls per pin ({polls / wall:.0f} polls/s)")
    print(f"machine time     {virtual:.0f} s virtual ({n / virtual:.2f} pins/s at the profile)")
    print(f"world            wraps == plan in every run: {ok}; collisions: {len(world['collisions'])}; "
          f"ring travel {world['ring_travel_deg']:.0f} deg")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
