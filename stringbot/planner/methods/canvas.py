"""The drawing as woven at the working size, and its error against the target, kept up to date chord by chord.

The residual's chooser (:mod:`.residual`) and its refinement (:mod:`.refine`)
draw on a :class:`Canvas`: the threads under the planner's thread model
(:mod:`stringbot.planner.model.union`: how many threads cover each sample of a
fine canvas of ``f x f`` samples per working pixel, the thread about one
sample wide), ``D`` the share of each pixel they cover, the error
``E = sum w (t - D)^2`` and its slope, what one more thread would change
(docs/planner.md, "How the chooser scores a chord").  With ``eye=True`` it
also keeps the error as the eye sees it (:mod:`.eye`) on a coarse grid.
"""

import numpy as np

from ..model.union import COUNT, UnionStamp, fine_per_pixel, unique

__all__ = ["Canvas", "fresh", "sum_sparse", "EYE_GRID"]

#: the chooser's fine canvas: samples per working pixel so that the thread is about one sample wide, at most
#: this many samples a side
CHOOSER_MAX_FINE = 4096
#: footprints the chooser keeps (about 20 kB each at 401 px): the chords drawn, and those tried by the refinement
MAX_CACHED = 8000
#: side of the coarse grid the chooser measures the error as the eye sees it on (``lines="auto"``)
EYE_GRID = 128


def sum_sparse(parts, acc, mark):
    """The sum of sparse vectors: ``(pix, total)``, each index once.

    Parameters
    ----------
    parts : list of (ndarray of int, ndarray of float)
        Indices (each once within a part) and their values.
    acc, mark : ndarray of float64 / int64
        Scratch as long as the dense vector; ``acc`` all zeros, and left so.
    """
    for idx, val in parts:
        acc[idx] += val
    every = np.concatenate([idx for idx, _ in parts])
    order = np.arange(len(every))
    mark[every] = order
    pix = every[mark[every] == order]
    total = acc[pix]
    acc[pix] = 0.0
    return pix, total


class Canvas:
    """The drawing as woven at the working size, and its error against the target.

    Parameters
    ----------
    target : ndarray of float, shape (size, size)
        Darkness wanted, 0..1.
    weights : ndarray of float, shape (size, size)
        Pixel weights (0 outside the frame).
    pin_xy : ndarray of float, shape (pins, 2)
    width_px : float
        Thread width in pixels at this size.
    eye : bool
        Also keep the error as the eye sees it (:attr:`eye`, for ``lines="auto"``).
    eye_target : ndarray of float, shape (size, size), optional
        The darkness the eye's error is measured against (default: ``target``; the residual's chooser lays
        threads against the picture sharpened and judges them, as the eye does, against the picture itself).

    Attributes
    ----------
    D : ndarray of float64, shape (size * size,)
        The share of each pixel the threads cover.
    C : ndarray of uint16, shape (F * F,)
        How many threads cover each sample of the fine canvas (``F = f size``).
    uses : ndarray of int32, shape (pins, pins)
        How many times each chord is drawn (symmetric).
    eye : EyeError or None
    """

    def __init__(self, target, weights, pin_xy, width_px, *, eye=False, eye_target=None):
        self.size = m = target.shape[0]
        self.t = np.asarray(target, dtype=np.float64).ravel()
        self.w = np.asarray(weights, dtype=np.float64).ravel()
        self.D = np.zeros_like(self.t)
        self.pin_xy = np.asarray(pin_xy, dtype=np.float64)
        self.width = float(width_px)
        self.f = fine_per_pixel(width_px, largest=max(1, CHOOSER_MAX_FINE // m))
        self.F = m * self.f
        self._stamp = UnionStamp(m, self.f, width_px)
        self.C = np.zeros(self.F * self.F, dtype=COUNT)
        self._fp = {}
        n = len(self.pin_xy)
        self.uses = np.zeros((n, n), dtype=np.int32)
        self._mark = np.zeros(m * m, dtype=np.int64)  # scratch: first occurrence of a pixel
        self._fmark = None  # the same for the fine canvas's samples
        # a thread's own overlap: half its sum of squared coverage per unit of coverage (measured on a
        # horizontal and a diagonal thread); the second-order cost of its darkness where none is wanted
        kap = []
        for xy0, xy1 in (((0.1, 0.5013), (0.9, 0.5007)), ((0.1013, 0.1), (0.9, 0.9011))):
            c = self._cover(self._stamp(np.array(xy0), np.array(xy1)))[2]
            kap.append(float(np.sum(c * c) / (2.0 * np.sum(c))))
        self.kappa = float(np.mean(kap))
        # how much one more thread's coverage lowers the error, per unit of coverage (see apply)
        self.g = (self.w * (self.t - self.kappa)).astype(np.float32)
        self.eye = None
        if eye:
            self._eye_grid(target if eye_target is None else eye_target, weights)

    # -- footprints -------------------------------------------------------------------------------------

    def _cover(self, flat):
        """``(cu, inv, cover)``: the pixels samples ``flat`` fall in (each once; sample ``i`` in
        ``cu[inv[i]]``) and the share of each they cover."""
        cu, inv = unique(self._stamp.cells(flat), self._mark)
        return cu, inv, np.bincount(inv, minlength=len(cu)) * (1.0 / (self.f * self.f))

    def _footprint(self, a, b):
        """``(flat, cu, inv, cover)`` of chord ``(a, b)``: its samples and :meth:`_cover` of them (cached)."""
        key = (a, b) if a < b else (b, a)
        fp = self._fp.get(key)
        if fp is None:
            if len(self._fp) >= MAX_CACHED:
                self._fp.clear()
            flat = self._stamp(self.pin_xy[key[0]], self.pin_xy[key[1]])
            fp = self._fp[key] = (flat,) + self._cover(flat)
        return fp

    def footprint(self, a, b):
        """``(pix, cover)`` of the chord between pins ``a`` and ``b``: the pixels it covers (each once) and
        the share of each it covers alone (cached)."""
        fp = self._footprint(a, b)
        return fp[1], fp[3]

    # -- the error ---------------------------------------------------------------------------------------

    def error(self):
        """``E = sum w (t - D)^2``."""
        return float(np.sum(self.w * (self.t - self.D) ** 2))

    def _changes(self, chords_out, chords_in):
        """``(flat, new, pix, dD, turned)``: the samples removing then adding chords touches (each once),
        their counts after, the change of ``D`` on the pixels ``pix`` (each once), and (with the eye's
        grid, else None) the samples covered or uncovered and how (``(samples, +1 or -1)``); None for no
        chords.

        A sample changes where its count goes from 0 to more (covered) or back to 0 (uncovered)."""
        parts = [(self._footprint(a, b), sign) for chords, sign in ((chords_out, -1), (chords_in, 1))
                 for a, b in chords]
        if not parts:
            return None
        if len(parts) == 1:  # one chord: its pixels are known
            (flat, cu, inv, _), sign = parts[0]
            old = self.C[flat]
            if sign > 0:
                new, turns = old + 1, old == 0
            else:
                new, turns = old - (old > 0), old == 1
            turned = None if self.eye is None else (flat[turns], float(sign))
            return flat, new, cu, np.bincount(inv[turns], minlength=len(cu)) * (sign / (self.f * self.f)), turned
        every = np.concatenate([fp[0] for fp, _ in parts])
        if self._fmark is None:  # scratch for the samples (allocated the first time several chords change)
            self._fmark = np.zeros(self.F * self.F, dtype=np.int64)
        flat, inv = unique(every, self._fmark)
        d = np.bincount(inv, weights=np.concatenate([np.full(len(fp[0]), s) for fp, s in parts]),
                        minlength=len(flat)).astype(np.int64)
        old = self.C[flat].astype(np.int64)
        new = np.maximum(old + d, 0)
        turns = (new > 0).astype(np.int8) - (old > 0)
        hit = turns != 0
        cu, inv = unique(self._stamp.cells(flat[hit]), self._mark)
        dD = np.bincount(inv, weights=turns[hit], minlength=len(cu)) * (1.0 / (self.f * self.f))
        turned = None if self.eye is None else (flat[hit], turns[hit].astype(np.float64))
        return flat, new.astype(COUNT), cu, dD, turned

    def delta(self, chords_out=(), chords_in=()):
        """Exact change of ``E`` if ``chords_out`` were removed and ``chords_in`` added (nothing changes)."""
        ch = self._changes(chords_out, chords_in)
        if ch is None:
            return 0.0
        _, _, pix, dD, _ = ch
        t, w, d0 = self.t[pix], self.w[pix], self.D[pix]
        return float(np.sum(w * ((t - d0 - dD) ** 2 - (t - d0) ** 2)))

    def apply(self, chords_out=(), chords_in=()):
        """Remove ``chords_out`` and add ``chords_in``; update the slope on the pixels they touch.

        Returns
        -------
        float
            The exact change of ``E`` (as :meth:`delta` would have said).
        """
        ch = self._changes(chords_out, chords_in)
        if ch is None:
            return 0.0
        for chords, sign in ((chords_out, -1), (chords_in, 1)):
            for a, b in chords:
                self.uses[a, b] += sign
                if a != b:
                    self.uses[b, a] += sign
        flat, new, pix, dD, turned = ch
        self.C[flat] = new
        if not len(pix):
            return 0.0
        t, w = self.t[pix], self.w[pix]
        d0 = self.D[pix]
        d = d0 + dD
        self.D[pix] = d
        # E's change for a thread covering c of a pixel, which falls on its uncovered part: it adds
        # c (1 - D); -2 w (t - D) (1 - D) c + w (1 - D)^2 c^2, per unit of coverage of a thread whose own
        # c^2 / c is 2 kappa: 2 w (1 - D) ((t - D) - kappa (1 - D))
        r, left = t - d, 1.0 - d
        self.g[pix] = w * left * (r - self.kappa * left)
        if self.eye is not None:
            self._eye_take(*turned)
        return float(np.sum(w * (r * r - (t - d0) ** 2)))

    def slope(self):
        """The slope field ``w (1 - D) ((t - D) - kappa (1 - D))``, flat float32 (a view: do not modify)."""
        return self.g

    # -- the error as the eye sees it (lines="auto") ---------------------------------------------------------

    def _eye_grid(self, target, weights):
        """The error as the eye sees it on a grid of :data:`EYE_GRID` px at most: each sample of the fine
        canvas in the cell its centre lies in, a cell's darkness the share of its samples covered (its
        target and weight the mean of its samples' pixels'), blurred by the scorer's sigma."""
        from .eye import EYE_SIGMA, EyeError

        m, f, F = self.size, self.f, self.F
        me = min(EYE_GRID, m)
        ec = (((np.arange(F) + 0.5) * me) // F).astype(np.int64)  # the cell row (or column) of a sample's
        self._erow, self._ecol = ec * me, ec
        n1 = np.bincount(ec, minlength=me).astype(np.float64)  # samples per cell, along one side
        self._einv = 1.0 / np.outer(n1, n1).ravel()  # a sample's share of its cell
        # A[j, i]: samples of pixel column i in cell column j; a cell's mean of a picture x is A x A^T / n
        A = np.zeros((me, m))
        np.add.at(A, (ec, np.arange(F) // f), 1.0)
        cnt = np.outer(n1, n1)
        w, t = np.asarray(weights, dtype=np.float64), np.asarray(target, dtype=np.float64)
        area = (A @ w @ A.T) / cnt
        te = (A @ (w * t) @ A.T) / np.maximum(area * cnt, 1e-12)
        self.eye = eye = EyeError(te, area, sigma=EYE_SIGMA * me)
        self._emark = np.zeros(me * me, dtype=np.int64)
        self._eu = np.zeros(eye.P * eye.P)  # s (1 - D) on the eye's padded grid
        self._eu[eye.pidx] = eye.s
        self.eye_slope = self._eu * eye.G  # how much one more thread's coverage lowers the eye's error (/ 2)

    def _eye_take(self, samples, turns):
        """The eye's drawing after ``samples`` (flat, each once) were covered (``turns`` +1) or uncovered (-1)."""
        F = self.F
        row = samples // F
        cu, inv = unique(self._erow[row] + self._ecol[samples - row * F], self._emark)
        eye = self.eye
        if np.ndim(turns):
            dC = np.bincount(inv, weights=turns, minlength=len(cu))
        else:  # all one way (one chord)
            dC = np.bincount(inv, minlength=len(cu)) * turns
        eye.take(cu, dC * self._einv[cu])
        self._eu[eye.pidx[cu]] = eye.s[cu] * (1.0 - eye.D[cu])
        np.multiply(self._eu, eye.G, out=self.eye_slope)

    def eye_error(self):
        """The error as the eye sees it (on :attr:`eye`'s grid), or None without it."""
        return None if self.eye is None else self.eye.error()


def fresh(scores, uses):
    """``scores`` of chords, ``-inf`` for those drawn already (``uses > 0``): a copy lies on the first
    and adds nothing, so it is never the one to draw."""
    return np.where(uses > 0, -np.inf, scores)
