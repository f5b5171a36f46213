"""Figures of the simulator's record file: dry-run throughput through ``sim://`` with and without it.

    python benchmarks/bench_sim_record.py [--plan PLAN.json] [--machines grbl-ring,...]

The record (``sim://?record=FILE``, ``--record``) holds the world's state
(ring angle, head position and side, move count, wraps, collisions, crashes);
writing it costs file rewrites.  This prints pins per second of wall time for
the camera plan (300 pins, ~1800 chords) with sync=move (the default), without
and with the record, and how many times the record was rewritten.
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_wind import camera_plan, dry_run  # noqa: E402
from stringbot.planner import read_plan  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plan", help="a plan file (default: plan the camera picture)")
    ap.add_argument("--machines", default="grbl-ring,grblhal-ring,marlin-ring")
    ap.add_argument("--repeat", type=int, default=2, help="runs per figure (the best is printed)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as workdir:
        plan_path = Path(args.plan) if args.plan else camera_plan(workdir)
        plan = read_plan(plan_path)
        print(f"plan: {plan_path.name}: {len(plan.sequence)} pins in the sequence; sync=move through sim://")
        for name in args.machines.split(","):
            row = []
            for record in (False, True):
                best, check = 0.0, ""
                for _ in range(args.repeat):
                    t = time.monotonic()
                    result, check = dry_run(plan, name, "move", workdir, record=record)
                    best = max(best, result.pins_per_second)
                row.append(best)
            print(f"  {name:13s} {row[0]:6.0f} pins/s without record, {row[1]:6.0f} pins/s with record  {check}")


if __name__ == "__main__":
    main()
