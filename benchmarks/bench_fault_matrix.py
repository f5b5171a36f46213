"""The cross-process fault matrix: faults and resumes exactly as a user meets them.

    python benchmarks/bench_fault_matrix.py [--lines 40] [--workers 2] [--machines ...] [--kinds ...]
                                            [--points 5] [--kills 5] [--seed 7] [--logs DIR]

Every case runs the way a user works, and only that way:

* the simulated machine is ``stringbot simulate --machine NAME --pty PTY --record REC.json
  --faults SPEC`` in its own process;
* the host is ``stringbot wind PLAN --machine NAME --port PTY --journal J --yes`` in another, then
  the same command with ``--resume`` after every stop, until it exits 0 or a limit is reached;
* on a machine that homes, the first ``wind`` says ``--head-side in`` (the operator has just
  powered it up with the head IN and says so: a firmware that just started cannot);
* a run that asks where the head is gets its answer from REC.json only, as a person looking at
  the machine: ``--head-side in|out`` where the head is clearly IN or OUT and the message offers
  that side; a run that asks for a terminal (the guided way, for a resume or a start) gets one --
  its questions answered and its jogs typed from REC.json by ``tests/scripted_operator.py`` (the
  guide's own commands: ``ring``, ``pin``, ``head``, ``done``) -- and a message that says to run
  the same command again gets that; nothing else ever looks at live objects.

A case is judged by the world (the record the simulator writes when it stops): its wraps must
equal the plan's sequence exactly, with no collision and no crash.  Outcomes:

exact       a run exited 0 and the world is exact
refused     the last run stopped with a message naming a way out that this operator does not
            take (the world so far is a prefix of the plan, no collision)
silent      a run exited 0 but the world differs (must be 0)
hung        a run did not end within ``--timeout`` seconds (must be 0)
dead end    advice that leads nowhere: the same stop again and again while following it, or a
            stop that names no way out (must be 0)
failed      anything else: a traceback, a world damaged before a refusal

The cases are built in ``matrix_cases.py``.  Fault points come from one fault-free probe per machine (in process, ``sim://``): the line
numbers of the moves of random steps, by kind of move -- the ring turning to a pin with the
head IN (``ring``), the head going OUT (``out``), the ring turning with the head OUT
(``hook``: mid-hook), the sync line that arrives while that turn runs (``hook-sync``) and the
head coming back IN (``in``: the head OUT).  ``kind@N`` fires as line N arrives;
``kind@N+0.5`` half way through line N's move (mid-move).  The first-move cases
(``first-power``, ``first-reboot``, ``first-reset``, each at the line and mid-move) strike the
homing line (``home``: ``$H``, ``G28``) and the first ring move (``first``: to the first pin's
gap).  ``start`` cases begin with a person's displacement typed into a terminal program before
``wind`` (``out-pin``: the head OUT with a pin in front of it, half a pitch at most from the gap
it went out by; ``out-gap``: OUT at a gap; ``ring``: the ring turned, the head IN) and, on a
machine that homes, ``out-pin`` followed by a power cut (the firmware then cannot say where it
stands).  ``uno-*`` cases run a copy of the
machine file with ``controller.reset_on_open = true`` (the board reboots whenever the port
opens).  The machines are every bundled machine file and the kinds every fault kind a resume
can get past (``firmware_protocol.faults.FAULT_KINDS``); a Dynamixel machine takes its own
faults (``power``, ``corrupt``, ``hardware``, ``silent``, ``disconnect`` at move N).  ``host-kill`` SIGKILLs the host ``--kills`` times at random moments
(after a random journaled step count plus a random fraction of a step) and resumes;
``sim-kill`` SIGKILLs the simulator: it cannot be restarted on the same world (the world is
not restored from a record), so that case judges only the host's stop (exit 1, a message
naming the resume, and a journal that claims no pin the world did not wind).
"""

import argparse
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from matrix_user import (  # noqa: E402
    STRINGBOT, Simulator, _done, _sigint_default, clear_side, displacement, homes, run_guided,
    run_host, type_lines, wait_event)

from matrix_cases import (  # noqa: E402
    FIRST_KINDS, GCODE, LINE_KINDS, MID_KINDS, SERVO, UNO_KINDS, build_cases, make_plan)

OUTCOMES = ["exact", "refused", "silent", "hung", "dead end", "failed"]
WAYS_OUT = ("--resume", "--head-side", "--from-step", "terminal", "guided", "home", "power",
            "restart", "run the same command")
HARDWARE = ("check its power", "cable")      # a stop that names a part to fix by hand


# ---- one case ---------------------------------------------------------------------------------

def _error_line(err):
    lines = [ln for ln in err.splitlines() if ln.startswith("stringbot: error:")]
    return lines[-1] if lines else (err.strip().splitlines() or [""])[-1]


def _world_ok(rec, seq, finished):
    wraps = [w["pin"] for w in rec.get("wraps", [])]
    clean = not rec.get("collisions") and not rec.get("crashes")
    return clean and (wraps == seq if finished else wraps == seq[:len(wraps)])


def run_case(case, plan_path, seq, workdir, *, timeout=120.0, max_runs=10, seed=0):
    """Wind ``plan_path`` through the case's faults, resuming as a user does.  Returns a dict:
    outcome, why, runs, stops, head_out (at a stop), log (every command and its output)."""
    work = Path(tempfile.mkdtemp(prefix="case-", dir=workdir))
    pty, record, journal = work / "pty", work / "rec.json", work / "j.journal"
    rng = random.Random(seed)
    base = ["wind", str(plan_path), "--machine", case.machine, "--port", str(pty), "--journal", str(journal)]
    log, stops, head_out, kills = [], 0, False, list(case.kills)
    result = {"case": case.name, "label": case.label, "kind": case.kind, "log": log}
    sim = Simulator(case.machine, pty, record, case.faults)
    try:
        extra, yes, repeats, last_msg = [], True, 0, None
        if case.setup:              # a person left the machine off its start, in a terminal program
            type_lines(pty, displacement(case.machine, case.setup), then=case.then or None)
            if case.then:           # the power went: wait for it to come back, as a person does
                wait_event(record, "power on")
            log.append(f"(typed before winding: {' / '.join(displacement(case.machine, case.setup))}"
                       + (f" / {case.then}" if case.then else "") + ")")
        elif homes(case.machine):   # just powered up with the head IN: the operator says so
            extra = ["--head-side", "in"]
        for run in range(1, max_runs + len(case.kills) + 1):
            sim.wait_port()
            args = base + (["--yes"] if yes else []) + extra
            if not yes:
                rc, out, err = run_guided(args, case.machine, record, timeout)
            elif case.sim_kill:
                proc_rc = _kill_the_simulator(sim, args, journal, case.sim_kill, timeout, rng, log)
                result.update(proc_rc, runs=1, stops=1)
                return result
            else:
                rc, out, err, sent = run_host(args, timeout, kills[0] if kills else None, journal, rng,
                                              case.signal)
                if sent or (kills and rc == 0):
                    kills.pop(0)
            log.append(f"$ stringbot {' '.join(args)}\n-> {rc}\n{out}{err}")
            if rc == "hung":
                return {**result, "outcome": "hung", "why": f"run {run} did not end in {timeout:.0f} s",
                        "runs": run, "stops": stops, "head_out": head_out}
            if rc == "killed":
                extra, yes = (["--resume"] if journal.exists() else []), True
                continue
            finished = rc == 0 or "says the winding is finished" in err   # killed after its last record
            rec = sim.look() if not finished else sim.stop()
            if finished:
                ok = _world_ok(rec, seq, True)
                why = "" if ok else (f"exit 0 but {len(rec.get('wraps', []))} wraps (plan {len(seq)}), "
                                     f"{len(rec.get('collisions', []))} collisions, "
                                     f"{len(rec.get('crashes', []))} crashes")
                return {**result, "outcome": "exact" if ok else "silent", "why": why, "runs": run,
                        "stops": stops, "head_out": head_out}
            stops += 1
            head_out = head_out or rec.get("head_side") in ("out", "on")     # OUT, or among the pins
            msg = _error_line(err)
            if "Traceback" in err or rc not in (1, 2, 130):
                return {**result, "outcome": "failed", "why": f"exit {rc}: {msg[-300:]}", "runs": run,
                        "stops": stops, "head_out": head_out}
            repeats = repeats + 1 if msg == last_msg else 0
            last_msg = msg
            if repeats >= 2 and any(w in msg for w in HARDWARE):    # a dead part: only hands fix it
                return {**result, "outcome": "refused", "runs": run, "stops": stops, "head_out": head_out,
                        "why": f"the same stop three times, naming a part to check: {msg[-300:]}"}
            if repeats >= 2:
                return {**result, "outcome": "dead end", "runs": run, "stops": stops, "head_out": head_out,
                        "why": f"the same stop three times while following its advice: {msg[-300:]}"}
            side = clear_side(rec, case.machine) if case.label not in SERVO else rec.get("head_side")
            offered = set(re.findall(r"--head-side (in|out)\b", msg))
            resuming = ["--resume"] if "--resume" in extra else []
            if side in offered and "--head-side" not in extra:
                extra, yes = resuming + ["--head-side", side], True       # clearly IN or OUT, as offered
            elif yes and ("terminal" in msg or "guided" in msg or "without --yes" in msg):
                extra, yes = resuming, False                   # among the pins: the guided way
            elif "nothing was wound yet" in msg or "run the same command again" in msg:
                pass                                           # the same command (nothing moved)
            elif "--resume" in msg or "resume again" in msg:
                extra, yes = ["--resume"], True
            else:
                world_ok = _world_ok(sim.stop(), seq, False)
                named = any(w in msg for w in WAYS_OUT)
                outcome = "refused" if named and world_ok else "dead end" if world_ok else "failed"
                why = msg if world_ok else f"world damaged before the stop: {msg}"
                return {**result, "outcome": outcome, "why": why[-300:], "runs": run, "stops": stops,
                        "head_out": head_out}
        return {**result, "outcome": "dead end", "why": f"not finished after {max_runs} runs: {last_msg}",
                "runs": max_runs, "stops": stops, "head_out": head_out}
    finally:
        sim.stop()
        result["work"] = str(work)


def _kill_the_simulator(sim, args, journal, after, timeout, rng, log):
    """SIGKILL the simulator once ``after`` steps are journaled; judge the host's stop."""
    proc = subprocess.Popen(STRINGBOT + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 preexec_fn=_sigint_default)
    deadline = time.monotonic() + timeout
    while proc.poll() is None and _done(journal) < after and time.monotonic() < deadline:
        time.sleep(0.002)
    time.sleep(rng.uniform(0.0, 0.03))
    sim.proc.send_signal(signal.SIGKILL)
    sim.proc.wait()
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        log.append(f"$ stringbot {' '.join(args)}\n-> hung\n{out}{err}")
        return {"outcome": "hung", "why": "the host did not notice the simulator's death"}
    log.append(f"$ stringbot {' '.join(args)}\n-> {proc.returncode}\n{out}{err}")
    done = _journal_pins(journal)
    wraps = [w["pin"] for w in sim.look().get("wraps", [])]
    msg = _error_line(err)
    if proc.returncode == 1 and "--resume" in msg and done == wraps[:len(done)]:
        return {"outcome": "refused", "why": f"host stopped at step {len(done)} with: {msg[-200:]}"}
    return {"outcome": "failed", "why": f"exit {proc.returncode}, journal {len(done)} pins, world "
                                        f"{len(wraps)} wraps: {msg[-200:]}"}


def _journal_pins(journal):
    out = []
    for line in Path(journal).read_text().splitlines() if Path(journal).exists() else []:
        try:
            rec = json.loads(line)
        except ValueError:
            continue
        if rec.get("kind") == "done":
            out.append(rec.get("pin"))
    return out


# ---- the matrix -------------------------------------------------------------------------------

def run_matrix(cases, plans, workdir, *, workers=2, timeout=120.0, progress=None):
    seqs = {name: json.loads(Path(p).read_text())["sequence"] for name, p in plans.items()}

    def one(i_case):
        i, case = i_case
        try:
            r = run_case(case, plans[case.label], seqs[case.label], workdir, timeout=timeout, seed=i)
        except Exception as exc:          # the harness itself: shown, counted as failed
            r = {"case": case.name, "label": case.label, "kind": case.kind, "outcome": "failed",
                 "why": f"harness: {type(exc).__name__}: {exc}", "log": [], "runs": 0, "stops": 0,
                 "head_out": False}
        r["point"] = case.point
        if progress:
            progress(r)
        return r
    with ThreadPoolExecutor(max_workers=max(1, min(workers, 2))) as pool:
        return list(pool.map(one, enumerate(cases)))


def _way(entry):
    """``wind:1``, ``resume:2``, ``head-side in:0``, ``guided:0`` for one logged run."""
    if not entry.startswith("$ stringbot"):
        return "typed"                       # a person's lines before the first wind
    cmd, rc = entry.split("\n")[:2]
    way = ("guided" if "--yes" not in cmd else "head-side " + cmd.split("--head-side ")[1].split()[0]
           if "--head-side" in cmd else "resume" if "--resume" in cmd else "wind")
    return f"{way}:{rc[3:]}"


def table_lines(results):
    rows = defaultdict(Counter)
    for r in results:
        rows[(r["label"], r["kind"])][r["outcome"]] += 1
        rows[(r["label"], r["kind"])]["head out"] += bool(r.get("head_out"))
    out = [f"{'machine':13s} {'fault':15s} {'cases':>5s} " + " ".join(f"{o:>8s}" for o in OUTCOMES)
           + "  head not IN at a stop"]
    totals = defaultdict(Counter)
    for (label, kind), c in rows.items():
        n = sum(c[o] for o in OUTCOMES)
        out.append(f"{label:13s} {kind:15s} {n:5d} " + " ".join(f"{c[o]:8d}" for o in OUTCOMES)
                   + f"  {c['head out']}")
        for o in OUTCOMES:
            totals[label][o] += c[o]
    out.append("")
    for label, c in totals.items():
        n = sum(c[o] for o in OUTCOMES)
        out.append(f"{label:13s} {'all':15s} {n:5d} " + " ".join(f"{c[o]:8d}" for o in OUTCOMES))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=40, help="chords of the plan (steps = lines + 1)")
    ap.add_argument("--picture", default="camera.png", help="a picture in examples/")
    ap.add_argument("--machines", nargs="*", default=GCODE + SERVO)
    ap.add_argument("--kinds", nargs="*", default=LINE_KINDS + [f"{k}+0.5" for k in MID_KINDS]
                    + [f"uno-{k}" for k in UNO_KINDS] + [f"first-{k}" for k in FIRST_KINDS]
                    + ["start", "dynamixel", "host-kill", "host-int", "sim-kill"])
    ap.add_argument("--points", type=int, default=5, help="fault points per kind (5: ring, out, hook, "
                    "hook-sync, in; mid-move kinds skip hook-sync)")
    ap.add_argument("--kills", type=int, default=5, help="host SIGKILLs in the host-kill case")
    ap.add_argument("--workers", type=int, default=2, help="cases run at once (at most 2)")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds one command may take")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--only", default=None, help="run only the cases whose name holds this text "
                    "(e.g. 'grbl-ring power@179+0.5')")
    ap.add_argument("--verbose", action="store_true", help="one line per case, with the resumes it took")
    ap.add_argument("--logs", default=None, help="folder for the logs of every case that is not exact "
                    "(default: a temporary folder, kept and named)")
    args = ap.parse_args()
    workdir = tempfile.mkdtemp(prefix="fault-matrix-")
    logs = Path(args.logs or Path(workdir) / "logs")
    logs.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    cases, plans = build_cases(workdir, args.machines, args.kinds, args.points, args.kills, args.seed,
                               lambda name: make_plan(workdir, name, args.lines, args.picture))
    if args.only:
        cases = [c for c in cases if args.only in c.name]
    steps = {n: len(json.loads(Path(p).read_text())["sequence"]) for n, p in plans.items()}
    print(f"plan: examples/{args.picture}, {args.lines} lines, 300 pins: "
          + ", ".join(f"{n} {s} steps" for n, s in steps.items()))
    print(f"{len(cases)} cases, {args.workers} at a time; load average {os.getloadavg()[0]:.2f}", flush=True)

    def progress(r):
        if args.verbose:
            ways = [_way(e) for e in r["log"]]
            print(f"  {r['outcome']:7s} {r['case']} ({r.get('point', '')}): {' '.join(ways)}", flush=True)
        elif r["outcome"] != "exact":
            print(f"  {r['outcome']:7s} {r['case']} ({r.get('point', '')}): {r['why']}", flush=True)
    results = run_matrix(cases, plans, workdir, workers=args.workers, timeout=args.timeout, progress=progress)
    print()
    for line in table_lines(results):
        print(line)
    bad = [r for r in results if r["outcome"] != "exact"]
    for i, r in enumerate(bad):
        name = re.sub(r"[^\w@.+-]+", "_", r["case"])
        (logs / f"{i:03d}-{r['outcome']}-{name}.log").write_text(
            f"{r['case']} ({r.get('point', '')}): {r['outcome']}: {r['why']}\n\n" + "\n".join(r["log"]))
    n = Counter(r["outcome"] for r in results)
    print(f"\ntotal {len(results)}: " + ", ".join(f"{o} {n[o]}" for o in OUTCOMES)
          + f"; {time.monotonic() - t0:.0f} s, load average {os.getloadavg()[0]:.2f}")
    if bad:
        print(f"logs of the {len(bad)} cases that were not exact: {logs}")
    for r in results:
        if r.get("work") and r["outcome"] == "exact":
            shutil.rmtree(r["work"], ignore_errors=True)
    return 1 if n["silent"] or n["hung"] or n["dead end"] else 0


if __name__ == "__main__":
    sys.exit(main())
