"""Speed and memory of `stringbot plan`: whole commands in fresh processes.

Prints wall time, CPU time (user + system of the child: on a shared machine
the wall time also counts the time other jobs had the cores), peak memory (max
RSS of the child) and the load average for

* the default method (residual, polish included), the same with
  ``--polish 0`` (what the polish costs), fitness and greedy (ThreadTone's
  1001 px), 300 pins, 401 px, auto lines, camera.png, with a cold chord cache
  (an empty cache folder) and a warm one;
* the default method and fitness at 600 pins, 801 px (cold and warm).

Usage: python benchmarks/bench_planner.py [IMAGE] [--repeat N] [--skip-600] [--methods residual,fitness,greedy]
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = next((d / "shared" for d in ROOT.parents if (d / "shared" / "images").is_dir()), ROOT.parent / "shared")
DEFAULT_IMAGE = SHARED / "images" / "camera.png"


def _command():
    exe = shutil.which("stringbot")
    return [exe] if exe else [sys.executable, "-c", "from stringbot.cli import main; main()"]


def run_once(args, cache):
    """Run `stringbot plan ...` in a fresh process; return (wall seconds, cpu seconds, stdout)."""
    import resource

    env = dict(os.environ, STRINGBOT_CACHE=str(cache))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    p = subprocess.run(_command() + ["plan", *args], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        raise SystemExit(f"failed: {' '.join(args)}\n{p.stderr}")
    return wall, cpu, p.stdout.strip()


def peak_of(args, cache):
    """Peak RSS of one run, measured alone in a helper process (children's maxrss is cumulative)."""
    code = ("import resource, subprocess, sys, os;"
            "p = subprocess.run(sys.argv[1:], capture_output=True);"
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0)")
    env = dict(os.environ, STRINGBOT_CACHE=str(cache))
    p = subprocess.run([sys.executable, "-c", code, *_command(), "plan", *args], capture_output=True, text=True, env=env)
    return float(p.stdout.strip())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("image", nargs="?", default=str(DEFAULT_IMAGE))
    ap.add_argument("--repeat", type=int, default=3, help="warm runs per case (best and median printed)")
    ap.add_argument("--skip-600", action="store_true", help="skip the 600-pin, 801-px case")
    ap.add_argument("--methods", default="residual,fitness,greedy", help="methods to run (comma-separated)")
    opts = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="stringbot-bench-"))
    cases = [("residual", ["--pins", "300", "--size", "401"]), ("residual", ["--pins", "300", "--size", "401",
                                                                             "--polish", "0"]),
             ("fitness", ["--pins", "300", "--size", "401"]), ("greedy", ["--pins", "300", "--size", "1001"])]
    if not opts.skip_600:
        cases += [("residual", ["--pins", "600", "--size", "801"]), ("fitness", ["--pins", "600", "--size", "801"])]
    unknown = set(opts.methods.split(",")) - {"residual", "fitness", "greedy"}
    if unknown:
        raise SystemExit(f"--methods {opts.methods}: unknown {', '.join(sorted(unknown))}; expected residual, fitness, greedy")
    cases = [c for c in cases if c[0] in opts.methods.split(",")]
    print(f"image {opts.image}; {os.cpu_count()} cores; python {sys.version.split()[0]}")
    print(f"{'case':<36} {'cache':<6} {'wall s':>7} {'cpu s':>6} {'peak MB':>8} {'load':>5}  summary")
    try:
        for method, extra in cases:
            name = f"{method} {extra[1]} pins {extra[3]} px" + (" nopolish" if "--polish" in extra else "")
            args = [opts.image, "-o", str(work / "p.json"), "--method", method, *extra]
            cache = work / f"cache-{method}-{'-'.join(extra[1::2])}"
            shutil.rmtree(cache, ignore_errors=True)
            cache.mkdir()
            wall, cpu, out = run_once(args, cache)          # cold: empty cache folder
            load = os.getloadavg()[0]
            shutil.rmtree(cache)
            cache.mkdir()
            peak = peak_of(args, cache)
            print(f"{name:<36} {'cold':<6} {wall:7.2f} {cpu:6.2f} {peak:8.0f} {load:5.1f}  {out.split(' -> ')[0]}")
            runs = []
            for _ in range(max(1, opts.repeat)):
                runs.append(run_once(args, cache)[:2])
            peak = peak_of(args, cache)
            runs.sort()
            wall, cpu = runs[len(runs) // 2]
            print(f"{name:<36} {'warm':<6} {wall:7.2f} {cpu:6.2f} {peak:8.0f} {os.getloadavg()[0]:5.1f}  "
                  f"(best {runs[0][0]:.2f} s of {len(runs)})")
            sys.stdout.flush()
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
