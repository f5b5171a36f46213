"""``--method fitness``, the paper's: the fitness of every chord (section 3.2), then sampling (3.3).

:func:`run` solves for the fitness of every chord, then samples the sequence
with error diffusion (:mod:`.sampling`; or, ``disconnected``, the
priority-queue chord set).  The knobs beta, gamma and T come in two *styles*:
``detail`` (the paper's defaults, 5 / 10 / 30) and ``fill`` (:data:`FILL`:
regularisation 30 times stronger and a sharp mapping, T = 1: a chord's
fitness is then close to its weighted mean darkness and next to no error is
diffused, so large flat dark areas are filled).  ``auto`` (the default)
plans both and keeps the drawing that scores higher by the paper's own
measure (section 4.1: SSIM plain plus blurred, with both the Gaussian and the
uniform window, summed, so that no one variant decides; see
:mod:`stringbot.planner.model.scoring`).  Giving beta, gamma or T means
``detail`` with those values.

The solve: a regularised least-squares problem.

Minimise ``E(f) = ||W (A f - b)||^2 + ||V f||^2`` where

* ``A`` (pixels x chords) has ``A[p, c] = 1`` when chord ``c`` covers pixel ``p``;
* ``b = (1 - alpha) I + alpha |g|``, ``I`` the reversed (inverted) gray image
  in [0, 255] and ``|g|`` its gradient magnitude;
* ``W = diag(w)``: 1 inside the frame (2 on important pixels), 0 outside;
* ``V = diag(v)``, ``v_c = beta exp(-s_c / P) + gamma d_c / max(d)``, ``s_c``
  the chord's span in pins and ``d_c`` the mean over its pixels of the cross
  product of the chord's unit direction ``e_c`` with the edge at the pixel.

The edge term follows the paper's words: "the cross product gives larger
result if the chord is not aligned with the edges.  Such chords are
suppressed".  For that, the vector crossed with ``e_c`` must lie *along* the
edge: the edge tangent ``t_p`` (the gradient ``g_p`` turned by 90 degrees,
same length), so ``|t_p x e_c| = |g_p . e_c|``: zero for a chord running
along an edge, ``|g_p|`` for one crossing it.  (Crossed with the gradient
itself, the formula would suppress the chords that follow edges, the
opposite of what the paper says the term is for.)

The solve is :func:`scipy.sparse.linalg.lsqr` on the stacked system
``[W A; V] f = [W b; 0]`` as a LinearOperator with the columns scaled to unit
norm (a Jacobi preconditioner), its sparse products in float32.  The scaling
changes the iterates, not the minimiser: ``f`` comes back in the units of
``b`` (levels of the reversed picture per chord).
"""

import logging
import time

import numpy as np

from ...errors import BadInput
from ..progress import report
from . import DEFAULTS, Outcome

log = logging.getLogger(__name__)

__all__ = ["run", "style_candidates", "gradients", "edge_consistency", "chord_weights", "solve_fitness", "STYLES",
           "FILL"]

STYLES = ("auto", "detail", "fill")
#: The ``fill`` style: the paper's regularisation weights times 30 and a sharp tanh.
FILL = {"beta": 150.0, "gamma": 300.0, "T": 1.0}


def style_candidates(style, *, beta=None, gamma=None, T=None):
    """The fitness knob settings to try.

    Parameters
    ----------
    style : {"auto", "detail", "fill"} or None
        None is ``auto``.
    beta, gamma, T : float or None
        Knobs given by the user (None: not given).

    Returns
    -------
    list of (str, dict)
        ``[(style name, {"beta": float, "gamma": float, "T": float}), ...]``:
        both styles for ``auto``, unless beta, gamma or T is given (then
        ``detail`` with those values and the paper's defaults for the rest).
    """
    given = {k: v for k, v in (("beta", beta), ("gamma", gamma), ("T", T)) if v is not None}
    detail = {k: float(given.get(k, DEFAULTS[k])) for k in ("beta", "gamma", "T")}
    if style == "fill":
        return [("fill", dict(FILL))]
    if style == "detail" or given:
        return [("detail", detail)]
    if style not in (None, "auto"):
        raise ValueError(f"style {style!r}; expected one of {STYLES}")
    return [("detail", detail), ("fill", dict(FILL))]


def run(job):
    """``--method fitness`` through the methods' contract (:mod:`stringbot.planner.methods`): each style's
    solve and sampling, the one that scores higher against ``job.reference()`` kept (see the module notes)."""
    from ..model.chords import pixel_chords

    k = job.knobs
    space = job.space
    rowptr, chords_of_pixel = pixel_chords(space, k["size"], cache=k["cache"])
    stats = {"pixels_per_chord": round(float(len(chords_of_pixel) / max(space.m, 1)), 2)}
    candidates = style_candidates(k["style"], beta=k["beta"], gamma=k["gamma"], T=k["T"])
    runs = _runs(space, job.picture, job.mask, job.weights, rowptr, chords_of_pixel, job.lines, alpha=k["alpha"],
                 epsilon=k["epsilon"], iterations=k["iterations"], start_pin=job.start_pin,
                 disconnected=k["disconnected"], candidates=candidates,
                 reference=job.reference() if len(candidates) > 1 else None)
    del rowptr, chords_of_pixel
    best = max(runs, key=lambda r: r["rank"])
    params = {"alpha": k["alpha"], "epsilon": k["epsilon"], "iterations": k["iterations"],
              "style_requested": k["style"] or "auto", "style": best["style"], **best["knobs"]}
    stats.update(best["stats"])
    if len(runs) > 1:
        stats["styles"] = {r["style"]: dict(r["scores"], solve_seconds=r["stats"]["solve_seconds"]) for r in runs}
    return Outcome(best["seq"], params, stats, chords=best["chords"])


def _runs(space, pic, mask, weights, rowptr, chords_of_pixel, k, *, alpha, epsilon, iterations, start_pin,
          disconnected, candidates, reference=None):
    """Solve and sample once per candidate knob setting; score each drawing when there are several.

    ``reference`` (a gray array, any square size) is what the drawings are
    scored against; plain SSIM, with every pixel weighted alike as in the
    paper's section 4.1 (an importance mask weighs the solve, not the choice).

    Returns
    -------
    list of dict
        Per candidate: ``style``, ``knobs``, ``seq`` (connected) or ``chords``
        (disconnected, else None), ``stats``, ``scores`` and ``rank``
        (the sum of the four SSIM figures against the picture, both windows plain
        and blurred; 0 for a single candidate).
    """
    from ..model.scoring import SSIM_KEYS, score_chords
    from .sampling import fitness_table, sample_connected, sample_disconnected

    inv = 255.0 - pic.gray
    if float(inv[mask].max(initial=0.0)) < 1.0:
        raise BadInput("fitness found nothing to draw: the picture is blank inside the frame; "
                       "expected a picture with some dark parts")
    gy, gx = gradients(inv)
    b = ((1.0 - alpha) * inv + alpha * np.hypot(gx, gy)).ravel()
    w = (mask.astype(np.float32) if weights is None else np.where(mask, weights, 0).astype(np.float32)).ravel()
    d = (edge_consistency(space, rowptr, chords_of_pixel, gy, gx) if any(c["gamma"] > 0 for _, c in candidates)
         else np.zeros(space.m))
    runs = []
    for name, knobs in candidates:
        t = time.perf_counter()
        report(f"solving ({name})")
        v = chord_weights(space, d, beta=knobs["beta"], gamma=knobs["gamma"])
        f, info = solve_fitness(rowptr, chords_of_pixel, b, w, v, iterations=iterations)
        t_solve = round(time.perf_counter() - t, 3)
        table = fitness_table(space, f, T=knobs["T"])
        report(f"sampling ({name})")
        if disconnected:
            chords, seq = sample_disconnected(space, table, k, epsilon=epsilon), []
        else:
            chords, seq = None, sample_connected(space, table, k, epsilon=epsilon, start_pin=start_pin)
        run = {"style": name, "knobs": knobs, "seq": seq, "chords": chords, "scores": None, "rank": 0.0,
               "stats": {"solve_iterations": info["iterations"], "solve_residual": round(info["residual"], 3),
                         "solve_seconds": t_solve,
                         "fitness_min": round(float(f.min()), 4), "fitness_max": round(float(f.max()), 4)}}
        if len(candidates) > 1:
            report(f"scoring ({name})")
            drawn = chords if disconnected else list(zip(seq[:-1], seq[1:]))
            sc = score_chords(drawn, space.pin_xy, pic.gray if reference is None else reference, frame=space.frame)
            run["scores"] = {k: round(sc[k], 4) for k in SSIM_KEYS}
            run["rank"] = sum(sc[k] for k in SSIM_KEYS)
            log.info("style %s: SSIM %.4f, blurred %.4f", name, sc["ssim"], sc["ssim_blurred"])
        runs.append(run)
    return runs


def gradients(image):
    """Central-difference gradient of an image.

    Returns
    -------
    gy, gx : ndarray of float32, shape image.shape
        Derivatives along rows (down) and columns (right), in levels per pixel.
    """
    gy, gx = np.gradient(np.asarray(image, dtype=np.float32))
    return gy.astype(np.float32), gx.astype(np.float32)


def edge_consistency(space, rowptr, chords, gy, gx):
    """``d_c``: mean ``|t_p x e_c| = |g_p . e_c|`` over the pixels of each chord.

    ``t_p`` is the edge tangent (the gradient turned by 90 degrees); chords
    crossing edges get large ``d``, chords along edges small (see the module notes).

    Parameters
    ----------
    space : ChordSpace
    rowptr, chords : ndarray
        Pixel-major incidence (:func:`stringbot.planner.model.chords.pixel_chords`).
    gy, gx : ndarray of float, shape (size, size)

    Returns
    -------
    ndarray of float64, shape (m,)
    """
    xy = space.pin_xy[space.ends]  # (m, 2, 2): chord, end, (x, y)
    e = xy[:, 1] - xy[:, 0]
    e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12)
    ex, ey = e[:, 0].astype(np.float32), e[:, 1].astype(np.float32)
    gxf, gyf = np.asarray(gx, np.float32).ravel(), np.asarray(gy, np.float32).ravel()
    per_pixel = np.diff(rowptr)
    sums = np.zeros(space.m)
    counts = np.zeros(space.m)
    n = len(per_pixel)
    step = max(1, int(n * 4_000_000 // max(1, rowptr[-1])))  # ~4M entries per chunk
    for a in range(0, n, step):
        b = min(a + step, n)
        cid = chords[rowptr[a]:rowptr[b]]
        k = per_pixel[a:b]
        val = np.repeat(gxf[a:b], k) * ex[cid]
        val += np.repeat(gyf[a:b], k) * ey[cid]
        np.abs(val, out=val)
        sums += np.bincount(cid, weights=val, minlength=space.m)
        counts += np.bincount(cid, minlength=space.m)
    return sums / np.maximum(counts, 1)


def chord_weights(space, d, *, beta, gamma):
    """``v_c = beta exp(-s_c / P) + gamma d_c / max(d)``.

    Returns
    -------
    ndarray of float64, shape (m,)
    """
    dmax = float(d.max()) if len(d) else 0.0
    edge = d / dmax if dmax > 0 else np.zeros_like(d)
    return beta * np.exp(-space.span / space.pins) + gamma * edge


def solve_fitness(rowptr, chords, b, w, v, *, iterations=25, tol=1e-4):
    """Least-squares fitness ``argmin ||W (A f - b)||^2 + ||V f||^2`` by LSQR.

    Parameters
    ----------
    rowptr, chords : ndarray
        Pixel-major incidence: ``A`` has a 1 at ``(p, c)`` for ``c`` in
        ``chords[rowptr[p]:rowptr[p + 1]]``.
    b : ndarray of float, shape (n_pixels,)
    w : ndarray of float, shape (n_pixels,)
        Pixel weights (0 outside the frame).
    v : ndarray of float, shape (m,)
        Chord weights.
    iterations : int
        Iteration limit.
    tol : float
        LSQR's ``atol`` and ``btol`` (at least 1e-5: the products are float32).

    Returns
    -------
    f : ndarray of float64, shape (m,)
    info : dict
        ``iterations`` used, the final ``residual`` norm ``||[W (A f - b); V f]||``
        and LSQR's ``stop`` code.
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import LinearOperator, lsqr

    n_pixels = len(rowptr) - 1
    m = len(v)
    data = np.ones(len(chords), dtype=np.float32)
    A = sp.csr_matrix((data, chords, rowptr), shape=(n_pixels, m), copy=False)
    AT = A.T  # csc view: the transposed product without a copy
    w32 = np.asarray(w, dtype=np.float32)
    v = np.asarray(v, dtype=np.float64)
    colnorm2 = np.asarray(AT @ (w32 * w32), dtype=np.float64) + v * v
    dscale = 1.0 / np.sqrt(np.maximum(colnorm2, 1e-12))  # unit columns: a Jacobi preconditioner
    dv = dscale * v

    def matvec(x):  # [W A D; V D] x
        x = np.ravel(x)
        top = (w32 * (A @ (dscale * x).astype(np.float32))).astype(np.float64)
        return np.concatenate([top, dv * x])

    def rmatvec(r):
        r = np.ravel(r)
        top = (AT @ (w32 * r[:n_pixels].astype(np.float32))).astype(np.float64)
        return dscale * top + dv * r[n_pixels:]

    M = LinearOperator((n_pixels + m, m), matvec=matvec, rmatvec=rmatvec, dtype=np.float64)
    rhs = np.concatenate([np.asarray(w, dtype=np.float64) * np.asarray(b, dtype=np.float64), np.zeros(m)])
    t = max(float(tol), 1e-5)  # float32 products: no point (and no stability) beyond this
    y, istop, itn, r1norm = lsqr(M, rhs, atol=t, btol=t, iter_lim=int(iterations))[:4]
    log.debug("lsqr: %d iterations, residual %.4g, stop %d", itn, r1norm, istop)
    return dscale * y, {"iterations": int(itn), "residual": float(r1norm), "stop": int(istop)}
