"""The default plan's critical path in CPU seconds: what an idle two-core machine would wait for.

On a machine shared with other jobs the wall time measures the load, and the
CPU time of all the processes (``bench_planner.py``) counts the helper's work
that runs beside the planner's.  This counts, in fresh processes (Python
start-up and imports included):

* the planner's own process: its CPU time (user + system), which leaves out
  its waits for the helper processes;
* plus, for the polish on two cores, the slower of the two polishing sides
  (``polish_rounds`` in the helper and in its twin: the planner's process waits
  for them);
* plus the slower of the two halves of the preview that the twin and the
  helper draw after the polish (``TwinDrawing.make``; the planner's process
  waits for them, less the machine estimate it makes meanwhile: counted twice,
  about 0.03 s).

The helper's work before the polish (finishing its canvas, ordering the pins,
forking the twin: 0.02-0.03 s) is left out.  The helpers' CPU is taken with
``time.process_time`` around those calls and sent back through a pipe.

Usage: python benchmarks/bench_critical_path.py [--repeat N] [PLAN ARGS ...]
       (default: ``camera.png --machine grbl-ring``; ``-o`` is added)
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = next((d / "shared" for d in ROOT.parents if (d / "shared" / "images").is_dir()), ROOT.parent / "shared")


def child(fd, argv):
    """Run ``stringbot plan`` here; write the figures to file descriptor ``fd``."""
    from stringbot.cli import main  # first: it keeps numpy's BLAS on one thread
    from stringbot.planner.methods import polish, woven_helper

    pid0 = os.getpid()

    def timed(owner, name, tag):
        f = getattr(owner, name)

        def g(*a, **k):
            c = time.process_time()
            try:
                return f(*a, **k)
            finally:
                if os.getpid() != pid0:  # a helper: its figure goes back before it ends
                    os.write(fd, f"{tag} {time.process_time() - c:.4f}\n".encode())
        setattr(owner, name, g)

    timed(polish, "polish_rounds", "polish")
    timed(woven_helper.TwinDrawing, "make", "preview")
    try:
        main(["plan", *argv])
    except SystemExit as exc:
        if exc.code:
            raise
    os.write(fd, f"main {time.process_time():.4f}\n".encode())  # since the process started


def run_once(argv, out):
    """One fresh process; returns (critical path, main, polish sides, preview halves) in CPU seconds."""
    r, w = os.pipe()
    code = f"import sys; sys.path.insert(0, {str(ROOT)!r}); import bench_critical_path as b; b.child({w}, sys.argv[1:])"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "benchmarks"))
    p = subprocess.run([sys.executable, "-c", code, *argv, "-o", str(out)], pass_fds=(w,), env=env,
                       capture_output=True, text=True)
    os.close(w)
    with os.fdopen(r) as f:
        rows = [line.split() for line in f.read().splitlines()]
    if p.returncode != 0:
        raise SystemExit(f"failed: {' '.join(argv)}\n{p.stderr}")
    main = sum(float(v) for k, v in rows if k == "main")
    pol = [float(v) for k, v in rows if k == "polish"]
    pre = [float(v) for k, v in rows if k == "preview"]
    return main + max(pol, default=0.0) + max(pre, default=0.0), main, pol, pre


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    opts, argv = ap.parse_known_args()
    argv = argv or [str(SHARED / "images" / "camera.png"), "--machine", "grbl-ring"]
    with tempfile.TemporaryDirectory(prefix="stringbot-crit-") as work:
        print(f"stringbot plan {' '.join(argv)}; load {os.getloadavg()[0]:.1f}")
        print(f"{'critical s':>10} {'planner s':>9}  polish sides s  preview halves s")
        for _ in range(max(1, opts.repeat)):
            crit, main_s, pol, pre = run_once(argv, Path(work) / "p.json")
            print(f"{crit:10.3f} {main_s:9.3f}  {' / '.join(f'{v:.3f}' for v in pol) or '-':<14}  "
                  f"{' / '.join(f'{v:.3f}' for v in pre) or '-'}")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
