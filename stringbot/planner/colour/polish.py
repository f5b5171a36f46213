"""The colour plan's frame's polish (``--face``): pins rerouted by the frame's error, guarded by the face's.

With ``--face`` the colour plan is laid against the face-weighted error; the
face gains and the rest of the frame loses a little (docs/planner.md,
"Faces", "In colour").  Afterwards the plan's inner pins are revisited, the
worst first: pin ``p`` between ``a`` and ``b`` of a run goes through ``q``
instead when the frame's error (the weights without the face's) drops and
the face's own error (the face's extra weight alone) does not rise, both
exact on the piece as the planner keeps it (:class:`~.model.Piece`).

The piece keeps only the colour on top of each sample; taking a thread off
needs what lies under it.  So :class:`Layers` counts, per run and sample, the
run's threads there: a sample shows the colour of the last run that covers
it (within a run the threads are one colour, their order does not show).
"""

import logging
import time

import numpy as np

from ..model.union import unique

log = logging.getLogger(__name__)

__all__ = ["Layers", "frame_polish", "POLISH"]

#: ``pins``: inner pins revisited (the worst first, at most this many); ``tries``: of each, the ``q`` best by
#: the estimate judged exactly; ``memory``: most bytes of the per-run sample counts (no polish beyond)
POLISH = {"pins": 1500, "tries": 3, "memory": 160 * 2 ** 20, "judge": "blurred", "sigma": 1.0}


class Layers:
    """Per run and sample of a :class:`~.model.Piece`'s fine canvas, the run's threads there.

    Parameters
    ----------
    piece : Piece
        The piece the runs were laid on (its ``top`` is what the counts say; it is changed in place).
    runs : list of (int, list of int)
        ``(colour, pins)`` of each run, in winding order.
    """

    def __init__(self, piece, runs):
        self.piece = piece
        n = piece.stamp.F * piece.stamp.F
        self.colour = np.array([k + 1 for k, _ in runs], dtype=np.uint8)
        self.count = np.zeros((n, len(runs)), dtype=np.uint8)     # a sample's counts side by side
        self._stamps = {}
        for r, (_, seq) in enumerate(runs):
            here = np.zeros(n, dtype=np.uint16)
            for a, b in zip(seq[:-1], seq[1:]):
                here[self.samples(a, b)] += 1
            if here.max() > 200:
                raise OverflowError("a run covers a sample more than 200 times")
            self.count[:, r] = here
            self._stamps.clear()

    def samples(self, a, b):
        """The samples of the chord from pin ``a`` to ``b`` (the last few kept: :meth:`forget`)."""
        s = self._stamps.get((a, b))
        if s is None:
            s = self._stamps[(a, b)] = self.piece.stamp(self.piece.pin_xy[a], self.piece.pin_xy[b])
        return s

    def forget(self):
        """Forget the chords' samples kept."""
        self._stamps.clear()

    def top(self, s):
        """The colour (0: the board, ``k + 1``: colour ``k``) the counts show at samples ``s``."""
        c = self.count[s] > 0
        last = c.shape[1] - 1 - np.argmax(c[:, ::-1], axis=1)
        return np.where(c.any(axis=1), self.colour[last], 0).astype(np.uint8)

    def change(self, r, out=(), inn=(), *, refresh=True):
        """Run ``r``'s chords ``out`` taken off and ``inn`` laid (pin pairs); the piece follows (its ``S`` only
        with ``refresh``, :meth:`~.model.Piece.retop`)."""
        parts = []
        for (a, b), d in [(ch, -1) for ch in out] + [(ch, 1) for ch in inn]:
            s = self.samples(a, b)
            if d > 0:
                self.count[s, r] += 1
            else:
                self.count[s, r] -= 1
            parts.append(s)
        if not parts:
            return
        s = np.unique(np.concatenate(parts))
        new = self.top(s)
        moved = new != self.piece.top[s]
        self.piece.retop(s[moved], new[moved], refresh=refresh)


class _Judge:
    """The frame's and the face's error at some pixels and fine cells of a piece."""

    def __init__(self, layers, frame, face, fine_frame=None, fine_face=None):
        self.layers, self.piece, self.frame, self.face = layers, layers.piece, frame, face
        self.fine_frame, self.fine_face = fine_frame, fine_face

    def cells(self, chords):
        """The pixels and the fine cells the chords (pin pairs) cross."""
        piece = self.piece
        s = np.concatenate([self.layers.samples(a, b) for a, b in chords])
        p = unique(piece.stamp.cells(s), piece._mark)[0]
        q = None
        if piece.fine is not None:
            F, h = piece.stamp.F, piece.h
            q = unique((s // (F * h)) * piece.m2 + (s % F) // h, piece._mark2)[0]
        return p, q

    def errors(self, where):
        """``(frame, face)``: the errors at ``where`` (from :meth:`cells`)."""
        p, q = where
        e = self.piece.pixel_errors(p)
        out = [float(self.frame[p] @ e), float(self.face[p] @ e)]
        if q is not None:
            e2 = self.piece.cell_errors(q)
            out[0] += float(self.fine_frame[q] @ e2)
            out[1] += float(self.fine_face[q] @ e2)
        return np.array(out)


class _Blurred:
    """The frame's and the face's error of the piece's gray blurred against the picture's, blurred alike: what
    the score's blurred SSIM sees (the gray at the working grid, a Gaussian of :data:`BLUR` pixels)."""

    def __init__(self, piece, gray, frame, face, *, sigma):
        from scipy.ndimage import gaussian_filter

        from .model import _gray

        self.piece, self.m, self.frame, self.face, self._to_gray = piece, piece.m, frame, face, _gray
        m = self.m
        self.g = _gray(piece.u)
        blur = lambda v: gaussian_filter(np.asarray(v, np.float64).reshape(m, m), sigma, mode="nearest").ravel()
        self.B = blur(self.g) - blur(gray)
        r = int(np.ceil(3 * sigma))
        d = np.arange(-r, r + 1)
        k = np.exp(-0.5 * (d / sigma) ** 2)
        k2 = np.outer(k, k)
        self.dr, self.dc = (a.ravel() for a in np.meshgrid(d, d, indexing="ij"))
        self.k = (k2 / k2.sum()).ravel()
        self._mark = np.zeros(self.piece.n, dtype=np.int64)

    def delta(self, p):
        """``((frame, face), token)``: the change of the errors since the last commit at pixels ``p`` (they hold
        all that changed), and what :meth:`commit` takes."""
        new = self._to_gray(self.piece.u[p])
        d = new - self.g[p]
        m = self.m
        r, c = np.divmod(p, m)
        rr, cc = r[:, None] + self.dr, c[:, None] + self.dc
        ok = (rr >= 0) & (rr < m) & (cc >= 0) & (cc < m)
        idx, inv = unique((rr * m + cc)[ok], self._mark)
        db = np.bincount(inv, weights=(d[:, None] * self.k)[ok], minlength=len(idx))
        b = self.B[idx]
        de = db * (2.0 * b + db)
        return np.array([float(self.frame[idx] @ de), float(self.face[idx] @ de)]), (p, new, idx, db)

    def commit(self, token):
        """Keep the change :meth:`delta` measured."""
        p, new, idx, db = token
        self.g[p] = new
        self.B[idx] += db


def _worst_blurred(runner, runs, B):
    """``(run, index)`` of the inner pins of ``runs``, those whose two chords run most where the blurred piece is
    darker than the picture (``B``, the blurred difference) first."""
    space = runner.space
    indptr, indices, _ = runner.everywhere.full
    keys = []
    for r, (k, seq) in enumerate(runs):
        if len(seq) < 3:
            continue
        ch = space.index[np.asarray(seq[:-1]), np.asarray(seq[1:])]
        sums = np.array([B[indices[a:b]].mean() for a, b in zip(indptr[ch], indptr[ch + 1])])
        bad = sums[:-1] + sums[1:]
        keys += [(float(v), r, i + 1) for i, v in enumerate(bad)]
    keys.sort()
    return [(r, i) for _, r, i in keys]


def _worst(runner, runs):
    """``(run, index)`` of the inner pins of ``runs``, those whose two chords' pixels least want more of their
    colour (by the piece's ``S``, per unit of share) first."""
    piece, space = runner.piece, runner.space
    indptr, indices, weights = runner.everywhere.full
    keys = []
    for r, (k, seq) in enumerate(runs):
        if len(seq) < 3:
            continue
        ch = space.index[np.asarray(seq[:-1]), np.asarray(seq[1:])]
        lo, hi = indptr[ch], indptr[ch + 1]
        sums = np.array([piece.S[k, indices[a:b]].sum() for a, b in zip(lo, hi)]) * weights[ch]
        bad = sums[:-1] + sums[1:]
        keys += [(-float(v), r, i + 1) for i, v in enumerate(bad)]
    keys.sort()
    return [(r, i) for _, r, i in keys]


def frame_polish(runner, runs, *, frame, face, fine=0.0, fine_frame=None, fine_face=None, pins=None, tries=None,
                 gray=None, judge=None):
    """Reroute the worst inner pins of ``runs`` by the frame's error where the face's does not rise.

    Parameters
    ----------
    runner : Runner
        The plan's, its piece holding ``runs``; its piece's weights become ``frame`` (its ``S`` the frame's).
    runs : list of (int, list of int)
        Changed in place.
    frame, face : ndarray of float, shape (m * m,)
        The pixel weights without the face's, and the face's extra weight alone.
    fine : float
        The fine luminance's weight (its cells weighed ``fine`` times the pixels' weights there).
    fine_frame, fine_face : ndarray of float, shape (2m * 2m,), optional
        The weights on the fine grid (with a fine piece).
    pins : int, optional
        Most inner pins revisited (default ``POLISH["pins"]``).
    tries : int, optional
        Of each, this many other pins (the best by the estimate) judged exactly (default ``POLISH["tries"]``).

    Returns
    -------
    dict
        ``tried``, ``rerouted``, and the frame's and the face's error before and after.
    """
    pins = POLISH["pins"] if pins is None else int(pins)
    tries = POLISH["tries"] if tries is None else int(tries)
    t0 = time.process_time()
    piece, space = runner.piece, runner.space
    if len(runs) * piece.stamp.F ** 2 > POLISH["memory"]:
        log.info("colour polish: skipped (%d runs)", len(runs))
        return {"tried": 0, "rerouted": 0}
    piece.reweigh(frame, None if fine_frame is None else fine_frame * fine)
    layers = Layers(piece, runs)
    judge = POLISH["judge"] if judge is None else judge
    if judge == "blurred":
        return _blurred_polish(runner, layers, runs, _Blurred(piece, gray, frame, face, sigma=POLISH["sigma"]),
                               pins=pins, tries=tries, t0=t0)
    judge = _Judge(layers, frame, face, None if fine_frame is None else fine_frame * fine,
                   None if fine_face is None else fine_face * fine)
    everything = (np.arange(piece.n), None if piece.fine is None else np.arange(piece.m2 * piece.m2))
    before = judge.errors(everything)
    order = _worst(runner, runs)[:pins]
    t_set = time.process_time()
    S = piece.S if piece.fine is None else piece.S2
    rerouted = 0
    for r, i in order:
        k, seq = runs[r]
        a, p, b = seq[i - 1], seq[i], seq[i + 1]
        layers.forget()
        out = [(a, p), (p, b)]
        where = judge.cells(out)
        e0 = judge.errors(where)
        layers.change(r, out=out, refresh=False)      # S as it was: the estimate below is by the piece with them
        d_out = judge.errors(where) - e0
        runner.laid[k, space.index[a, p]] = runner.laid[k, space.index[p, b]] = False
        est = np.zeros(space.pins)
        for end in (a, b):
            others, chords, pix, starts, w = runner.fans.get(end)
            g = w * np.add.reduceat(S[k].take(pix), starts)
            g[runner.laid[k, chords]] = np.inf
            part = np.full(space.pins, np.inf)
            part[others] = g
            est += part
        est[[a, b, p]] = np.inf
        best, best_d, best_at = p, None, None
        for q in np.argpartition(est, tries)[:tries]:
            q = int(q)
            if not est[q] + d_out[0] < 0:      # no gain by the estimate
                continue
            inn = [(a, q), (q, b)]
            w2 = judge.cells(inn)
            f0 = judge.errors(w2)
            layers.change(r, inn=inn, refresh=False)
            d = d_out + judge.errors(w2) - f0
            layers.change(r, out=inn, refresh=False)
            if d[0] < 0 and d[1] <= 0 and (best_d is None or d[0] < best_d[0]):
                best, best_d, best_at = q, d, w2
        layers.change(r, inn=[(a, best), (best, b)], refresh=False)
        runner.laid[k, space.index[a, best]] = runner.laid[k, space.index[best, b]] = True
        if best != p:
            piece.refresh_at(*where)
            piece.refresh_at(*best_at)
            seq[i] = best
            rerouted += 1
    t_done = time.process_time()
    after = judge.errors(everything)
    log.info("colour polish: %d of %d pins rerouted; frame error %.1f -> %.1f, face %.1f -> %.1f; %.2f s CPU "
             "(%.2f s set up)", rerouted, len(order), before[0], after[0], before[1], after[1],
             time.process_time() - t0, t_set - t0)
    return {"tried": len(order), "rerouted": rerouted, "frame_error": [round(float(before[0]), 1),
                                                                        round(float(after[0]), 1)],
            "face_error": [round(float(before[1]), 1), round(float(after[1]), 1)]}


def _estimate(runner, S, k, a, b, p):
    """Colour ``k``'s estimated gain (by ``S``) of going from ``a`` to ``b`` through each pin (inf: not allowed)."""
    space = runner.space
    est = np.zeros(space.pins)
    for end in (a, b):
        others, chords, pix, starts, w = runner.fans.get(end)
        g = w * np.add.reduceat(S[k].take(pix), starts)
        g[runner.laid[k, chords]] = np.inf
        part = np.full(space.pins, np.inf)
        part[others] = g
        est += part
    est[[a, b, p]] = np.inf
    return est


def _blurred_polish(runner, layers, runs, judge, *, pins, tries, t0):
    """:func:`frame_polish` judged by the blurred gray (:class:`_Blurred`)."""
    piece, space = runner.piece, runner.space
    S = piece.S if piece.fine is None else piece.S2
    cells = lambda chords: unique(piece.stamp.cells(np.concatenate([layers.samples(a, b) for a, b in chords])),
                                  piece._mark)[0]
    order = _worst_blurred(runner, runs, judge.B)[:pins]
    e0 = judge.delta(np.arange(piece.n))[0]          # zero: the errors are kept as changes
    before = [float(judge.frame @ judge.B ** 2), float(judge.face @ judge.B ** 2)]
    t_set = time.process_time()
    rerouted = 0
    for r, i in order:
        k, seq = runs[r]
        a, p, b = seq[i - 1], seq[i], seq[i + 1]
        layers.forget()
        out = [(a, p), (p, b)]
        p_out = cells(out)
        layers.change(r, out=out, refresh=False)
        d_out, token = judge.delta(p_out)
        judge.commit(token)
        runner.laid[k, space.index[a, p]] = runner.laid[k, space.index[p, b]] = False
        est = _estimate(runner, S, k, a, b, p)
        best, best_d, best_at = p, None, None
        for q in np.argpartition(est, tries)[:tries]:
            q = int(q)
            if not np.isfinite(est[q]):
                continue
            inn = [(a, q), (q, b)]
            p_in = cells(inn)
            layers.change(r, inn=inn, refresh=False)
            d = d_out + judge.delta(p_in)[0]
            layers.change(r, out=inn, refresh=False)
            if d[0] < 0 and d[1] <= 0 and (best_d is None or d[0] < best_d[0]):
                best, best_d, best_at = q, d, p_in
        layers.change(r, inn=[(a, best), (best, b)], refresh=False)
        runner.laid[k, space.index[a, best]] = runner.laid[k, space.index[best, b]] = True
        judge.commit(judge.delta(p_out if best == p else best_at)[1])
        if best != p:
            piece.refresh_at(*_fine_cells(piece, p_out))
            piece.refresh_at(*_fine_cells(piece, best_at))
            seq[i] = best
            rerouted += 1
    after = [float(judge.frame @ judge.B ** 2), float(judge.face @ judge.B ** 2)]
    log.info("colour polish (blurred): %d of %d pins rerouted; frame error %.3f -> %.3f, face %.3f -> %.3f; "
             "%.2f s CPU (%.2f s set up)", rerouted, len(order), before[0], after[0], before[1], after[1],
             time.process_time() - t0, t_set - t0)
    del e0
    return {"tried": len(order), "rerouted": rerouted, "judge": "blurred",
            "frame_error": [round(before[0], 3), round(after[0], 3)],
            "face_error": [round(before[1], 3), round(after[1], 3)]}


def _fine_cells(piece, p):
    """``(p, q)``: pixels ``p`` and their fine cells (None without :class:`~.model.Fine`)."""
    return p, (None if piece.fine is None else piece._kids[p].ravel())
