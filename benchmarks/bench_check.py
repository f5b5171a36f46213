"""What the settings check adds to the start of a winding, per bundled machine.

Two figures, median of N runs each (give the load average with them: the machine is shared):

1. ``stringbot wind PLAN --machine M --yes`` dry runs of a 3-pin plan, as a user runs them (a new
   process each time), with and without ``--no-check``;
2. in one process, ``wind_plan`` on a fresh simulated machine with ``check=True`` and ``False``
   (no interpreter start-up in the figure), and ``check_link`` alone;
3. ``check_link`` over a pseudo-terminal to ``stringbot simulate`` in its own process (the real
   pyserial / dynamixel-sdk port code; bytes cross the pty): the check's own exchanges, read
   afresh (for GRBL the winding's identification reads ``$$`` anyway, so there the check adds no
   exchange at all).

    python benchmarks/bench_check.py [--runs 9]
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

MACHINES = ["grbl-ring", "grblhal-ring", "fluidnc-ring", "marlin-ring", "dynamixel-ring"]
STRINGBOT = [sys.executable, "-c", "import sys; from stringbot.cli import main; main(sys.argv[1:])"]


def cli_runs(plan, machine, runs, extra):
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        done = subprocess.run(STRINGBOT + ["wind", str(plan), "--machine", machine, "--yes", "--force"] + extra,
                              capture_output=True, text=True)
        times.append(time.perf_counter() - t0)
        if done.returncode != 0:
            raise SystemExit(f"{machine}: {done.stderr}")
    return statistics.median(times)


def in_process(plan, machine, runs, folder):
    from firmware_protocol.machine import load_machine
    from firmware_protocol.urlhandler import protocol_sim
    from stringbot.links import open_link, sim_url
    from stringbot.links.settings_check import check_link
    from stringbot.winding import Job, wind_plan

    m = load_machine(machine)
    out = {True: [], False: [], "check": []}
    for i in range(runs):
        for check in (True, False):
            url = sim_url(machine, record=folder / f"{machine}-{i}-{check}.json")
            job = Job(plan, m, port=url, journal=folder / f"{machine}-{i}-{check}.journal")
            t0 = time.perf_counter()
            wind_plan(job, confirm=None, check=check, eyes=lambda: protocol_sim.look(url))
            out[check].append(time.perf_counter() - t0)
            protocol_sim.forget(url)
        url = sim_url(machine, record=folder / f"{machine}-{i}-alone.json")
        link = open_link(url, m)
        link.identify()
        t0 = time.perf_counter()
        check_link(link, m)
        out["check"].append(time.perf_counter() - t0)
        link.close()
        protocol_sim.forget(url)
    return {k: statistics.median(v) for k, v in out.items()}


def over_pty(machine, runs, folder):
    from firmware_protocol.machine import load_machine
    from stringbot.links import open_link
    from stringbot.links.settings_check import check_link

    pty = folder / f"{machine}.pty"
    sim = subprocess.Popen(STRINGBOT + ["simulate", "--machine", machine, "--pty", str(pty)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 30
        while not os.path.exists(os.path.realpath(pty)) or not pty.is_symlink():
            if time.monotonic() > deadline:
                raise SystemExit(f"{machine}: the simulator did not start")
            time.sleep(0.05)
        m = load_machine(machine)
        link = open_link(str(pty), m)
        link.identify()
        times = []
        for _ in range(runs):
            t0 = time.perf_counter()
            report = check_link(link, m, fresh=True)
            times.append(time.perf_counter() - t0)
            assert report.agrees
        link.close()
        return statistics.median(times)
    finally:
        sim.send_signal(2)
        sim.wait(timeout=10)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=9)
    args = parser.parse_args()
    from stringbot.planner import write_plan
    from test_wind_sim import small_plan

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        plan = folder / "plan.json"
        write_plan(small_plan(n=3, seed=1), plan)
        print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}; "
              f"median of {args.runs} runs; 3-pin plan")
        print(f"{'machine':<16} {'CLI check':>10} {'CLI --no-check':>15} {'adds':>7}   "
              f"{'wind_plan check':>15} {'no check':>9} {'adds':>7}   {'check_link':>10}")
        for machine in MACHINES:
            with_check = cli_runs(plan, machine, args.runs, [])
            without = cli_runs(plan, machine, args.runs, ["--no-check"])
            inner = in_process(plan, machine, args.runs, folder)
            print(f"{machine:<16} {with_check:>9.3f}s {without:>14.3f}s {1000 * (with_check - without):>5.0f}ms   "
                  f"{inner[True]:>14.3f}s {inner[False]:>8.3f}s {1000 * (inner[True] - inner[False]):>5.0f}ms   "
                  f"{1000 * inner['check']:>8.1f}ms")
        print(f"check_link over a pty to the simulator in its own process (read afresh), median of {args.runs}:")
        for machine in MACHINES:
            print(f"  {machine:<16} {1000 * over_pty(machine, args.runs, folder):6.1f} ms")
        print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
