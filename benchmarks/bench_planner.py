"""Speed and memory of `stringbot plan`: whole commands in fresh processes.

Prints wall time (until the command ends), CPU time (user + system of the
command and of its helper processes: on a shared machine the wall time also
counts the time other jobs had the cores), peak memory (max RSS of its largest
process) and the load average for

* the default method (residual, polish included, on two cores where there
  are two), the same in one process (``STRINGBOT_PROCESSES=1``) and with
  ``--polish 0`` (what the polish costs), fitness and greedy (ThreadTone's
  1001 px), 300 pins, 401 px, auto lines, camera.png, with a cold chord cache
  (an empty cache folder) and a warm one;
* the default method and fitness at 600 pins, 801 px (cold and warm);
* with ``--pictures DIR``: the default plan of every picture in DIR
  (``stringbot plan IMG --machine grbl-ring``), median of ``--repeat`` runs.

This machine's speed drifts (a virtual machine sharing its host): the same
command can take 20 % more or less from one hour to the next.  The first and
last lines time a fixed numpy workload (the chooser's inner step, 2000 times)
so that runs made at different times can be compared.

The command timed is the ``stringbot`` beside the interpreter that runs the
benchmark (a venv's: run it with the venv's python, as the README sets up),
with the package's bytecode compiled first (``--no-compile``: not).

Usage: python benchmarks/bench_planner.py [IMAGE] [--repeat N] [--skip-600] [--methods residual,fitness,greedy]
           [--pictures DIR] [--no-compile]
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
sys.path.insert(0, str(ROOT))
from stringbot.planner.methods import METHODS  # noqa: E402


def _command():
    """The ``stringbot`` a user of this interpreter runs: the console script beside it (a venv's, as the
    README installs it), else the one on PATH (a version manager's shim, such as pyenv's, adds about
    0.1 s to every run), else ``python -c``."""
    beside = Path(sys.executable).parent / "stringbot"
    if beside.is_file():
        return [str(beside)]
    exe = shutil.which("stringbot")
    return [exe] if exe else [sys.executable, "-c", "from stringbot.cli import main; main()"]


def _compile_bytecode():
    """Compile the package's bytecode, as ``pip install`` does for a regular install and any first run
    does after an editable one (unless ``PYTHONDONTWRITEBYTECODE`` is set: then every run compiles the
    sources again, about 0.06 s more).  Returns the package's folder."""
    import compileall

    import stringbot

    pkg = Path(stringbot.__file__).parent
    compileall.compile_dir(pkg, quiet=1)
    return pkg


def reference_seconds():
    """A fixed workload: 2000 gathers of 75 000 points and their sums per chord (the chooser's step)."""
    import numpy as np

    rng = np.random.default_rng(0)
    g = rng.random(401 * 401).astype(np.float32)
    pix = np.sort(rng.integers(0, g.size, 75_000)).astype(np.int32)
    starts = np.linspace(0, len(pix) - 1, 300).astype(np.int64)
    t = time.perf_counter()
    for _ in range(2000):
        np.add.reduceat(g.take(pix), starts)
    return time.perf_counter() - t


def _adopt_orphans():
    """Make this process the reaper of its descendants' orphans (Linux), so that the CPU time and peak
    memory of the plan's helper processes, which may end just after the command, are counted."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # PR_SET_CHILD_SUBREAPER
    except (OSError, AttributeError):
        pass


def _reap_all():
    """Wait for every process left to this one (the helpers ending after the command)."""
    while True:
        try:
            os.wait()
        except ChildProcessError:
            return


def run_once(args, cache, env_extra=None):
    """Run `stringbot plan ...` in a fresh process; return (wall seconds until the command ends, cpu
    seconds of it and its helper processes, stdout)."""
    import resource

    env = dict(os.environ, STRINGBOT_CACHE=str(cache), **(env_extra or {}))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    p = subprocess.run(_command() + ["plan", *args], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t
    _reap_all()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        raise SystemExit(f"failed: {' '.join(args)}\n{p.stderr}")
    return wall, cpu, p.stdout.strip()


def peak_of(args, cache, env_extra=None):
    """Peak RSS of one run (its largest process), measured alone in a helper process (children's maxrss
    is cumulative)."""
    code = ("import resource, subprocess, sys, os, ctypes\n"
            "try:\n    ctypes.CDLL(None).prctl(36, 1, 0, 0, 0)\nexcept (OSError, AttributeError):\n    pass\n"
            "p = subprocess.run(sys.argv[1:], capture_output=True)\n"
            "while True:\n    try:\n        os.wait()\n    except ChildProcessError:\n        break\n"
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0)")
    env = dict(os.environ, STRINGBOT_CACHE=str(cache), **(env_extra or {}))
    p = subprocess.run([sys.executable, "-c", code, *_command(), "plan", *args], capture_output=True, text=True, env=env)
    return float(p.stdout.strip())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("image", nargs="?", default=str(DEFAULT_IMAGE))
    ap.add_argument("--repeat", type=int, default=3, help="warm runs per case (best and median printed)")
    ap.add_argument("--skip-600", action="store_true", help="skip the 600-pin, 801-px case")
    ap.add_argument("--methods", default=",".join(METHODS), help="methods to run (comma-separated)")
    ap.add_argument("--pictures", default=None, help="also time the default plan of every picture in this folder")
    ap.add_argument("--no-compile", action="store_true",
                    help="do not compile the package's bytecode first (what every run costs with PYTHONDONTWRITEBYTECODE)")
    opts = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="stringbot-bench-"))
    one = {"STRINGBOT_PROCESSES": "1"}
    cases = [("residual", ["--pins", "300", "--size", "401"], None),
             ("residual", ["--pins", "300", "--size", "401"], one),
             ("residual", ["--pins", "300", "--size", "401", "--polish", "0"], None),
             ("fitness", ["--pins", "300", "--size", "401"], None), ("greedy", ["--pins", "300", "--size", "1001"], None)]
    if not opts.skip_600:
        cases += [("residual", ["--pins", "600", "--size", "801"], None),
                  ("fitness", ["--pins", "600", "--size", "801"], None)]
    cases += [(m, ["--pins", "300"], None) for m in METHODS if m not in {c[0] for c in cases}]  # at its own size
    unknown = set(opts.methods.split(",")) - set(METHODS)
    if unknown:
        raise SystemExit(f"--methods {opts.methods}: unknown {', '.join(sorted(unknown))}; expected {', '.join(METHODS)}")
    cases = [c for c in cases if c[0] in opts.methods.split(",")]
    _adopt_orphans()
    print(f"image {opts.image}; {os.cpu_count()} cores; python {sys.version.split()[0]}; command {' '.join(_command())}")
    if opts.no_compile:
        print("bytecode: as it is (PYTHONDONTWRITEBYTECODE=%s)" % os.environ.get("PYTHONDONTWRITEBYTECODE", ""))
    else:
        print(f"bytecode: compiled in {_compile_bytecode()} first, as pip install or a first run does")
    print(f"machine speed: reference workload {reference_seconds():.2f} s")
    print(f"{'case':<36} {'cache':<6} {'wall s':>7} {'cpu s':>6} {'peak MB':>8} {'load':>5}  summary")
    try:
        for method, extra, env in cases:
            name = (f"{method} {extra[1]} pins {extra[3]} px" + (" nopolish" if "--polish" in extra else "")
                    + (" 1 process" if env else ""))
            args = [opts.image, "-o", str(work / "p.json"), "--method", method, *extra]
            cache = work / f"cache-{method}-{'-'.join(extra[1::2])}"
            shutil.rmtree(cache, ignore_errors=True)
            cache.mkdir()
            wall, cpu, out = run_once(args, cache, env)          # cold: empty cache folder
            load = os.getloadavg()[0]
            shutil.rmtree(cache)
            cache.mkdir()
            peak = peak_of(args, cache, env)
            print(f"{name:<36} {'cold':<6} {wall:7.2f} {cpu:6.2f} {peak:8.0f} {load:5.1f}  {out.split(' -> ')[0]}")
            runs = []
            for _ in range(max(1, opts.repeat)):
                runs.append(run_once(args, cache, env)[:2])
            peak = peak_of(args, cache, env)
            runs.sort()
            wall, cpu = runs[len(runs) // 2]
            print(f"{name:<36} {'warm':<6} {wall:7.2f} {cpu:6.2f} {peak:8.0f} {os.getloadavg()[0]:5.1f}  "
                  f"(best {runs[0][0]:.2f} s of {len(runs)})")
            sys.stdout.flush()
        if opts.pictures:
            print(f"{'default plan, --machine grbl-ring':<36} {'median':>6} {'min':>6} {'max':>6} {'cpu s':>6}")
            for img in sorted(Path(opts.pictures).glob("*.png")):
                runs = sorted(run_once([str(img), "-o", str(work / "p.json"), "--machine", "grbl-ring"],
                                       work)[:2] for _ in range(max(1, opts.repeat)))
                walls = sorted(r[0] for r in runs)
                print(f"{img.stem:<36} {walls[len(walls) // 2]:6.2f} {walls[0]:6.2f} {walls[-1]:6.2f} "
                      f"{runs[len(runs) // 2][1]:6.2f}")
                sys.stdout.flush()
        print(f"machine speed: reference workload {reference_seconds():.2f} s")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
