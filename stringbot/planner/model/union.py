"""The planner's thread model: the reference rendering's union of sharp threads, kept up to date.

The reference rendering (:mod:`stringbot.planner.model.reference`) covers a sample
of a fine canvas when it lies within half a thread's width of any thread's
line.  The planners keep the same test on a fine canvas of ``f x f``
samples per pixel of their working grid (the thread at least about one
sample wide), as *counts*: how many threads cover each sample.  A sample is
covered while its count is above 0, so adding or removing a thread changes
the drawing exactly where a count goes from 0 to 1 or from 1 to 0: two
threads on one spot are as dark as one, a chord drawn twice no darker than
once, two side by side twice as dark.  A pixel's darkness ``D`` is the share
of its samples covered.  One more thread that covers ``c`` of a pixel adds
``c (1 - D)`` to it on average (it falls on the uncovered part as often as
that part is large), the slope the planners score chords by.

Against the converged reference rendering of the same plan (box-filtered to
512 px, both blurred by sigma 2 px) this model's drawing is within 0.001 in
mean gray and 0.005-0.009 rms (docs/planner.md, "The planner's thread
model"; ``benchmarks/bench_model_agreement.py``).

:class:`UnionStamp` gives a thread's samples and the pixels they fall in;
the chooser (:class:`~stringbot.planner.methods.canvas.Canvas`) and the polish
(:class:`~stringbot.planner.methods.woven.WovenCanvas`) keep the counts.
"""

import math

import numpy as np


__all__ = ["UnionStamp", "fine_per_pixel", "offsets", "unique", "COUNT", "SEED"]

#: the counts' type: a sample may lie under up to 65535 threads (a chord drawn 300 times over counts each)
COUNT = np.uint16


def fine_per_pixel(width_px, *, samples=1.0, largest=None):
    """Samples per pixel's side on which a thread ``width_px`` pixels wide is at least about ``samples``
    samples wide (``round``: 0.128 px -> 8); at most ``largest`` (None: no bound)."""
    f = max(1, int(round(float(samples) / float(width_px))))
    return f if largest is None else max(1, min(f, int(largest)))


#: the seed of the samples' offsets (:func:`offsets`): every process draws a plan on the same samples
SEED = 23


def offsets(F, *, rng=None):
    """The samples' offsets on an ``F x F`` fine canvas: ``(down, across)``, float64 in ``[-0.5, 0.5)``.

    A thread nearer horizontal (a run of rows per column) tests the sample of
    row ``r`` and column ``c`` at ``(c + 0.5, r + 0.5 + down[c])``; one nearer
    vertical (a run of columns per row) at ``(c + 0.5 + across[r], r +
    0.5)``; each stays in its own cell.  On a regular lattice a thread about
    one sample wide meets the samples in the same phase column after column,
    so two threads side by side, or a chord drawn again a hair off the first,
    are over- or under-counted alike along their whole length, and the error
    survives the eye's blur; with the phase drawn at random from column to
    column the errors are independent and the blur averages them out
    (docs/planner.md, "The planner's thread model").  Two threads of the two
    kinds meet at an angle, and a straight band's overlap with another
    crossing it does not depend on where, along either, it is tested: their
    union is counted as on one lattice.

    Parameters
    ----------
    F : int
    rng : None, int or numpy Generator
        None: :data:`SEED` (the same samples in every process, so the same plan).
    """
    rng = np.random.default_rng(SEED if rng is None else rng)
    return rng.random(int(F)) - 0.5, rng.random(int(F)) - 0.5


class UnionStamp:
    """The samples a thread covers on the fine canvas of an ``m x m`` grid, ``f`` samples a pixel.

    Parameters
    ----------
    m : int
        Side of the grid (the chooser's working size, the polish's error grid).
    f : int
        Samples per pixel's side.
    width_px : float
        Thread width in pixels of the grid.
    jitter : bool
        Test the samples at their :func:`offsets` (the planners' canvases); False: at their centres
        (the reference rendering's lattice).

    Calling ``stamp(xy0, xy1)`` gives the flat indices (int32, each once) of
    the samples of the ``m f x m f`` canvas the thread covers, by the
    reference rendering's test (a sample is covered when it is within half
    the thread's width of its line, between its ends); :meth:`cells` the
    pixel of each.
    """

    def __init__(self, m, f, width_px, *, jitter=True):
        self.m, self.f = int(m), int(f)
        self.F = self.m * self.f
        self._off = offsets(self.F) if jitter else (np.zeros(self.F), np.zeros(self.F))
        self.half = float(width_px) * self.f / 2.0  # half the thread's width in samples
        # samples of one thread, at most: a run of up to 2 half sqrt(2) + 2 per column of the canvas
        self.max_samples = self.F * (int(math.ceil(2.0 * self.half * math.sqrt(2.0))) + 2)
        self._pow2 = self.F & (self.F - 1) == 0 and self.f & (self.f - 1) == 0

    def __call__(self, xy0, xy1):
        """The samples the thread from ``xy0`` to ``xy1`` covers: what
        :func:`~stringbot.planner.model.reference.thread_samples` gives on the samples as offset
        (:func:`offsets`), made with few array operations."""
        F = self.F
        x0, y0, x1, y1 = xy0[0] * F, xy0[1] * F, xy1[0] * F, xy1[1] * F
        if abs(x1 - x0) >= abs(y1 - y0):  # a run of rows per column
            a0, a1, b0, b1, smaj, smin, off = x0, x1, y0, y1, 1, F, self._off[0]
        else:  # a run of columns per row
            a0, a1, b0, b1, smaj, smin, off = y0, y1, x0, x1, F, 1, self._off[1]
        if a1 < a0:
            a0, a1, b0, b1 = a1, a0, b1, b0
        slope = (b1 - b0) / max(a1 - a0, 1e-12)
        hh = self.half * math.sqrt(1.0 + slope * slope)
        first, last = max(math.ceil(a0 - 0.5), 0), min(math.floor(a1 - 0.5), F - 1)
        if last < first:
            return np.zeros(0, np.int32)
        a = np.arange(first, last + 1, dtype=np.float64)
        m = a * slope
        m += b0 + (0.5 - a0) * slope
        m -= off[first:last + 1]  # the line's centre against the samples of each column (or row) as offset
        start = np.ceil(m - (hh + 0.5))
        n = np.floor(m + (hh - 0.5)) - start + 1.0
        top = int(n.max())
        if top <= 0:
            return np.zeros(0, np.int32)
        if start.min() < 0 or start.max() + top > F:  # near the edge
            off = np.arange(top, dtype=np.float64)
            minor = start[:, None] + off[None, :]
            ok = (off[None, :] < n[:, None]) & (minor >= 0) & (minor < F)
            minor *= smin
            minor += (a * smaj)[:, None]
            return minor[ok].astype(np.int32)
        base = (start * smin + a * smaj).astype(np.int32)
        low = max(int(n.min()), 0)
        parts = [base + j * smin for j in range(low)]
        for j in range(low, top):  # the longer runs (they differ by one sample at most)
            parts.append(base[n > j] + j * smin)
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def tile(self, flat):
        """The samples ``flat`` (row-major, as :meth:`__call__` gives them) in the tiled order of a canvas
        that keeps each pixel's ``f x f`` samples together (pixel after pixel, row-major within each):
        sample ``(r, c)`` at ``(r // f * m + c // f) * f * f + r % f * f + c % f``.  A thread's samples
        in one pixel then lie side by side in memory (a few cache lines where they took one each)."""
        F, f, m = self.F, self.f, self.m
        flat = np.asarray(flat)
        if self._pow2:
            sF, sf, sm = F.bit_length() - 1, f.bit_length() - 1, m.bit_length() - 1
            r, c = flat >> sF, flat & (F - 1)
            return ((((r >> sf) << sm) | (c >> sf)) << (2 * sf)) | ((r & (f - 1)) << sf) | (c & (f - 1))
        r, c = np.divmod(flat, F)
        return ((r // f) * m + c // f) * (f * f) + (r % f) * f + c % f

    def tiled_cells(self, tiled):
        """The pixel (flat, ``row * m + col``, int64) of each sample of a tiled canvas (:meth:`tile`)."""
        tiled = np.asarray(tiled).astype(np.int64)
        if self._pow2:
            return tiled >> (2 * (self.f.bit_length() - 1))
        return tiled // (self.f * self.f)

    def untile(self, counts):
        """A tiled canvas's values (:meth:`tile`, flat) as the ``F x F`` canvas, row-major."""
        f, m = self.f, self.m
        return np.asarray(counts).reshape(m, m, f, f).transpose(0, 2, 1, 3).reshape(self.F, self.F)

    def cells(self, flat):
        """The pixel (flat, ``row * m + col``, int64) of each sample ``flat``."""
        F, f, m = self.F, self.f, self.m
        flat = np.asarray(flat).astype(np.int64)
        if self._pow2:  # shifts and masks (the polish's 2048-sample canvas of a 256-px grid)
            sf, sm = f.bit_length() - 1, m.bit_length() - 1
            return (((flat >> (F.bit_length() - 1)) >> sf) << sm) | ((flat & (F - 1)) >> sf)
        return (flat // (F * f)) * m + (flat % F) // f


def unique(idx, mark):
    """``(u, inv)``: the distinct values of ``idx`` (in order of first appearance) and where each entry is
    in ``u`` (int32); ``mark``: int64 scratch longer than the largest value (left dirty)."""
    order = np.arange(len(idx))
    mark[idx] = order
    u = idx[mark[idx] == order]
    mark[u] = np.arange(len(u))
    return u, mark[idx].astype(np.int32)
