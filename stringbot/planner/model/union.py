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
mean gray and 0.005-0.013 rms (docs/planner.md, "The planner's thread
model"; ``benchmarks/bench_model_agreement.py``).

:class:`UnionStamp` gives a thread's samples and the pixels they fall in;
the chooser (:class:`~stringbot.planner.methods.canvas.Canvas`) and the polish
(:class:`~stringbot.planner.methods.woven.WovenCanvas`) keep the counts.
"""

import math

import numpy as np


__all__ = ["UnionStamp", "fine_per_pixel", "unique", "COUNT"]

#: the counts' type: a sample may lie under up to 65535 threads (a chord drawn 300 times over counts each)
COUNT = np.uint16


def fine_per_pixel(width_px, *, samples=1.0, largest=None):
    """Samples per pixel's side on which a thread ``width_px`` pixels wide is at least about ``samples``
    samples wide (``round``: 0.128 px -> 8); at most ``largest`` (None: no bound)."""
    f = max(1, int(round(float(samples) / float(width_px))))
    return f if largest is None else max(1, min(f, int(largest)))


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

    Calling ``stamp(xy0, xy1)`` gives the flat indices (int32, each once) of
    the samples of the ``m f x m f`` canvas the thread covers, by the
    reference rendering's test; :meth:`cells` the pixel of each.
    """

    def __init__(self, m, f, width_px):
        self.m, self.f = int(m), int(f)
        self.F = self.m * self.f
        self.half = float(width_px) * self.f / 2.0  # half the thread's width in samples
        # samples of one thread, at most: a run of up to 2 half sqrt(2) + 2 per column of the canvas
        self.max_samples = self.F * (int(math.ceil(2.0 * self.half * math.sqrt(2.0))) + 2)
        self._pow2 = self.F & (self.F - 1) == 0 and self.f & (self.f - 1) == 0

    def __call__(self, xy0, xy1):
        """The samples the thread from ``xy0`` to ``xy1`` covers: what
        :func:`~stringbot.planner.model.reference.thread_samples` gives, made with few array operations."""
        F = self.F
        x0, y0, x1, y1 = xy0[0] * F, xy0[1] * F, xy1[0] * F, xy1[1] * F
        if abs(x1 - x0) >= abs(y1 - y0):  # a run of rows per column
            a0, a1, b0, b1, smaj, smin = x0, x1, y0, y1, 1, F
        else:  # a run of columns per row
            a0, a1, b0, b1, smaj, smin = y0, y1, x0, x1, F, 1
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
        start = np.ceil(m - (hh + 0.5))
        n = np.floor(m + (hh - 0.5)) - start + 1.0
        top = int(n.max())
        if top <= 0:
            return np.zeros(0, np.int32)
        if start[0] < 0 or start[-1] < 0 or start[0] + top > F or start[-1] + top > F:  # near the edge
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
