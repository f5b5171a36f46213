"""The as-woven polish: refine a plan against the piece as the eye sees it.

The residual planner (:mod:`stringbot.planner.residual`) judges its threads
pixel by pixel at the working size, with the thread model's average law
(``D = tanh(S)``).  Two things it cannot see decide how the piece looks from
a step away:

* *where threads overlap.*  Whether two threads crossing one working pixel
  lie side by side or on top of each other changes that pixel's darkness by
  up to a third (0.08 rms on the horse); only a canvas on which the thread is
  about one pixel wide shows it.
* *the eye's blur.*  From a step away (and in ``stringbot score``'s as-woven
  error) the piece is seen through a blur of about 2 mm on a 500 mm frame:
  a light gap beside a dark band matters, a thread's own stripe does not.

:class:`WovenCanvas` keeps both: the summed coverage ``Sf`` of the threads on a
fine canvas where the thread is about one pixel wide (the scorer's 2048 px
for the default 0.25 mm on 500 mm), capped at 1 per fine pixel as the thread
model does, averaged to a grid of ``m`` pixels (``D``); and the error
``E = || B (s (t - D)) ||^2`` where ``B`` is the eye's Gaussian blur (sigma
2 px at 512 px, the scorer's), ``t`` the target darkness and ``s`` the square
root of the pixel weights (0 outside the frame).  With ``G = B^2 (s (t - D))``
kept up to date, a change ``dD`` of the drawing (``v = s dD``) changes the
error by exactly ``-2 <v, G> + <v, B^2 v>``.

:mod:`stringbot.planner.polish` revisits pins of the sequence against it.
"""

import logging
import math

import numpy as np

from .residual import repeat_gains, sum_sparse
from .scoring import WOVEN_SIGMA, WOVEN_SIZE
from .thread import SegmentStamp

log = logging.getLogger(__name__)

__all__ = ["WovenCanvas", "EYE_SIGMA", "MAX_FINE", "GRID", "fine_factor"]

#: the eye's blur: sigma as a fraction of the frame's side (the as-woven scorer's, 2 px at 512 px)
EYE_SIGMA = WOVEN_SIGMA / WOVEN_SIZE
#: side of the grid the error is measured on (at most the working size): half the scorer's, the blur 1 px
GRID = WOVEN_SIZE // 2
#: largest side of the fine canvas (its coverage is float32: 64 MB)
MAX_FINE = 4096
#: footprints kept (about 60 kB each on a 2048-px canvas): the drawing's chords and the chords tried
#: (tried again often: the same pin's best way round comes up again)
MAX_CACHED = 5000


def fine_factor(width_px, m):
    """Fine pixels per pixel of an ``m``-px grid on which a thread ``width_px`` grid pixels wide is about
    one fine pixel wide (at most :data:`MAX_FINE` fine pixels in all)."""
    return max(1, min(int(round(1.0 / float(width_px))), MAX_FINE // m))


class WovenCanvas:
    """The drawing as woven on a fine canvas, and its error as the eye sees it.

    Parameters
    ----------
    target : ndarray of float, shape (m, m)
        Darkness wanted, 0..1, on the grid the error is measured on.
    weights : ndarray of float, shape (m, m)
        Pixel weights (0 outside the frame).
    pin_xy : ndarray of float, shape (pins, 2)
    width_px : float
        Thread width in pixels of the ``m`` grid.
    sigma : float
        The eye's blur as a fraction of the frame's side (:data:`EYE_SIGMA`).
    """

    def __init__(self, target, weights, pin_xy, width_px, *, sigma=EYE_SIGMA):
        m = target.shape[0]
        self.size = m
        self.pin_xy = np.asarray(pin_xy, dtype=np.float64)
        f = fine_factor(width_px, m)  # the thread about one fine pixel wide
        self.f, self.F = f, m * f
        self.Sf = np.zeros(self.F * self.F, dtype=np.float32)
        self._wf = float(width_px) * f  # the thread's width in fine pixels
        self._stamp = SegmentStamp(self.F, self._wf)
        self._fp = {}
        self.t = np.asarray(target, dtype=np.float64).ravel()
        self.s = np.sqrt(np.asarray(weights, dtype=np.float64).ravel())
        self.D = np.zeros(m * m)
        # B: a Gaussian of sigma in pixels of the m grid (the scorer's sigma), cut at two sigmas (the
        # scorer's filter goes on to four: E differs by about 0.1 %); B^2 its own square
        sg = float(sigma) * m
        r1 = max(1, int(math.ceil(2.0 * sg)))
        ax1 = np.arange(-r1, r1 + 1, dtype=np.float64)
        k1 = np.exp(-ax1 ** 2 / (2.0 * sg * sg))
        k1 /= k1.sum()
        k2 = np.convolve(k1, k1)
        rad = 2 * r1
        ax = np.arange(-rad, rad + 1, dtype=np.int64)
        P = m + 2 * rad
        self.rad, self.P = rad, P
        self._koff = (ax[:, None] * P + ax[None, :]).ravel()  # B^2 on the padded grid
        self._kw = np.outer(k2, k2).ravel()
        self._koff1 = (ax1.astype(np.int64)[:, None] * P + ax1.astype(np.int64)[None, :]).ravel()  # B
        self._kw1 = np.outer(k1, k1).ravel()
        r, c = np.divmod(np.arange(m * m), m)
        self.pidx = ((r + rad) * P + (c + rad)).astype(np.int32)  # each grid pixel on the padded grid
        # B^2 of a picture on the grid, as the padded grid: T x T^T (T: the 1-D kernel, grid -> padded)
        off = np.arange(m)[None, :] + rad - np.arange(P)[:, None]
        self._T = np.where(np.abs(off) <= rad, k2[np.clip(off + rad, 0, 2 * rad)], 0.0)
        self.G = self._blur2_grid(self.s * self.t)
        self.E = float(np.dot(self.s * self.t, self.G[self.pidx]))
        self.u = np.zeros(P * P)  # s (1 - D): how much darker one more thread still makes a pixel
        self.u[self.pidx] = self.s
        self.g = self.u * self.G  # the error's slope: how much one more thread's coverage lowers E (/ 2)
        n = len(self.pin_xy)
        self.uses = np.zeros((n, n), dtype=np.int32)
        self.gains = repeat_gains()
        self._rows = {}
        self._mark = np.zeros(m * m, dtype=np.int64)
        self._acc = np.zeros(m * m)

    # -- footprints -------------------------------------------------------------------------------------

    def footprint(self, a, b):
        """``(flat, cover, inv, cu)`` of chord ``(a, b)``: its fine pixels (each once), their coverage,
        and the grid pixels ``cu`` they fall in (each once; fine pixel ``i`` is in ``cu[inv[i]]``); cached."""
        fp = self.stamped(a, b)
        if fp[2] is None:  # the grid pixels: found the first time a change needs them (drawing does not)
            fp[3], fp[2] = self._unique(self._cells(fp[0]))
        return fp

    def _cells(self, flat):
        """The grid pixel of each fine pixel ``flat`` (int64: it indexes)."""
        F, f, m = self.F, self.f, self.size
        flat = flat.astype(np.int64)
        if F & (F - 1) == 0 and f & (f - 1) == 0:  # powers of two (the usual case): shifts and masks
            sf, sm = f.bit_length() - 1, m.bit_length() - 1
            return (((flat >> (F.bit_length() - 1)) >> sf) << sm) | ((flat & (F - 1)) >> sf)
        return (flat // (F * f)) * m + (flat % F) // f

    def stamped(self, a, b):
        """``[flat, cover, inv, cu]`` of chord ``(a, b)`` as cached (``inv``, ``cu`` None until needed)."""
        key = (a, b) if a < b else (b, a)
        fp = self._fp.get(key)
        if fp is None:
            if len(self._fp) >= MAX_CACHED:  # chords tried and not drawn go first
                for k in [k for k in self._fp if self.uses[k] == 0]:
                    del self._fp[k]
                if len(self._fp) >= MAX_CACHED // 2:
                    self._fp.clear()  # a footprint is stamped again exactly as it was
            flat, cov = self._stamp(self.pin_xy[key[0]], self.pin_xy[key[1]], compact=True)
            fp = self._fp[key] = [flat, cov, None, None]
        return fp

    def _unique(self, idx):
        """``(u, inv)``: the distinct grid pixels of ``idx`` and where each entry is in ``u``."""
        mark = self._mark
        order = np.arange(len(idx))
        mark[idx] = order
        u = idx[mark[idx] == order]
        mark[u] = np.arange(len(u))
        return u, mark[idx].astype(np.int32)

    # -- the whole drawing -------------------------------------------------------------------------------

    def build(self, chords):
        """Draw ``chords`` on a fresh canvas; returns ``E``.

        The same as :meth:`draw` of ``chords`` in any number of parts in turn
        (on a fresh canvas), then :meth:`finish`: the same float operations in
        the same order.
        """
        self.Sf[:] = 0.0
        self.uses[:] = 0
        self.draw(chords)
        return self.finish()

    def draw(self, chords):
        """Add chords' coverage to the fine canvas (``D`` and the error wait for :meth:`finish`)."""
        for a, b in chords:
            a, b = int(a), int(b)
            flat, cov, _, _ = self.stamped(a, b)
            self.Sf[flat] += cov  # each fine pixel once per footprint
            self.uses[a, b] += 1
            if a != b:
                self.uses[b, a] += 1

    def finish(self):
        """The grid, the error and its slope from the fine canvas as drawn; returns ``E``."""
        m, f = self.size, self.f
        self.D = np.minimum(self.Sf, 1.0).reshape(m, f, m, f).mean(axis=(1, 3), dtype=np.float64).ravel()
        x = self.s * (self.t - self.D)
        self.G = self._blur2_grid(x)
        self.E = float(np.dot(x, self.G[self.pidx]))
        self.u[self.pidx] = self.s * (1.0 - self.D)
        self.g = self.u * self.G
        return self.E

    def _blur2_grid(self, x):
        """``B^2 x`` on the padded grid (flat) of ``x`` on the grid (zero around it)."""
        m = self.size
        return (self._T @ np.asarray(x, dtype=np.float64).reshape(m, m) @ self._T.T).ravel()

    def error(self):
        """``E = || B (s (t - D)) ||^2``."""
        return self.E

    # -- changes -----------------------------------------------------------------------------------------

    def _fine(self, chords_out, chords_in, write):
        """Change of ``D`` from removing then adding chords: ``(cp, dD)`` on the grid.

        ``write``: ``"keep"`` changes ``Sf`` (exact); ``"undo"`` puts it back (exact); ``"none"``
        judges each chord against ``Sf`` as it is (exact but where the chords given overlap each other).
        """
        saved, parts = [], []
        for chords, sign in ((chords_out, -1.0), (chords_in, 1.0)):
            for a, b in chords:
                flat, cov, inv, cu = self.footprint(a, b)
                old = self.Sf[flat]
                new = old + cov if sign > 0 else np.maximum(old - cov, 0.0)
                if write != "none":
                    self.Sf[flat] = new
                    if write == "undo":
                        saved.append((flat, old))
                np.minimum(new, 1.0, out=new)
                parts.append((cu, np.bincount(inv, weights=new - np.minimum(old, 1.0), minlength=len(cu))))
        for flat, old in reversed(saved):
            self.Sf[flat] = old
        if not parts:
            return None, None
        cp, dC = parts[0] if len(parts) == 1 else sum_sparse(parts, self._acc, self._mark)
        return cp, dC / float(self.f * self.f)

    def _change(self, cp, dD, *, blur2=False, sign=False):
        """``(dE, v, h)``: the exact change of ``E`` for ``dD`` on grid pixels ``cp``; ``h = B^2 v``
        if ``blur2`` (else None: ``<v, B^2 v> = |B v|^2`` is cheaper).  ``sign``: when the linear
        term alone does not lower ``E``, that term (the quadratic one is never negative: ``dE`` is
        not negative either)."""
        v = self.s[cp] * dD
        pp = self.pidx[cp]
        lin = -2.0 * np.dot(v, self.G[pp])
        if blur2:
            h = self._blur(cp, v, self._koff, self._kw)
            return float(lin + np.dot(v, h[pp])), v, h
        if sign and lin >= 0.0:
            return float(lin), v, None
        b = self._blur(cp, v, self._koff1, self._kw1)
        return float(lin + np.dot(b, b)), v, None

    def _blur(self, cp, v, koff, kw):
        idx = (self.pidx[cp][:, None] + koff[None, :]).ravel()
        return np.bincount(idx, weights=(v[:, None] * kw[None, :]).ravel(), minlength=self.P * self.P)

    def delta(self, chords_out=(), chords_in=()):
        """Exact change of ``E`` if ``chords_out`` were removed and ``chords_in`` added (nothing changes)."""
        cp, dD = self._fine(chords_out, chords_in, "undo")
        return 0.0 if cp is None else self._change(cp, dD)[0]

    def estimate(self, chords_out=(), chords_in=()):
        """:meth:`delta` with each chord judged against the drawing as it is: exact but where the
        chords given overlap each other (near the pins they share); cheaper (nothing is written)."""
        cp, dD = self._fine(chords_out, chords_in, "none")
        return 0.0 if cp is None else self._change(cp, dD)[0]

    def helps(self, chords_out=(), chords_in=()):
        """Whether :meth:`estimate` is below 0: the same answer, sooner when the change's linear
        term already says no."""
        cp, dD = self._fine(chords_out, chords_in, "none")
        return cp is not None and self._change(cp, dD, sign=True)[0] < 0.0

    def apply(self, chords_out=(), chords_in=()):
        """Remove ``chords_out`` and add ``chords_in``; returns the exact change of ``E``."""
        self._count(chords_out, chords_in)
        cp, dD = self._fine(chords_out, chords_in, "keep")
        if cp is None:
            return 0.0
        dE, v, h = self._change(cp, dD, blur2=True)
        self.G -= h
        self.D[cp] += dD
        self.u[self.pidx[cp]] = self.s[cp] * (1.0 - self.D[cp])
        np.multiply(self.u, self.G, out=self.g)  # the same as where h is not 0, and cheaper than finding it
        self.E += dE
        return dE

    def _count(self, chords_out, chords_in):
        """Keep :attr:`uses` (how many times each chord is drawn) in step with a change."""
        for chords, sign in ((chords_out, -1), (chords_in, 1)):
            for a, b in chords:
                self.uses[a, b] += sign
                if a != b:
                    self.uses[b, a] += sign

    # -- the same change in another process ----------------------------------------------------------------

    def change_record(self, chords):
        """What the last changes of ``chords`` left on the drawing: ``(flat, sf, cu, d)``, the fine
        canvas at their fine pixels and the grid at their grid pixels (with :attr:`G` and :attr:`E`,
        all that :meth:`replay` needs to bring a copy of the drawing as it was before to the same state)."""
        fps = [self.footprint(a, b) for a, b in chords]
        flat = np.concatenate([fp[0] for fp in fps])
        cu = np.concatenate([fp[3] for fp in fps])
        return flat, self.Sf[flat], cu, self.D[cu]

    def replay(self, record, G, E, chords_out=(), chords_in=()):
        """Bring the drawing to the state another copy of it reached by :meth:`apply` (removing
        ``chords_out``, adding ``chords_in``; both empty when it was undone) and described by
        :meth:`change_record`, ``G`` and ``E``: the same values, not computed again."""
        self._count(chords_out, chords_in)
        flat, sf, cu, d = record
        self.Sf[flat] = sf
        self.D[cu] = d
        self.u[self.pidx[cu]] = self.s[cu] * (1.0 - self.D[cu])  # u = s (1 - D) everywhere, always
        np.copyto(self.G, G)
        np.multiply(self.u, self.G, out=self.g)
        self.E = float(E)

    # -- scores ------------------------------------------------------------------------------------------

    def row(self, pin_lines, a):
        """``(others, pp, starts, counts)``: pin ``a``'s chords' points on the padded grid (kept)."""
        row = self._rows.get(a)
        if row is None:
            others, pix, starts, counts = pin_lines.get_with_counts(a)
            row = self._rows[a] = (others, self.pidx[pix], starts, counts)
        return row

    def scores(self, pin_lines, a):
        """``(others, score)``: the mean of ``u G`` along each chord from pin ``a`` (its error slope),
        times the share of a thread a copy of it adds (:func:`~stringbot.planner.residual.repeat_gains`).

        ``pin_lines`` should not keep its points (``keep=False``): they are kept here, on the padded grid.
        """
        others, pp, starts, counts = self.row(pin_lines, a)
        return others, self._weigh(np.add.reduceat(self.g.take(pp), starts), counts, self.uses[a, others])

    def chord_scores(self, pin_lines, chords):
        """:meth:`scores` of the given chords ``(a, b)`` alone (each from its pin ``a``'s row, the
        same values), 0 for a chord not in the row; one gather for all."""
        out = np.zeros(len(chords))
        pick, counts, at, uses = [], [], [], []
        for i, (a, b) in enumerate(chords):
            others, pp, starts, cnt = self.row(pin_lines, a)
            j = int(np.searchsorted(others, b))
            if j < len(others) and others[j] == b:
                end = int(starts[j + 1]) if j + 1 < len(starts) else len(pp)
                pick.append(pp[int(starts[j]):end])
                counts.append(cnt[j])
                at.append(i)
                uses.append(self.uses[a, b])
        if pick:
            first = np.concatenate([[0], np.cumsum([len(x) for x in pick])[:-1]])
            sums = np.add.reduceat(self.g.take(np.concatenate(pick)), first)
            out[at] = self._weigh(sums, np.asarray(counts, dtype=np.float32), np.asarray(uses))
        return out

    def _weigh(self, sums, counts, uses):
        """Mean along each chord times the share of a thread its next copy adds."""
        return sums / counts * self.gains[np.minimum(uses, len(self.gains) - 1)]
