"""The as-woven polish: refine a plan against the piece as the eye sees it.

The residual planner (:mod:`stringbot.planner.methods.residual`) judges its threads
pixel by pixel at the working size.  From a step away (and in ``stringbot
score``'s as-woven error) the piece is seen through a blur of about 2 mm on
a 500 mm frame: a light gap beside a dark band matters, a thread's own
stripe does not.

:class:`WovenCanvas` keeps the threads as the reference rendering draws
them (:mod:`stringbot.planner.model.union`: how many threads cover each sample of
a fine canvas on which the thread is about one sample wide, 2048 samples a
side for the default 0.25 mm on 500 mm), the covered share of each pixel of
a grid of ``m`` pixels (``D``); and the error
``E = || B (s (t - D)) ||^2`` where ``B`` is the eye's Gaussian blur (sigma
2 px at 512 px, the scorer's), ``t`` the target darkness and ``s`` the square
root of the pixel weights (0 outside the frame).  With ``G = B^2 (s (t - D))``
kept up to date, a change ``dD`` of the drawing (``v = s dD``) changes the
error by exactly ``-2 <v, G> + <v, B^2 v>``.

:mod:`stringbot.planner.methods.polish` revisits pins of the sequence against it.
"""

import logging

import numpy as np

from ..model.scoring import WOVEN_SIZE
from ..model.union import COUNT, UnionStamp, fine_per_pixel, unique
from .canvas import fresh, sum_sparse
from .eye import EYE_SIGMA, EyeError

log = logging.getLogger(__name__)

__all__ = ["WovenCanvas", "EYE_SIGMA", "MAX_FINE", "GRID", "fine_factor"]

#: side of the grid the error is measured on (at most the working size): half the scorer's, the blur 1 px
GRID = WOVEN_SIZE // 2
#: largest side of the fine canvas (its counts are uint16: 32 MB)
MAX_FINE = 4096
#: footprints kept (about 20 kB each on a 2048-px canvas): the drawing's chords and the chords tried
#: (tried again often: the same pin's best way round comes up again)
MAX_CACHED = 8000


def fine_factor(width_px, m):
    """Fine pixels per pixel of an ``m``-px grid on which a thread ``width_px`` grid pixels wide is about
    one fine pixel wide (at most :data:`MAX_FINE` fine pixels in all)."""
    return fine_per_pixel(width_px, largest=MAX_FINE // m)


class WovenCanvas(EyeError):
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
        self.Sf = np.zeros(self.F * self.F, dtype=COUNT)  # threads over each fine pixel, tiled (UnionStamp.tile)
        self._stamp = UnionStamp(m, f, width_px)
        self._fp = {}
        EyeError.__init__(self, target, weights, sigma=float(sigma) * m)
        P = self.P
        self.u = np.zeros(P * P)  # s (1 - D): how much darker one more thread still makes a pixel
        self.u[self.pidx] = self.s
        self.g = self.u * self.G  # the error's slope: how much one more thread's coverage lowers E (/ 2)
        n = len(self.pin_xy)
        self.uses = np.zeros((n, n), dtype=np.int32)
        self._rows = {}
        self._mark = np.zeros(m * m, dtype=np.int64)
        self._acc = np.zeros(m * m)

    # -- footprints -------------------------------------------------------------------------------------

    def footprint(self, a, b):
        """``(flat, None, inv, cu)`` of chord ``(a, b)``: its fine pixels (each once), and the grid pixels
        ``cu`` they fall in (each once; fine pixel ``i`` is in ``cu[inv[i]]``); cached."""
        fp = self.stamped(a, b)
        if fp[2] is None:  # the grid pixels: found the first time a change needs them (drawing does not)
            fp[3], fp[2] = unique(self._stamp.tiled_cells(fp[0]), self._mark)
        return fp

    def stamped(self, a, b):
        """``[flat, None, inv, cu]`` of chord ``(a, b)`` as cached (``inv``, ``cu`` None until needed);
        ``flat``: its samples on the tiled fine canvas (:meth:`UnionStamp.tile
        <stringbot.planner.model.union.UnionStamp.tile>`: a pixel's samples together, fewer cache misses
        where a change reads and writes them)."""
        key = (a, b) if a < b else (b, a)
        fp = self._fp.get(key)
        if fp is None:
            if len(self._fp) >= MAX_CACHED:  # chords tried and not drawn go first
                for k in [k for k in self._fp if self.uses[k] == 0]:
                    del self._fp[k]
                if len(self._fp) >= MAX_CACHED // 2:
                    self._fp.clear()  # a footprint is stamped again exactly as it was
            flat = self._stamp.tile(self._stamp(self.pin_xy[key[0]], self.pin_xy[key[1]]))
            fp = self._fp[key] = [flat, None, None, None]
        return fp

    def fine_counts(self):
        """Threads over each fine pixel as the ``F x F`` canvas (row-major; kept tiled)."""
        return self._stamp.untile(self.Sf)

    @property
    def max_samples(self):
        """Fine pixels of one chord, at most."""
        return self._stamp.max_samples

    # -- the whole drawing -------------------------------------------------------------------------------

    def build(self, chords):
        """Draw ``chords`` on a fresh canvas; returns ``E``.

        The same as :meth:`draw` of ``chords`` in any number of parts in turn
        (on a fresh canvas), then :meth:`finish`: the same float operations in
        the same order.
        """
        self.Sf[:] = 0
        self.uses[:] = 0
        self.draw(chords)
        return self.finish()

    def draw(self, chords):
        """Add chords to the fine canvas (``D`` and the error wait for :meth:`finish`)."""
        for a, b in chords:
            a, b = int(a), int(b)
            flat = self.stamped(a, b)[0]
            self.Sf[flat] += 1  # each fine pixel once per footprint
            self.uses[a, b] += 1
            if a != b:
                self.uses[b, a] += 1

    def finish(self):
        """The grid, the error and its slope from the fine canvas as drawn; returns ``E``."""
        m, f = self.size, self.f
        covered = (self.Sf > 0).reshape(m * m, f * f).sum(axis=1, dtype=np.int32)  # tiled: a pixel's samples
        self.reset(covered / float(f * f))
        self.u[self.pidx] = self.s * (1.0 - self.D)
        self.g = self.u * self.G
        return self.E

    # -- changes -----------------------------------------------------------------------------------------

    def _fine(self, chords_out, chords_in, write):
        """Change of ``D`` from removing then adding chords: ``(cp, dD)`` on the grid.

        ``write``: ``"keep"`` changes ``Sf`` (exact); ``"undo"`` puts it back (exact); ``"none"``
        judges each chord against ``Sf`` as it is (exact but where the chords given overlap each other),
        and ``cp`` may then hold a grid pixel more than once (its changes to be summed: what the error's
        change, linear in ``dD`` and through the blur, does anyway).
        A fine pixel changes where its count goes from 0 to 1 (a chord added) or 1 to 0 (removed).
        """
        saved, parts = [], []
        for chords, sign in ((chords_out, -1), (chords_in, 1)):
            for a, b in chords:
                flat, _, inv, cu = self.footprint(a, b)
                old = self.Sf[flat]
                turns = old == (0 if sign > 0 else 1)
                if write != "none":
                    self.Sf[flat] = old + 1 if sign > 0 else old - (old > 0)
                    if write == "undo":
                        saved.append((flat, old))
                parts.append((cu, sign * np.bincount(inv[turns], minlength=len(cu))))
        for flat, old in reversed(saved):
            self.Sf[flat] = old
        if not parts:
            return None, None
        if len(parts) == 1:
            cp, dC = parts[0]
        elif write == "none":  # an estimate: the parts as they are (a pixel may come twice; the sums are the same)
            cp, dC = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        else:
            cp, dC = sum_sparse(parts, self._acc, self._mark)
        return cp, dC * (1.0 / float(self.f * self.f))

    def delta(self, chords_out=(), chords_in=()):
        """Exact change of ``E`` if ``chords_out`` were removed and ``chords_in`` added (nothing changes)."""
        cp, dD = self._fine(chords_out, chords_in, "undo")
        return 0.0 if cp is None else self.change(cp, dD)[0]

    def estimate(self, chords_out=(), chords_in=()):
        """:meth:`delta` with each chord judged against the drawing as it is: exact but where the
        chords given overlap each other (near the pins they share); cheaper (nothing is written)."""
        cp, dD = self._fine(chords_out, chords_in, "none")
        return 0.0 if cp is None else self.change(cp, dD)[0]

    def helps(self, chords_out=(), chords_in=()):
        """Whether :meth:`estimate` is below 0: the same answer, sooner when the change's linear
        term already says no."""
        cp, dD = self._fine(chords_out, chords_in, "none")
        return cp is not None and self.change(cp, dD, sign=True)[0] < 0.0

    def apply(self, chords_out=(), chords_in=()):
        """Remove ``chords_out`` and add ``chords_in``; returns the exact change of ``E``."""
        return self.apply_change(chords_out, chords_in)[0]

    def apply_change(self, chords_out=(), chords_in=()):
        """:meth:`apply`, and the change of the drawing it made: ``(dE, cp, dD)`` (``cp`` the grid pixels
        whose ``D`` changed by ``dD``; None, None where nothing did), for another error of the same drawing
        (:class:`~stringbot.planner.methods.polish.Guarded`)."""
        self._count(chords_out, chords_in)
        cp, dD = self._fine(chords_out, chords_in, "keep")
        if cp is None:
            return 0.0, None, None
        dE, v, h = self.change(cp, dD, blur2=True)
        self.G -= h
        self.D[cp] += dD
        self.u[self.pidx[cp]] = self.s[cp] * (1.0 - self.D[cp])
        np.multiply(self.u, self.G, out=self.g)  # the same as where h is not 0, and cheaper than finding it
        self.E += dE
        return dE, cp, dD

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
        """``(others, score)``: the mean of ``u G`` along each chord from pin ``a`` (its error slope) times
        the square root of its length in points, ``-inf`` for a chord drawn already (a copy adds nothing:
        :func:`~stringbot.planner.methods.canvas.fresh`).  (The chord's whole gain is the sum, its
        mean the gain per length; between the two the polish finds better pins to go through:
        docs/planner.md.)

        ``pin_lines`` should not keep its points (``keep=False``): they are kept here, on the padded grid.
        """
        others, pp, starts, counts = self.row(pin_lines, a)
        return others, fresh(np.add.reduceat(self.g.take(pp), starts) / np.sqrt(counts), self.uses[a, others])

    def chord_scores(self, pin_lines, chords):
        """The mean of ``u G`` along each of the given chords ``(a, b)`` (each from its pin ``a``'s row, as
        :meth:`scores` gives it for a chord not drawn), 0 for a chord not in the row; one gather for all."""
        out = np.zeros(len(chords))
        pick, counts, at = [], [], []
        for i, (a, b) in enumerate(chords):
            others, pp, starts, cnt = self.row(pin_lines, a)
            j = int(np.searchsorted(others, b))
            if j < len(others) and others[j] == b:
                end = int(starts[j + 1]) if j + 1 < len(starts) else len(pp)
                pick.append(pp[int(starts[j]):end])
                counts.append(cnt[j])
                at.append(i)
        if pick:
            first = np.concatenate([[0], np.cumsum([len(x) for x in pick])[:-1]])
            sums = np.add.reduceat(self.g.take(np.concatenate(pick)), first)
            out[at] = sums / np.asarray(counts, dtype=np.float32)
        return out
