"""The fault matrix on a full plan: every fault kind at many points, and the host SIGKILLed.

    python benchmarks/bench_faults.py [--plan PLAN.json] [--points 12] [--kills 8] [--machines ...]

1. For each G-code machine and each fault kind (disconnect, reset, power,
   garble, drop-ok, error), ``--points`` fault points spread over the whole
   job (line numbers drawn at random, seeded): wind the plan through
   ``sim://?faults=kind@N``, then ``--resume`` (as the library call the CLI
   makes) after every stop until finished.  The operator's answer to "where is
   the head?" -- asked only when the firmware lost its position during a head
   move -- is read off the simulated machine.  Survived = the world's wraps
   equal the plan's sequence exactly, with zero collisions.  Faults that hit
   while the head was OUT (mid-hook) are counted apart.
2. The host killed with SIGKILL at random moments: ``stringbot simulate`` on
   a pty in its own process, ``stringbot wind --port PTY`` in another, killed
   ``--kills`` times, each time followed by ``--resume``, until it exits 0.
"""

import argparse
import json
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))

from firmware_protocol.machine import load_machine  # noqa: E402
from firmware_protocol.urlhandler import protocol_sim  # noqa: E402
from matrix_user import homes  # noqa: E402
from test_wind_sim import eyes_at  # noqa: E402
from stringbot.errors import Interrupted, MachineFailure  # noqa: E402
from stringbot.links import sim_url  # noqa: E402
from stringbot.winding import Job, wind_plan  # noqa: E402
from stringbot.winding.resume import resume_plan  # noqa: E402

from bench_wind import STRINGBOT, camera_plan  # noqa: E402

KINDS = ["disconnect", "reset", "power", "garble", "drop-ok", "error"]


def one_fault(plan_path, name, kind, n, workdir):
    url = sim_url(name, faults=f"{kind}@{n}")
    protocol_sim.forget(url)
    job = Job(plan_path, load_machine(name), port=url, journal=Path(workdir) / f"j-{name}-{kind}-{n}")
    world = None
    stops, head_out_at_stop = 0, False
    run = lambda: wind_plan(job, confirm=None, eyes=eyes_at(job.url))           # noqa: E731
    for _ in range(12):
        try:
            run()
            break
        except (MachineFailure, Interrupted):
            stops += 1
            world = protocol_sim.session(url).world
            head_out_at_stop = head_out_at_stop or world.head_out
        side = "out" if protocol_sim.session(url).world.head_out else "in"
        run = lambda side=side: resume_plan(job, confirm=None, head_side=side)   # noqa: E731
    else:
        return stops, head_out_at_stop, False, "never finished"
    world = protocol_sim.session(url).world
    ok = [w.pin for w in world.wraps] == job.plan.sequence and not world.collisions
    why = "" if ok else f"{len(world.wraps)} wraps, {len(world.collisions)} collisions"
    protocol_sim.forget(url)
    return stops, head_out_at_stop, ok, why


def matrix(plan_path, machines, points, seed, workdir):
    rng = random.Random(seed)
    print("1. fault matrix (sim://, the whole plan each time)")
    totals = Counter()
    for name in machines:
        job = Job(plan_path, load_machine(name), journal=Path(workdir) / "probe")
        lines = 6 + sum(2 * len(s.moves) + (2 if s.dwell_s else 0) for s in job.steps)
        for kind in KINDS:
            tried = survived = stopped = mid_hook = 0
            failures = []
            for n in sorted(rng.sample(range(5, lines), points)):
                stops, out, ok, why = one_fault(plan_path, name, kind, n, workdir)
                tried += 1
                stopped += stops > 0
                mid_hook += out
                survived += ok
                if not ok:
                    failures.append(f"{kind}@{n}: {why}")
            totals["tried"] += tried
            totals["survived"] += survived
            print(f"  {name:13s} {kind:10s} tried {tried:3d}  stopped the job {stopped:3d}  "
                  f"head out at the stop {mid_hook:3d}  survived {survived:3d}"
                  + (f"  FAILED: {'; '.join(failures[:3])}" if failures else ""), flush=True)
    print(f"  total: {totals['survived']} of {totals['tried']} survived")


def _done_count(journal):
    try:
        return journal.read_bytes().count(b'"kind":"done"')
    except FileNotFoundError:
        return 0


def kills(plan_path, plan_seq, name, n_kills, seed, workdir):
    """Kill the host when the journal reaches random step counts (plus a random fraction of a step)."""
    rng = random.Random(seed)
    pty = Path(workdir) / "pty"
    rec = Path(workdir) / "kill-rec.json"
    journal = Path(workdir) / "kill.journal"
    targets = sorted(rng.sample(range(1, len(plan_seq) - 1), n_kills))
    sim = subprocess.Popen(STRINGBOT + ["simulate", "--machine", name, "--pty", str(pty), "--record", str(rec)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = runs = 0
    problems = []
    try:
        while not pty.exists():
            time.sleep(0.05)
        extra = ["--head-side", "in"] if homes(name) else []     # just started: the operator says IN
        while True:
            runs += 1
            cmd = STRINGBOT + ["wind", str(plan_path), "--machine", name, "--port", str(pty), "--yes", "--force",
                               "--journal", str(journal)] + extra
            proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            if killed < len(targets):
                while proc.poll() is None and _done_count(journal) < targets[killed]:
                    time.sleep(0.002)
                time.sleep(rng.uniform(0.0, 0.02))
                if proc.poll() is None:
                    proc.send_signal(signal.SIGKILL)
                    killed += 1
            out, err = proc.communicate()
            extra = ["--resume"]
            if proc.returncode == 0:
                break
            if proc.returncode != -signal.SIGKILL:
                problems.append(err.strip()[-200:])
            if runs > n_kills + 10:
                break
    finally:
        sim.send_signal(signal.SIGINT)
        sim.wait(timeout=30)
    r = json.loads(rec.read_text())
    ok = [w["pin"] for w in r["wraps"]] == plan_seq and not r["collisions"]
    print(f"2. SIGKILL: {name}: host killed {killed} times at random moments (after steps "
          f"{', '.join(map(str, targets[:killed]))} + a random fraction of a step), {runs} runs; "
          + ("survived: wraps == sequence, 0 collisions" if ok else
             "FAILED: %d wraps, %d collisions" % (len(r["wraps"]), len(r["collisions"]))))
    for p in problems:
        print("   a run ended otherwise:", p)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plan", help="a plan file (default: plan the camera picture)")
    ap.add_argument("--points", type=int, default=12, help="fault points per kind and machine")
    ap.add_argument("--kills", type=int, default=8)
    ap.add_argument("--machines", nargs="*", default=["grbl-ring", "grblhal-ring", "marlin-ring"])
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as workdir:
        plan_path = Path(args.plan) if args.plan else camera_plan(workdir)
        job = Job(plan_path, load_machine(args.machines[0]), journal=Path(workdir) / "probe")
        print(f"plan: {plan_path.name}: {len(job.plan.sequence)} pins in the sequence")
        t = time.monotonic()
        matrix(plan_path, args.machines, args.points, args.seed, workdir)
        print(f"  ({time.monotonic() - t:.0f} s)")
        if args.kills:
            kills(plan_path, job.plan.sequence, "grbl-ring", args.kills, args.seed, workdir)


if __name__ == "__main__":
    main()
