"""``--method euler``: a chord set chosen with no thread to follow, made one thread, then polished.

The default method (:mod:`.residual`) grows its thread pin by pin, and each
chord must start where the last one ended.  This one chooses the chords
first, as if each could be drawn on its own, and only then makes them one
thread:

1. *The chord set* (:func:`relaxed_densities`).  Every chord gets a density
   ``x`` in [0, 1], a pixel of a :data:`GRID`-px grid darkens by the union's
   expectation ``D = 1 - exp(-A x)`` (``A``: each chord's coverage of each
   pixel, its length in the pixel times the thread's width), and ``x``
   minimises the error as the eye sees it (the picture's darkness minus
   ``D``, both blurred as ``stringbot score`` blurs them, squared, over the
   frame) by L-BFGS-B: :data:`ITERATIONS` iterations over all chords, then
   the :data:`ROUNDS` over the active chords only (those above
   :data:`ACTIVE`, and those under it whose slope over all chords says they
   would grow: one product over all chords a round), then the stages of
   :data:`SCHEDULE` over the chords above :data:`PRUNE`, each adding
   ``lam * sum x (1 - x)``, which drives every density to 0 or 1.  The
   sparse products are float32 (the coverage is one CSR pattern, chords x
   pixels, and a width per chord), over 2000 chords and more in two halves
   (a second thread takes one where there are two cores: the same sums).
   The chords are then taken in order of density, as many as give the
   lowest error once made one thread (:data:`SCAN`, :func:`choose_chords`).
2. *One thread* (:func:`make_trail`, :func:`euler_sequence`).  A thread is
   an Euler trail of its chords: they hang together and every pin but the
   two ends holds an even number of them.  The odd pins are paired
   greedily by the chord between them that harms least by the relaxed
   error's slope (drawing it once more, or leaving out a chord of the set
   where that harms less), the parts are joined by their least harmful
   chord, and the trail is walked (Hierholzer).  A chord joins two pins, so
   no pin comes twice in a row.
3. *The polish* (:mod:`.polish`, on two cores where there are two, as the
   default method's) of that sequence against the picture as woven, then
   :data:`DELETES` pass of deletes (with ``--lines auto``).

Measured against the default in docs/planner.md ("The euler method").
"""

import logging
import time

import numpy as np

from . import Outcome

log = logging.getLogger(__name__)

__all__ = ["run", "coverage", "relaxed_densities", "choose_chords", "pair_odd", "make_trail", "euler_sequence",
           "GRID", "ITERATIONS", "ROUNDS", "ACTIVE", "SPLIT", "SCHEDULE", "PRUNE", "DELETES", "SCAN"]

#: side of the grid the densities are solved on (the polish's grid)
GRID = 256
#: L-BFGS-B iterations over all chords, from 0.02 each
ITERATIONS = 10
#: then rounds of as many iterations over the active chords (above :data:`ACTIVE`, or growing)
ROUNDS = (40, 40, 40)
#: chords at or under this density are active in a round only if their slope is negative
ACTIVE = 1e-3
#: chords from which the products over them run in two halves (on two threads where there are two cores)
SPLIT = 2000
#: then ``(lam, iterations)`` stages with ``lam * sum x (1 - x)`` added (units of the summed squared error)
SCHEDULE = ((0.02, 20), (0.1, 20), (0.4, 20))
#: chords under this density after the first iterations are left out of the stages
PRUNE = 0.01
#: passes of deletes (``a-p-c -> a-c``, kept where the piece as woven gets better) after the polish: the
#: pairing's extra chords are what they take out
DELETES = 1
#: the densities are solved again from :func:`_log_start` when their darkness exceeds the target's by this
SATURATED = 0.1
#: chord counts tried: from ``SCAN[0]`` to ``SCAN[1]`` times the chords over 0.5, ``SCAN[2]`` of them
SCAN = (0.8, 2.0, 13)


def coverage(space, size, width_px):
    """``(AT, w)``: which pixels of a ``size``-px grid each chord covers, chords x pixels, CSR of float32
    ones, and each chord's coverage of them (its length in a pixel times the thread's width, at most
    1), float32: the coverage matrix ``A`` (pixels x chords) is ``AT^T diag(w)``."""
    import scipy.sparse as sp

    from ..model.chords import chord_pixels, pin_pixels

    indptr, indices = chord_pixels(space, size)
    rc = pin_pixels(space.pin_xy, size).astype(np.float64)
    d = rc[space.ends[:, 1]] - rc[space.ends[:, 0]]
    per = np.hypot(d[:, 0], d[:, 1]) / np.maximum(np.abs(d).max(axis=1), 1.0)  # length per pixel step
    AT = sp.csr_matrix((np.ones(len(indices), dtype=np.float32), indices, indptr), shape=(space.m, size * size),
                       copy=False)
    return AT, np.minimum(per * width_px, 1.0).astype(np.float32)


class _Products:
    """``A x`` and ``A^T y`` in float32 (``A = AT^T diag(w)``, :func:`coverage`), with ``AT``'s rows in two
    halves that ``threads`` (a ``ThreadPoolExecutor``, or None) takes one of: the same sums either way
    (scipy's sparse products let go of the interpreter's lock while they run)."""

    def __init__(self, AT, w, threads=None):
        self.AT, self.w = AT, np.asarray(w, dtype=np.float32)
        m = AT.shape[0]
        self.threads = threads if m >= SPLIT else None
        self.halves = [_rows(AT, 0, m // 2), _rows(AT, m // 2, m)] if m >= SPLIT else [AT]

    def _both(self, fn):
        if self.threads is None or len(self.halves) == 1:
            return [fn(h) for h in self.halves]
        first = self.threads.submit(fn, self.halves[0])
        second = fn(self.halves[1])
        return [first.result(), second]

    def darkness(self, x):
        """``A x`` (float32, one per pixel); of the chords' own rows where few are nonzero."""
        x = np.asarray(x)
        nz = np.flatnonzero(x)
        if len(nz) * 4 < len(x):
            return self.AT[nz].T @ (self.w[nz] * x[nz].astype(np.float32))
        v = self.w * x.astype(np.float32)
        cut = self.halves[0].shape[0]
        parts = self._both(lambda h: h.T @ (v[:cut] if h is self.halves[0] else v[cut:]))
        return parts[0] if len(parts) == 1 else parts[0] + parts[1]

    def back(self, y):
        """``A^T y`` (float32, one per chord)."""
        y = np.asarray(y, dtype=np.float32)
        parts = self._both(lambda h: h @ y)
        return self.w * (parts[0] if len(parts) == 1 else np.concatenate(parts))


def _rows(AT, a, b):
    """Rows ``a:b`` of the CSR ``AT`` sharing its data (no copy but of the row pointers)."""
    import scipy.sparse as sp

    p = AT.indptr
    return sp.csr_matrix((AT.data[p[a]:p[b]], AT.indices[p[a]:p[b]], p[a:b + 1] - p[a]), shape=(b - a, AT.shape[1]),
                         copy=False)


def objective(AT, w, target, weights, sigma, *, threads=None):
    """``f(x) -> (E, grad)``: ``E = || B (s (t - D)) ||^2 = <u, B^2 u>`` (``u = s (t - D)``) with
    ``D = 1 - exp(-A x)`` (``A = AT^T diag(w)``, :func:`coverage`, over the chords of ``AT``'s rows),
    ``B`` the Gaussian blur of ``sigma`` px, ``s`` the square root of the weights, and its gradient;
    ``f.value(x)`` is ``E`` alone.  The sparse products are in float32 (:class:`_Products`, on
    ``threads``), the rest in float64."""
    from scipy.ndimage import gaussian_filter

    m = target.shape[0]
    s = np.sqrt(weights).ravel()
    t = target.ravel()
    prod = _Products(AT, w, threads)

    def blur2(v):  # B^2 = the blur of sigma * sqrt(2) (to 1e-5 of the peak): one pass for E and its slope
        return gaussian_filter(v.astype(np.float32).reshape(m, m), sigma * np.sqrt(2.0), mode="constant").ravel()

    def value(x):
        ex = np.exp(-prod.darkness(x).astype(np.float64))
        u = s * (t - (1.0 - ex))
        bu = blur2(u)
        return float(u @ bu), bu, ex

    def f(x):
        E, bu, ex = value(x)
        return E, prod.back(ex * (-2.0 * s * bu)).astype(np.float64)
    f.value = lambda x: value(x)[0]
    return f


def _solve(f, x0, iterations, lam=0.0):
    """``x`` after L-BFGS-B on ``f`` plus ``lam * sum x (1 - x)``, from ``x0``."""
    from scipy.optimize import Bounds, minimize

    def fp(y):
        E, g = f(y)
        return E + lam * float(np.sum(y * (1.0 - y))), g + lam * (1.0 - 2.0 * y)
    res = minimize(fp if lam else f, x0, jac=True, method="L-BFGS-B", bounds=Bounds(0.0, 1.0),
                   options={"maxiter": int(iterations)})
    return res.x


def _saturated(AT, w, x, target, weights, *, by=SATURATED):
    """Whether the union's expectation ``1 - exp(-A x)`` is darker than the target by more than ``by`` on
    the weighted mean: where the densities ran to their bound, the objective is flat (``exp(-A x)`` near
    0) and L-BFGS-B stays there."""
    d = 1.0 - np.exp(-_Products(AT, w).darkness(x).astype(np.float64))
    wt = weights.ravel()
    return float(wt @ (d - target.ravel())) > by * float(wt.sum())


def _log_start(AT, w, target, weights, *, iterations=ITERATIONS, threads=None):
    """Densities whose ``A x`` fits the union's log ``-ln(1 - t)`` (``t`` capped at 0.95) by weighted least
    squares, in [0, 1]: a convex problem with no flat region, a start the relaxed objective cannot leave for
    saturation at once."""
    prod = _Products(AT, w, threads)
    wt = weights.ravel().astype(np.float64)
    L = -np.log1p(-np.minimum(target.ravel(), 0.95))

    def g(x):
        r = prod.darkness(x).astype(np.float64) - L
        return float(wt @ (r * r)), 2.0 * prod.back(wt * r).astype(np.float64)
    return _solve(g, np.zeros(AT.shape[0]), iterations)


def relaxed_densities(space, target, weights, width_px, *, sigma, iterations=ITERATIONS, rounds=ROUNDS,
                      schedule=SCHEDULE, prune=PRUNE, threads=None):
    """The chords' densities (see the module notes): ``(x, f)``, ``f`` the objective over all chords.

    Parameters
    ----------
    space : ChordSpace
    target, weights : ndarray of float, shape (m, m)
        Darkness wanted (0..1) and pixel weights (0 outside the frame) on the grid.
    width_px : float
        Thread width in grid pixels.
    sigma : float
        The eye's blur in grid pixels.
    iterations : int
        Over all chords, from 0.02 each.
    rounds : sequence of int
        Then rounds of as many iterations over the active chords: those above :data:`ACTIVE` and
        those below whose slope says they would grow (all chords' slope, after each round).
    schedule : sequence of (float, int)
        Then ``(lam, iterations)`` stages over the chords above ``prune``.
    prune : float
    threads : concurrent.futures.ThreadPoolExecutor, optional
        One thread to take half of every product over all chords (the plan is the same without).
    """
    AT, w = coverage(space, target.shape[0], width_px)
    f = objective(AT, w, target, weights, sigma, threads=threads)

    def over(cols, x0, its, lam=0.0):
        fc = objective(AT[cols], w[cols], target, weights, sigma, threads=threads)
        x = np.zeros(space.m)
        x[cols] = _solve(fc, x0[cols], its, lam)
        return x

    x = _solve(f, np.full(space.m, 0.02), iterations)
    if _saturated(AT, w, x, target, weights):  # a dark picture: the first steps ran every chord to 1
        log.info("euler: the densities saturated from a uniform start; solving again from the union's log")
        x = _solve(f, _log_start(AT, w, target, weights, threads=threads), iterations)
    for its in rounds:
        grow = (x <= ACTIVE) & (f(x)[1] < 0.0)
        x = over(np.flatnonzero((x > ACTIVE) | grow), x, its)
    if schedule:
        cols = np.flatnonzero(x > prune)
        fc = objective(AT[cols], w[cols], target, weights, sigma, threads=threads)
        xc = x[cols]
        for lam, its in schedule:
            xc = _solve(fc, xc, its, lam)
        x = np.zeros(space.m)
        x[cols] = xc
    return x, f


def choose_chords(space, x, f, *, scan=SCAN, start=None, lines=None):
    """The chords of highest density, as many as give the lowest ``f`` once made one thread: ``(count,
    chosen)``, the times each chord is drawn (:func:`make_trail`) and how many chords were taken.
    ``lines``: as many as make a thread of at most about that many chords instead (the sequence is
    cut where it is longer)."""
    order = np.argsort(-x, kind="stable")

    def trail(k):
        v = np.zeros(space.m)
        v[order[:k]] = 1.0
        count = make_trail(space, v.astype(np.int64), f(v)[1], start=start)
        return f.value(count.astype(np.float64)), count, k

    if lines is not None:
        k = min(int(lines), space.m)
        for _ in range(4):  # fewer chords by those the thread adds, until it is not longer than asked
            _, count, k = trail(k)
            if count.sum() <= lines or k == 1:
                break
            k = max(1, k - int(count.sum() - lines))
        return count, k
    n0 = max(int(np.sum(x > 0.5)), 1)
    ks = sorted(set(min(max(k, 1), space.m) for k in np.linspace(scan[0] * n0, scan[1] * n0, int(scan[2])).astype(int)))
    return min((trail(k) for k in ks), key=lambda r: r[0])[1:]


def pair_odd(space, count, harm, *, ends=2, remove=True):
    """Pair the odd pins of the chord multiset ``count`` (times each chord is drawn) by the chords
    between them that harm least, greedily, until ``ends`` are left; returns the new counts.

    ``harm``: per chord, what drawing it once more costs (lower is better); with ``remove``, a chord
    drawn once may instead be left out, at the cost ``-harm``."""
    count = count.copy()
    deg = np.bincount(space.ends.ravel(), weights=np.repeat(count, 2), minlength=space.pins).astype(np.int64)
    odd = np.flatnonzero(deg % 2)
    if len(odd) <= ends:
        return count
    iu = np.triu_indices(len(odd), 1)
    pc = space.index[odd[iu[0]], odd[iu[1]]]
    ok = pc >= 0
    pa, pb, pc = iu[0][ok], iu[1][ok], pc[ok]
    out = remove & (count[pc] == 1) & (-harm[pc] < harm[pc])
    cost = np.where(out, -harm[pc], harm[pc])
    free = np.ones(len(odd), dtype=bool)
    left = len(odd)
    for j in np.argsort(cost, kind="stable"):
        if left <= ends:
            break
        a, b = pa[j], pb[j]
        if free[a] and free[b]:
            free[a] = free[b] = False
            left -= 2
            count[pc[j]] += -1 if out[j] else 1
    return count


def _parts(space, count):
    """A label per pin of the part of the drawn chords it is in (-1: no chord), and the labels."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = space.ends[count > 0]
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(space.pins, space.pins))
    lab = connected_components(g, directed=False)[1]
    used = np.zeros(space.pins, dtype=bool)
    used[e.ravel()] = True
    lab = np.where(used, lab, -1)
    return lab, np.unique(lab[used])


def make_trail(space, count, harm, *, start=None):
    """The chord multiset ``count`` made one thread: odd pins paired (:func:`pair_odd`), then the parts
    joined by their least harmful chord (the odd pins that makes paired again, by added chords only).
    Returns the new counts: one part, at most two odd pins (none with ``start``, which is then in it)."""
    count = np.asarray(count, dtype=np.int64)
    ends = 2 if start is None else 0
    count = pair_odd(space, count, harm, ends=ends)
    while True:
        lab, names = _parts(space, count)
        if start is not None and lab[start] < 0:  # the start pin joins as a part of its own
            lab[start] = lab.max() + 1
            names = np.append(names, lab[start])
        if len(names) <= 1:
            return count
        big = max(names, key=lambda r: int(np.sum(lab == r)))
        ii, oo = np.flatnonzero(lab == big), np.flatnonzero((lab >= 0) & (lab != big))
        cand = space.index[np.ix_(ii, oo)]
        cost = np.where(cand >= 0, harm[np.maximum(cand, 0)], np.inf)
        k = np.unravel_index(int(np.argmin(cost)), cost.shape)
        count = count.copy()
        count[int(cand[k])] += 1
        count = pair_odd(space, count, harm, ends=ends, remove=False)


def euler_sequence(space, count, *, start=None):
    """An Euler trail of the chord multiset ``count`` (times each chord is drawn: one part, at most two
    odd pins), as pins: from the lower odd pin, else from ``start`` (or the lowest pin with a chord)."""
    n = space.pins
    chords = np.repeat(np.arange(len(count)), count)
    adj = [[] for _ in range(n)]
    for e, c in enumerate(chords):
        a, b = (int(p) for p in space.ends[c])
        adj[a].append((b, e))
        adj[b].append((a, e))
    deg = np.array([len(v) for v in adj])
    odd = np.flatnonzero(deg % 2)
    if len(odd):
        cur = int(odd[0])
    else:
        cur = int(start) if start is not None and deg[start] else int(np.flatnonzero(deg)[0])
    done = np.zeros(len(chords), dtype=bool)
    ptr = [0] * n
    stack, trail = [cur], []
    while stack:  # Hierholzer
        v = stack[-1]
        while ptr[v] < len(adj[v]) and done[adj[v][ptr[v]][1]]:
            ptr[v] += 1
        if ptr[v] == len(adj[v]):
            trail.append(stack.pop())
        else:
            w, e = adj[v][ptr[v]]
            done[e] = True
            stack.append(w)
    return trail[::-1]


def run(job):
    """``--method euler`` through the methods' contract (:mod:`stringbot.planner.methods`): the chord set,
    its thread, then the polish of :mod:`.residual`'s (two processes where there are two cores)."""
    from concurrent.futures import ThreadPoolExecutor

    from ...errors import BadInput
    from ..model.chords import frame_mask
    from ..model.scoring import WOVEN_SIGMA, WOVEN_SIZE
    from ..picture.resample import resize_square
    from .polish import polish_plan
    from .residual import woven_canvas
    from .woven_helper import TwinDrawing, WovenHelper, two_cores

    k = job.knobs
    space, model = job.space, job.model
    polish, passes = k["polish"], k.get("polish_passes") or 0
    deletes = DELETES if polish and job.lines == "auto" else 0  # with --lines N the line count stays
    target = np.where(job.mask, 1.0 - job.picture.gray / 255.0, 0.0)
    if float(target.max(initial=0.0)) < 1.0 / 255:
        raise BadInput("euler found nothing to draw: the picture is blank inside the frame; "
                       "expected a picture with some dark parts")
    w = job.mask.astype(np.float64) if job.weights is None else np.where(job.mask, job.weights, 0.0)
    helper = None
    if polish and two_cores():  # the helper lays out the polish's chords while the densities are solved
        preview = k.get("preview")
        drawing = None if preview is None or passes or deletes else TwinDrawing(preview, model)
        helper = WovenHelper(lambda: woven_canvas(target, w, space, model), space, drawing=drawing, patience=0)
    threads = ThreadPoolExecutor(1) if two_cores() else None  # after the fork: half of each product over all chords
    try:
        t0 = time.perf_counter()
        m = min(GRID, target.shape[0])
        inside = frame_mask(m, space.frame)
        x, f = relaxed_densities(space, np.where(inside, resize_square(target, m), 0.0),
                                 np.where(inside, resize_square(w, m), 0.0), model.width_px(m),
                                 sigma=WOVEN_SIGMA * m / WOVEN_SIZE, threads=threads)
        t1 = time.perf_counter()
        lines = None if job.lines == "auto" else int(job.lines)
        count, chosen = choose_chords(space, x, f, start=job.start_pin, lines=lines)
        if threads is not None:
            threads.shutdown()
        seq = euler_sequence(space, count, start=job.start_pin)
        if lines is not None:
            seq = seq[:lines + 1]
        taken = np.zeros(space.m, dtype=np.int64)
        taken[np.argsort(-x, kind="stable")[:chosen]] = 1
        stats = {"relaxed_seconds": round(t1 - t0, 3), "trail_seconds": round(time.perf_counter() - t1, 3),
                 "chords_chosen": int(chosen), "chords_added": int(np.sum(np.maximum(count - taken, 0))),
                 "chords_left_out": int(np.sum((count == 0) & (taken > 0))),
                 "densities_sum": round(float(x.sum()), 1)}
        t2 = time.perf_counter()
        done, drawings = None, None
        if helper is not None and polish:
            for a, b in zip(seq[:-1], seq[1:]):
                helper.add((int(a), int(b)))
            done = helper.finish(seq, polish, passes, deletes)
            drawings = None if done is None else helper.drawing
        if done is None:
            woven = woven_canvas(target, w, space, model)
            woven.build(list(zip(seq[:-1], seq[1:])))
            done = polish_plan(woven, seq, space, budget=polish, passes=passes, deletes=deletes)
        seq, stats["polish"] = done
        stats["polish_seconds"] = round(time.perf_counter() - t2, 3)
    finally:
        if threads is not None:
            threads.shutdown()
        if helper is not None:
            helper.close()
    log.info("euler: %d chords chosen, %d added, %d left out; %d lines after the polish", stats["chords_chosen"],
             stats["chords_added"], stats["chords_left_out"], len(seq) - 1)
    params = {"polish": polish, "polish_passes": passes, "polish_deletes": deletes, "grid": m,
              "iterations": ITERATIONS, "rounds": list(ROUNDS), "active": ACTIVE,
              "schedule": [list(s) for s in SCHEDULE], "prune": PRUNE, "thread_px": round(model.width_px(k["size"]), 4)}
    return Outcome([int(p) for p in seq], params, stats, drawings=drawings)
