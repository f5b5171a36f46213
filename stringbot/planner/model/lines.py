"""Points along chords: ThreadTone's line sampling, and per pin the points of every chord from it.

A chord is sampled at ``int(hypot(dx, dy) / spacing)`` points spaced evenly
from pin to pin (ThreadTone's ``linePixels``: ``np.linspace``, both pins
included), so the count of points is proportional to the chord's length in
every direction.  The greedy (:mod:`stringbot.planner.methods.greedy`), the
residual chooser (:mod:`stringbot.planner.methods.residual`) and the polish
(:mod:`stringbot.planner.methods.polish`) score chords by the mean of a field
at these points (:class:`PinLines`).
"""

import numpy as np

from .chords import pin_pixels

__all__ = ["line_samples", "line_counts", "PinLines"]


def line_counts(r0, c0, r1, c1, *, spacing=1.0):
    """How many points :func:`line_samples` takes along each chord: ``int(hypot / spacing)``, at least 1
    (int64, shape (k,))."""
    r1, c1 = np.asarray(r1, dtype=np.float64), np.asarray(c1, dtype=np.float64)
    return np.maximum((np.hypot(r1 - r0, c1 - c0) / spacing).astype(np.int64), 1)


def line_samples(r0, c0, r1, c1, size, *, nearest=False, spacing=1.0):
    """ThreadTone's line points: ``int(hypot)`` points from pin to pin, each on its nearest pixel.

    Parameters
    ----------
    r0, c0 : int
        The start pin's pixel.
    r1, c1 : ndarray of int, shape (k,)
        The other pins' pixels.
    size : int
    nearest : bool
        Each point on its nearest pixel; False: truncated, as ThreadTone does.
    spacing : float
        ``int(hypot / spacing)`` points (1: ThreadTone's).

    Returns
    -------
    starts : ndarray of int64, shape (k,)
        Offset of each chord's first point in ``flat``.
    flat : ndarray of int32
        Flat pixel indices, chord after chord (a pixel may come twice).
    """
    r1, c1 = np.asarray(r1, dtype=np.float64), np.asarray(c1, dtype=np.float64)
    dr, dc = r1 - r0, c1 - c0
    n = line_counts(r0, c0, r1, c1, spacing=spacing)
    starts = np.concatenate([[0], np.cumsum(n)[:-1]])
    # one row per chord, padded to the longest (fewer gathers than repeating per point); the points kept
    # are, in order, those of np.linspace
    inv = (1.0 / np.maximum(n - 1, 1)).astype(np.float32)  # linspace: both pins included
    k = np.arange(int(n.max()), dtype=np.float32)
    keep = k[None, :] < n[:, None]
    t = k[None, :] * inv[:, None]
    rnd = np.rint if nearest else np.floor
    # float32 is exact enough here: coordinates < 4096, steps of at least 1/4096
    rr = t * dr.astype(np.float32)[:, None]
    rr += np.float32(r0)
    rnd(rr, out=rr)
    cc = t * dc.astype(np.float32)[:, None]
    cc += np.float32(c0)
    rnd(cc, out=cc)
    np.clip(rr, 0, size - 1, out=rr)
    np.clip(cc, 0, size - 1, out=cc)
    rr *= size
    rr += cc
    return starts, rr[keep].astype(np.int32)


class PinLines:
    """Per pin, the line points of every chord from it, built the first time the pin is visited.

    ``nearest``: points on their nearest pixel (else truncated, as ThreadTone does); ``spacing``:
    pixels between points (1: ThreadTone's); ``keep``: False builds them again each time (for a caller
    that keeps them itself).  ``shared`` (set by the caller, None by default): where another process
    may have laid out a pin's points already, ``shared.points(self, p)`` (flat, or None: built here).
    """

    def __init__(self, space, size, *, nearest=False, spacing=1.0, keep=True):
        self.space, self.size, self.nearest, self.spacing, self.keep = space, size, nearest, spacing, keep
        if nearest:
            self.rc = pin_pixels(space.pin_xy, size)
        else:  # ThreadTone truncates its pin coordinates: int(r + 1 + r cos a), sampled one pixel lower
            self.rc = np.clip(np.floor(np.asarray(space.pin_xy)[:, ::-1] * (size - 1) + 1e-9), 0,
                              size - 1).astype(np.int64)
        self.cache = {}
        self.shared = None

    def build(self, p):
        """``(others, starts, flat)`` of pin ``p``, built afresh."""
        others = np.flatnonzero(self.space.index[p] >= 0)
        r0, c0 = self.rc[p]
        return (others,) + line_samples(r0, c0, self.rc[others, 0], self.rc[others, 1], self.size,
                                        nearest=self.nearest, spacing=self.spacing)

    def counts(self, p):
        """``(others, n)``: the pins reachable from ``p`` and how many points each chord has (int64)."""
        others = np.flatnonzero(self.space.index[p] >= 0)
        r0, c0 = self.rc[p]
        return others, line_counts(r0, c0, self.rc[others, 0], self.rc[others, 1], spacing=self.spacing)

    def totals(self):
        """How many points each pin's chords have together (int64, shape (pins,)): :meth:`counts` summed,
        for every pin at once."""
        rc = self.rc
        n = line_counts(rc[:, None, 0], rc[:, None, 1], rc[None, :, 0], rc[None, :, 1], spacing=self.spacing)
        return np.where(self.space.index >= 0, n, 0).sum(axis=1)

    def get_with_counts(self, p):
        """``(others, flat, starts, counts)``: the pins reachable from ``p`` and their chords' points."""
        row = self.cache.get(p)
        if row is None:
            flat = None if self.shared is None else self.shared.points(self, p)
            if flat is None:
                others, starts, flat = self.build(p)
            else:  # laid out elsewhere: the same points (line_samples's starts, from the same counts)
                others, n = self.counts(p)
                starts = np.concatenate([[0], np.cumsum(n)[:-1]])
            counts = np.diff(np.append(starts, len(flat))).astype(np.float32)
            row = (others, flat, starts, counts)
            if self.keep:
                self.cache[p] = row
        return row

    def get(self, p):
        return self.get_with_counts(p)[:3]
