"""Pins per second wound through the real dynamixel_sdk on the emulator's pty, at full speed.

    python benchmarks/bench_dynamixel.py [--pins-wound 300] [--plan plan.json] [--machine dynamixel-ring]

Every byte crosses a pseudo-terminal: hooking steps -> DynamixelLink ->
dynamixel_sdk -> pty -> DynamixelEmulator (fast mode: virtual time) -> World.
Prints wall-clock pins per second, exchanges per pin, the machine time the
winding would take at the machine file's profile (virtual seconds), and checks
that the world's wraps equal the plan with no collision.
"""

import argparse
import os
import select
import sys
import threading
import time
import tty
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from firmware_protocol.emulators.dynamixel import DynamixelEmulator  # noqa: E402
from firmware_protocol.machine import load_machine  # noqa: E402
from firmware_protocol.world import World  # noqa: E402
from stringbot.links.dynamixel import DynamixelLink  # noqa: E402
from stringbot.motion import hook_steps  # noqa: E402
from stringbot.planner import Plan, read_plan  # noqa: E402


class _Pty:
    """Serve an emulator on a pty in a thread (fast mode)."""

    def __init__(self, emu):
        self.emu = emu
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._stop_r, self._stop_w = os.pipe()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while True:
            ready, _, _ = select.select([self.master, self._stop_r], [], [], 0.005)
            if self._stop_r in ready:
                return
            if self.master in ready:
                self.emu.receive(os.read(self.master, 4096))
            elif self.emu.busy:
                self.emu.advance(None)
            out = self.emu.transmit()
            if out:
                os.write(self.master, out)

    def close(self):
        os.write(self._stop_w, b"x")
        self.thread.join(2)


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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machine", default="dynamixel-ring")
    ap.add_argument("--plan", help="a plan file (default: a random sequence)")
    ap.add_argument("--pins-wound", type=int, default=300, help="pins of a random sequence")
    args = ap.parse_args()
    machine = load_machine(args.machine)
    plan = read_plan(args.plan) if args.plan else random_plan(args.pins_wound, machine.pins)
    world = World(machine)
    emu = DynamixelEmulator(machine, world=world)
    server = _Pty(emu)
    link = DynamixelLink(machine, server.path)
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
        server.close()
    n = len(steps)
    ok = [w.pin for w in world.wraps] == list(plan.sequence) and not world.collisions
    print(f"machine          {machine.name} ({len(plan.sequence)} pins wound, {plan.pins}-pin ring)")
    print(f"wall clock       {wall:.2f} s  ->  {n / wall:.1f} pins/s through the SDK on the pty")
    print(f"polls            {(link.polls - polls0) / n:.1f} sync reads per pin "
          f"({(link.polls - polls0) / wall:.0f} exchanges/s)")
    print(f"machine time     {emu.now:.0f} s virtual ({n / emu.now:.2f} pins/s at the profile)")
    print(f"world            wraps == plan: {ok}; collisions: {len(world.collisions)}; "
          f"ring travel {world.ring_travel_deg:.0f} deg")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
