"""Figures of winding: dry-run throughput on the camera plan, and the realtime planner measurement.

    python benchmarks/bench_wind.py [--plan PLAN.json] [--realtime-steps 12] [--skip-pty]

1. Dry run (the simulated machine as fast as possible) of the whole camera
   plan (300 pins, ~1800 chords) on every bundled G-code machine, through
   ``sim://``: pins per second of wall time, for the default move-by-move
   execution (``sync=move``) and for streaming with one sync per step
   (``sync=step``); checked against the world: wraps == sequence, 0 collisions.
2. The same through a pty served by ``stringbot simulate`` in its own process
   (the real pyserial port code, a journal with fsync).
3. Realtime (``realtime=1``): a background thread samples the simulated
   planner every millisecond while the host winds the first steps; prints how
   much of the time the planner was empty although the host still had lines
   to send, how many such gaps and how long.
"""

import argparse
import json
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from firmware_protocol.machine import load_machine  # noqa: E402
from matrix_user import homes  # noqa: E402
from stringbot.links import open_link, sim_url  # noqa: E402
from stringbot.motion import hook_steps  # noqa: E402
from stringbot.planner import read_plan  # noqa: E402
from stringbot.winding import Journal, Winder  # noqa: E402

MACHINES = ["grbl-ring", "grblhal-ring", "marlin-ring"]
STRINGBOT = [sys.executable, "-c", "import sys; from stringbot.cli import main; main(sys.argv[1:])"]


def camera_plan(workdir):
    image = Path("/work/shared/images/camera.png")
    if not image.exists():
        image = ROOT / "examples" / "camera.png"
    out = Path(workdir) / "camera.json"
    done = subprocess.run(STRINGBOT + ["plan", str(image), "-o", str(out), "--pins", "300"],
                          capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        sys.exit("could not plan the camera picture: " + done.stderr.strip())
    return out


def dry_run(plan, name, sync, workdir, record=True):
    machine = load_machine(name)
    steps = hook_steps(plan, machine)
    rec = Path(workdir) / f"rec-{name}-{sync}-{time.monotonic_ns()}.json" if record else None
    url = sim_url(name, record=rec)
    from firmware_protocol.urlhandler import protocol_sim
    protocol_sim.forget(url)                 # a fresh simulated machine
    link = open_link(url, machine, sync=sync)
    journal = Journal.create(Path(workdir) / "j", plan_path="camera", plan_sha256=plan.sha256(),
                             machine=name, steps=len(steps), durable=False)
    try:
        w = Winder(link, steps, machine, journal=journal)
        w.start(home=machine["controller.homing"])
        result = w.wind(0)
    finally:
        link.close()
        journal.close()
        protocol_sim.forget(url)             # its record written now, inside the temporary folder
    check = ""
    if rec:
        r = json.loads(rec.read_text())
        ok = [x["pin"] for x in r["wraps"]] == plan.sequence and not r["collisions"]
        check = "wraps == sequence, 0 collisions" if ok else \
            f"MISMATCH: {len(r['wraps'])} wraps, {len(r['collisions'])} collisions"
    return result, check


def pty_run(plan_path, plan, name, workdir, record=True):
    """Wind through ``stringbot simulate --pty`` in its own process; (wall s, ok or None, summary)."""
    pty = Path(workdir) / f"pty-{name}-{record}"
    rec = Path(workdir) / f"pty-rec-{name}.json"
    cmd = STRINGBOT + ["simulate", "--machine", name, "--pty", str(pty)]
    if record:
        cmd += ["--record", str(rec)]
    sim = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        while not pty.exists():
            time.sleep(0.05)
        t = time.monotonic()
        done = subprocess.run(STRINGBOT + ["wind", str(plan_path), "--machine", name, "--port", str(pty),
                                           "--yes", "--force", "--journal", str(Path(workdir) / f"pty-{name}-{record}.journal")]
                              + (["--head-side", "in"] if homes(name) else []),     # the operator: head IN
                              capture_output=True, text=True)
        wall = time.monotonic() - t
    finally:
        sim.send_signal(signal.SIGINT)
        sim.wait(timeout=20)
    ok = None
    if record:
        r = json.loads(rec.read_text())
        ok = [x["pin"] for x in r["wraps"]] == plan.sequence and not r["collisions"]
    summary = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else done.stderr.strip()
    return wall, ok, summary


def realtime_gaps(plan, name, sync, n_steps):
    """Wind the first ``n_steps`` in realtime; sample the planner; return figures."""
    from firmware_protocol.urlhandler import protocol_sim
    machine = load_machine(name)
    steps = hook_steps(plan, machine)[:n_steps]
    url = sim_url(name, realtime=True)
    protocol_sim.forget(url)
    link = open_link(url, machine, sync=sync)
    emu = protocol_sim.session(url).emulator
    samples = []
    running = threading.Event()
    running.set()

    def sample():
        while running.is_set():
            try:
                empty = emu.motion.empty
            except Exception:
                empty = False
            samples.append((time.monotonic(), empty))
            time.sleep(0.001)
    w = Winder(link, steps, machine)
    w.start(home=machine["controller.homing"])
    th = threading.Thread(target=sample, daemon=True)
    t0 = time.monotonic()
    th.start()
    try:
        w.wind(0, finish=False)
    finally:
        running.clear()
        th.join()
        link.close()
    wall = time.monotonic() - t0
    gaps, start = [], None
    for t, empty in samples:
        if empty and start is None:
            start = t
        elif not empty and start is not None:
            gaps.append(t - start)
            start = None
    empty_s = sum(gaps)
    return {"wall_s": wall, "steps": len(steps), "gaps": len(gaps), "empty_s": empty_s,
            "median_ms": 1000 * statistics.median(gaps) if gaps else 0.0,
            "max_ms": 1000 * max(gaps) if gaps else 0.0}


def realtime_pty(name, plan, sync, n_steps, workdir, interval=0.005):
    """Realtime simulator on a pty in its own process; the host polls ``?`` every ``interval``."""
    pty = Path(workdir) / f"rt-{name}-{sync}"
    sim = subprocess.Popen(STRINGBOT + ["simulate", "--machine", name, "--pty", str(pty), "--realtime"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        while not pty.exists():
            time.sleep(0.05)
        machine = load_machine(name)
        steps = hook_steps(plan, machine)[:n_steps]
        link = open_link(str(pty), machine, sync=sync)
        link.proto.port.timeout = interval / 5          # reads return quickly: queries go out on time
        link.proto.status_log = []
        w = Winder(link, steps, machine)
        w.start(home=machine["controller.homing"])
        link.proto.status_interval = interval
        t0 = time.monotonic()
        try:
            w.wind(0, finish=False)
        finally:
            link.close()
        wall = time.monotonic() - t0
        log = [(t, st) for t, st, _ in link.proto.status_log if t >= t0]
    finally:
        sim.send_signal(signal.SIGINT)
        sim.wait(timeout=20)
    idle = [st.state == "Idle" for _, st in log]
    runs, cur = [], 0
    for flag in idle:
        if flag:
            cur += 1
        elif cur:
            runs.append(cur)
            cur = 0
    return {"wall_s": wall, "samples": len(log), "idle": sum(idle), "gaps": len(runs),
            "longest_ms": 1000 * interval * max(runs) if runs else 0.0}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plan", help="a plan file (default: plan the camera picture)")
    ap.add_argument("--realtime-steps", type=int, default=8)
    ap.add_argument("--skip-pty", action="store_true")
    ap.add_argument("--skip-realtime", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as workdir:
        plan_path = Path(args.plan) if args.plan else camera_plan(workdir)
        plan = read_plan(plan_path)
        print(f"plan: {plan_path.name}: {plan.pins} pins, {len(plan.sequence)} pins in the sequence")
        print("\n1. dry run through sim:// (pins per second of wall time; target >= 300)")
        for name in MACHINES:
            for sync in ("move", "step"):
                result, _ = dry_run(plan, name, sync, workdir, record=False)
                _, check = dry_run(plan, name, sync, workdir, record=True)
                print(f"  {name:13s} sync={sync:4s}  {result.pins_per_second:7.0f} pins/s  "
                      f"({result.steps_done} pins in {result.wall_s:.2f} s, {result.lines_sent} lines; "
                      f"model machine time {result.machine_s / 3600:.2f} h)  {check}")
        if not args.skip_pty:
            print("\n2. through a pty (stringbot simulate in its own process; journal fsync'd); pins/s of "
                  "wall time incl. start-up, without and with the world's record file (rewritten per wrap)")
            for name in MACHINES:
                wall, _, summary = pty_run(plan_path, plan, name, workdir, record=False)
                wall2, ok, _ = pty_run(plan_path, plan, name, workdir, record=True)
                print(f"  {name:13s} {len(plan.sequence) / wall:7.0f} pins/s   with --record "
                      f"{len(plan.sequence) / wall2:5.0f} pins/s  "
                      f"{'wraps == sequence, 0 collisions' if ok else 'MISMATCH'}\n      {summary}")
        if not args.skip_realtime:
            print(f"\n3. realtime: planner empty while the host still had lines to send "
                  f"(first {args.realtime_steps} steps, sampled every 1 ms)")
            for sync in ("step", "move"):
                f = realtime_pty("grbl-ring", plan, sync, args.realtime_steps, workdir)
                print(f"  through a pty, grbl-ring sync={sync:4s}: {f['samples']} status reports (every 5 ms) "
                      f"in {f['wall_s']:.1f} s, {f['idle']} Idle ({100 * f['idle'] / max(1, f['samples']):.2f}%) "
                      f"in {f['gaps']} runs, longest ~{f['longest_ms']:.0f} ms")
            for sync in ("step", "move"):
                f = realtime_gaps(plan, "grbl-ring", sync, args.realtime_steps)
                print(f"  in process, grbl-ring sync={sync:4s} {f['steps']} steps in {f['wall_s']:.1f} s: planner empty "
                      f"{f['empty_s'] * 1000:.0f} ms in {f['gaps']} gaps ({100 * f['empty_s'] / f['wall_s']:.2f}% "
                      f"of the time), median {f['median_ms']:.1f} ms, longest {f['max_ms']:.1f} ms")


if __name__ == "__main__":
    main()
