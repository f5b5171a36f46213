"""Speed and memory of `stringbot plan`: whole commands in fresh processes.

Prints wall time and peak memory (max RSS of the child) for

* fitness and greedy, 300 pins, 401 px, auto lines, camera.png, with a cold
  chord cache (an empty cache folder) and a warm one;
* fitness at 600 pins, 801 px (cold and warm).

Usage: python benchmarks/bench_planner.py [IMAGE] [--repeat N]
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
DEFAULT_IMAGE = ROOT.parent / "shared" / "images" / "camera.png"


def _command():
    exe = shutil.which("stringbot")
    return [exe] if exe else [sys.executable, "-c", "from stringbot.cli import main; main()"]


def run_once(args, cache):
    """Run `stringbot plan ...` in a fresh process; return (wall seconds, stdout)."""
    env = dict(os.environ, STRINGBOT_CACHE=str(cache))
    t = time.perf_counter()
    p = subprocess.run(_command() + ["plan", *args], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        raise SystemExit(f"failed: {' '.join(args)}\n{p.stderr}")
    return wall, p.stdout.strip()


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
    opts = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="stringbot-bench-"))
    cases = [("fitness", ["--pins", "300", "--size", "401"]), ("greedy", ["--pins", "300", "--size", "401"])]
    if not opts.skip_600:
        cases.append(("fitness", ["--pins", "600", "--size", "801"]))
    print(f"image {opts.image}; {os.cpu_count()} cores; python {sys.version.split()[0]}")
    print(f"{'case':<28} {'cache':<6} {'wall s':>7} {'peak MB':>8}  summary")
    try:
        for method, extra in cases:
            name = f"{method} {extra[1]} pins {extra[3]} px"
            args = [opts.image, "-o", str(work / "p.json"), "--method", method, *extra]
            cache = work / f"cache-{method}-{extra[1]}-{extra[3]}"
            shutil.rmtree(cache, ignore_errors=True)
            cache.mkdir()
            wall, out = run_once(args, cache)          # cold: empty cache folder
            shutil.rmtree(cache)
            cache.mkdir()
            peak = peak_of(args, cache)
            print(f"{name:<28} {'cold':<6} {wall:7.2f} {peak:8.0f}  {out.split(' -> ')[0]}")
            walls = []
            for _ in range(max(1, opts.repeat)):
                walls.append(run_once(args, cache)[0])
            peak = peak_of(args, cache)
            walls.sort()
            print(f"{name:<28} {'warm':<6} {walls[len(walls) // 2]:7.2f} {peak:8.0f}  "
                  f"(best {walls[0]:.2f} s of {len(walls)})")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
