"""How low could any plan of these pins go?  A relaxed optimum of the as-woven error, against ours.

Every chord of the 300 pins gets a density ``x`` in [0, 1] (no path to
follow, a chord may be half drawn), and the darkness of a pixel is the
union's expectation ``D = 1 - exp(-A x)`` (``A``: each chord's coverage of
each 401-px pixel, as the chooser's union model measures it, a 0.25 mm
thread on 500 mm).  ``x`` minimises the as-woven error at 401 px (the
picture's luminance, both blurred by 2 px of 512, over the frame) by
L-BFGS-B.  That relaxed error is below what a plan can reach (a plan draws
whole chords, in one thread); the chords with ``x > 0.5``, drawn whole but
in no order, give a second figure.  Our plan (``stringbot plan IMG
--machine grbl-ring``) is scored on the same yardstick, and by ``stringbot
score``'s: ``scaled`` is the relaxed figure times their ratio, the as-woven
error a plan would need to match the relaxation on ``score``'s yardstick.

Usage: python benchmarks/bench_relaxed_bound.py [--only NAMES] [--iterations N] [--plans DIR]
(a few minutes a picture: the coverage has 14 million entries)
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = next((d / "shared" for d in ROOT.parents if (d / "shared" / "images").is_dir()), ROOT.parent / "shared")
SIZE = 401


def coverage(space, width_px):
    """The chords' coverage of the pixels, ``(A, A^T)`` as CSR (pixels x chords), by the chooser's union."""
    import scipy.sparse as sp

    from stringbot.planner.methods.canvas import Canvas

    blank = np.zeros((SIZE, SIZE))
    canvas = Canvas(blank, blank, space.pin_xy, width_px)
    rows, cols, vals = [], [], []
    for c, (a, b) in enumerate(space.ends):
        pix, cover = canvas.footprint(int(a), int(b))
        rows.append(pix)
        cols.append(np.full(len(pix), c))
        vals.append(cover)
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(SIZE * SIZE, space.m))
    return A, A.T.tocsr()


def objective(A, AT, target, mask):
    """``f(x) -> (E, grad)``: the blurred error of ``D = 1 - exp(-A x)`` over the frame, and its gradient."""
    from scipy.ndimage import gaussian_filter

    from stringbot.planner.model.scoring import WOVEN_SIGMA, WOVEN_SIZE

    sg = WOVEN_SIGMA * SIZE / WOVEN_SIZE
    m = mask.ravel().astype(np.float64)
    t = target.ravel()

    def blur(v):
        return gaussian_filter(v.reshape(SIZE, SIZE), sg, mode="constant").ravel()

    def f(x):
        ex = np.exp(-(A @ x))
        r = blur(m * (t - (1.0 - ex))) * m
        return float(r @ r), AT @ (ex * (-2.0 * m * blur(m * r)))
    return f


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", default=str(SHARED / "images"))
    ap.add_argument("--only", default="horse,astronaut", help="comma-separated picture names")
    ap.add_argument("--iterations", type=int, default=1500)
    ap.add_argument("--plans", default=None, help="folder of our plans (NAME.json), made where missing")
    opts = ap.parse_args()
    from scipy.optimize import minimize

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_model_agreement import our_plans
    from quality_table import score_plan

    from stringbot.planner.knobs import thread_model
    from stringbot.planner.model.chords import chord_space, frame_mask
    from stringbot.planner.model.scoring import LUMINANCE
    from stringbot.planner.picture.read import read_picture

    images = Path(opts.images)
    names = opts.only.split(",")
    ours = our_plans(names, images, opts.plans)
    space = chord_space(300, "circle")
    model = thread_model(500.0, 0.25)
    t0 = time.perf_counter()
    A, AT = coverage(space, model.width_px(SIZE))
    print(f"coverage: {A.nnz} entries, {time.perf_counter() - t0:.0f} s", flush=True)
    mask = frame_mask(SIZE, "circle")
    area = float(mask.sum())
    for name in names:
        plan = ours[name]
        pic = read_picture(images / f"{name}.png", size=SIZE, crop=plan.crop, gray="luminance", weights=LUMINANCE)
        f = objective(A, AT, np.where(mask, 1.0 - pic.gray / 255.0, 0.0), mask)
        t = time.perf_counter()
        res = minimize(f, np.full(space.m, 0.02), jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * space.m,
                       options={"maxiter": opts.iterations})
        x = res.x
        whole = (x > 0.5).astype(np.float64)
        drawn = np.zeros(space.m)
        drawn[[space.index[a, b] for a, b in plan.chord_list()]] = 1.0
        relaxed, rounded, here = (float(np.sqrt(f(v)[0] / area)) for v in (x, whole, drawn))
        scored = score_plan(plan, images / f"{name}.png")["woven_error"]
        print(f"{name:<10} relaxed {relaxed:.4f} ({res.nit} iterations, {time.perf_counter() - t:.0f} s; "
              f"{x.sum():.0f} chords' worth, {int(whole.sum())} over 0.5)  whole chords {rounded:.4f}  "
              f"ours ({len(plan.chord_list())} lines) {here:.4f} here, {scored:.4f} scored  "
              f"scaled: relaxed {relaxed * scored / here:.4f}, whole chords {rounded * scored / here:.4f}", flush=True)


if __name__ == "__main__":
    main()
