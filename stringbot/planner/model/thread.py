"""The blurred thread model: how a set of real threads darkens a board, in real units.

(The piece as it will hang is drawn by :mod:`stringbot.planner.model.reference`, the
union of sharp threads; the planners keep that union too,
:mod:`stringbot.planner.model.union`, the colour planner with the colour on top of
each sample.  :class:`ThreadModel` -- the frame and the thread, in millimetres --
serves all; this module's anti-aliased footprints serve no planner any more: only
their own tests and the measurements of docs/planner.md that compare them.)

A thread painting is threads of width ``thread_mm`` stretched between pins on a
frame of diameter ``diameter_mm``.  Drawn on a ``size x size`` canvas that
spans the frame's square, a thread is ``width_px = thread_mm / diameter_mm *
size`` pixels wide.  This module answers three questions, for any canvas size:

1. *How much of each pixel does one thread cover?*  (:func:`footprints`)
   A thread is a band of width ``width_px`` centred on the straight line
   between its pins.  A pixel's share is the band integrated across the
   thread against a smooth pixel-sized filter (the quadratic B-spline, 3
   pixels wide) of the distance from the pixel's centre to the line.  So the coverage is
   anti-aliased, depends on the distance from the line alone (never on the
   thread's direction), and adds up to the thread's width per unit of length
   in every direction: one thread of width 0.3 px darkens, summed across it,
   0.3 pixels' worth per pixel of length whether it runs along a row or at 45
   degrees.  (A Bresenham line counts a 45-degree thread 29 % lighter.)
2. *How dark is a pixel under many threads?*  (:func:`saturate`)
   The coverages add up and the total is capped at 1: two threads on the same
   spot are not twice as dark as one that covers it already.
3. *What does the piece look like?*  (:func:`composite`)
   The board shows through what the threads leave uncovered:
   ``board * (1 - coverage) + thread * coverage``, per channel.

Coordinates: pin positions are normalised to the frame's square (``x`` right,
``y`` down, in [0, 1], as in a plan's ``pin_xy``); pixel ``(r, c)`` of a
``size x size`` canvas covers ``[c / size, (c + 1) / size] x [r / size,
(r + 1) / size]`` of that square (the picture's crop is resampled the same
way), so its centre is at ``((c + 0.5) / size, (r + 0.5) / size)``.

Typical use::

    from stringbot.planner.model.thread import ThreadModel, coverage, composite
    model = ThreadModel(diameter_mm=500, thread_mm=0.25)
    cov = coverage(plan.chord_list(), plan.pin_xy, size=1001, width_px=model.width_px(1001))
    gray = composite(cov, board=1.0, thread=0.0)          # as woven, black thread on white
    rgb = composite(cov, board=(0.95, 0.93, 0.88), thread=(0.6, 0.1, 0.1))   # red on linen

A colour planner can keep one coverage per thread colour and composite them in
winding order (a later thread covers an earlier one where they cross).
"""

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ThreadModel", "footprints", "SegmentStamp", "coverage", "saturate", "composite", "DEFAULT_DIAMETER_MM",
           "DEFAULT_THREAD_MM"]

DEFAULT_DIAMETER_MM = 500.0
DEFAULT_THREAD_MM = 0.25
_CHUNK = 3_000_000  # footprint entries per vectorised chunk: bounds the temporaries (~100 MB)


@dataclass(frozen=True)
class ThreadModel:
    """A frame and its thread, in millimetres.

    Parameters
    ----------
    diameter_mm : float
        Diameter of the pin circle (the side of a square frame), > 0.
    thread_mm : float
        Width of the thread, > 0 and less than the diameter.
    """

    diameter_mm: float = DEFAULT_DIAMETER_MM
    thread_mm: float = DEFAULT_THREAD_MM

    def __post_init__(self):
        for name in ("diameter_mm", "thread_mm"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} {v!r}; expected a number > 0")
        if self.thread_mm >= self.diameter_mm:
            raise ValueError(f"thread_mm {self.thread_mm} is not less than diameter_mm {self.diameter_mm}")

    @property
    def fraction(self):
        """Thread width as a fraction of the frame's diameter."""
        return self.thread_mm / self.diameter_mm

    def width_px(self, size):
        """Thread width in pixels on a ``size x size`` canvas spanning the frame."""
        return self.fraction * float(size)


def _kernel_cdf(x):
    """Integral from -inf to ``x`` of the pixel filter across a thread: the quadratic B-spline.

    It has unit area and a support of 3 pixels; its shifts by whole pixels add up
    to 1 (a thread along a row gives exactly its width per column) and, sampled
    at any spacing down to a diagonal's 0.71 pixel, they add up to within 0.2 %
    of the mean (a tent would ripple by 10 %), so no direction is favoured.
    """
    x = np.clip(x, -1.5, 1.5)
    mid = 1.0 / 6.0 + 0.75 * (x + 0.5) - (x ** 3 + 0.125) / 3.0
    return np.where(x < -0.5, (x + 1.5) ** 3 / 6.0, np.where(x > 0.5, 1.0 - (1.5 - x) ** 3 / 6.0, mid))


_LUT_STEP = 1.0 / 2048.0  # pixels: the coverage-by-distance table is exact to well under 0.1 %


def _profile(width_px):
    """Coverage of a pixel by a thread of ``width_px`` as a function of the pixel's distance to its line.

    Returns ``(table, reach)``: ``table[int(d / _LUT_STEP)]`` for ``d < reach``.
    """
    w = float(width_px)
    reach = 1.5 + w / 2.0  # beyond this distance from the line a pixel gets nothing
    d = np.arange(int(math.ceil(reach / _LUT_STEP)) + 2, dtype=np.float64) * _LUT_STEP + _LUT_STEP / 2
    table = np.minimum(_kernel_cdf(d + w / 2.0) - _kernel_cdf(d - w / 2.0), 1.0)
    table[-2:] = 0.0
    return table.astype(np.float32), reach


def _chunks(xy0, xy1, size, width_px, *, with_seg=True):
    """Footprints in chunks of arrays ``(seg, flat, cover)``; entries with ``cover == 0`` included.

    ``with_seg=False``: ``seg`` is None (a drawing needs no thread numbers).
    """
    w = float(width_px)
    if not (math.isfinite(w) and w > 0):
        raise ValueError(f"width_px {width_px!r}; expected a number > 0")
    xy0 = np.atleast_2d(np.asarray(xy0, dtype=np.float64)) * size - 0.5
    xy1 = np.atleast_2d(np.asarray(xy1, dtype=np.float64)) * size - 0.5
    dx, dy = xy1[:, 0] - xy0[:, 0], xy1[:, 1] - xy0[:, 1]
    xmajor = np.abs(dx) >= np.abs(dy)
    a0 = np.where(xmajor, xy0[:, 0], xy0[:, 1])
    a1 = np.where(xmajor, xy1[:, 0], xy1[:, 1])
    b0 = np.where(xmajor, xy0[:, 1], xy0[:, 0])
    b1 = np.where(xmajor, xy1[:, 1], xy1[:, 0])
    swap = a1 < a0
    a0, a1 = np.where(swap, a1, a0), np.where(swap, a0, a1)
    b0, b1 = np.where(swap, b1, b0), np.where(swap, b0, b1)
    slope = (b1 - b0) / np.maximum(a1 - a0, 1e-12)
    scale = (1.0 / np.sqrt(1.0 + slope * slope)) / _LUT_STEP  # minor-axis distance -> table index
    table, reach = _profile(w)
    top = len(table) - 1
    K = int(math.ceil(reach * math.sqrt(2.0)))
    offsets = np.arange(-K + 1, K + 1, dtype=np.float32)
    lo = np.clip(np.ceil(a0), 0, size - 1)
    hi = np.clip(np.floor(a1), 0, size - 1)
    n = np.where((hi >= lo) & (a1 >= 0) & (a0 <= size - 1), hi - lo + 1, 0).astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(n)])
    # strides of the major and minor axes in flat indices
    smaj = np.where(xmajor, 1, size).astype(np.int64)
    smin = np.where(xmajor, size, 1).astype(np.int64)
    k, a = len(n), 0
    per = max(1, _CHUNK // len(offsets))
    while a < k:
        b = int(np.searchsorted(starts, starts[a] + per, side="right")) - 1
        b = min(max(b, a + 1), k)
        cnt = n[a:b]
        total = int(cnt.sum())
        if total:
            seg = np.repeat(np.arange(a, b, dtype=np.int32), cnt)
            t = (np.arange(total, dtype=np.int64) - np.repeat(starts[a:b] - starts[a], cnt)) + lo[seg].astype(np.int64)
            m = (b0[seg] + (t - a0[seg]) * slope[seg]).astype(np.float32)
            base = np.floor(m)
            frac = m - base  # in [0, 1)
            mp = base[:, None] + offsets[None, :]  # candidate minor coordinates
            idx = (np.abs(offsets[None, :] - frac[:, None]) * scale[seg].astype(np.float32)[:, None]).astype(np.int64)
            cov = table[np.minimum(idx, top)]
            cov[(mp < 0) | (mp > size - 1)] = 0.0
            mpi = np.clip(mp, 0, size - 1).astype(np.int64)
            flat = (t * smaj[seg])[:, None] + mpi * smin[seg][:, None]
            if with_seg:
                yield np.broadcast_to(seg[:, None], mp.shape).ravel(), flat.ravel().astype(np.int32), cov.ravel()
            else:  # flat as it is (np.bincount wants it so)
                yield None, flat.ravel(), cov.ravel()
        a = b


class SegmentStamp:
    """Footprints of single threads one at a time, fast: for planners that add threads one by one.

    Parameters
    ----------
    size : int
        Canvas side in pixels.
    width_px : float
        Thread width in pixels.

    Calling ``stamp(xy0, xy1)`` gives ``(flat, cover)`` as :func:`footprints`
    does for one thread (each pixel once, ``flat`` int64, ``cover`` float64).
    """

    def __init__(self, size, width_px):
        self.size = int(size)
        self.table, reach = _profile(width_px)
        self.top = len(self.table) - 1
        K = int(math.ceil(reach * math.sqrt(2.0)))
        self.offsets = np.arange(-K + 1, K + 1, dtype=np.float64)

    def __call__(self, xy0, xy1, *, compact=False):
        """``(flat, cover)`` of the thread from ``xy0`` to ``xy1``; ``compact``: ``flat`` int32 and
        ``cover`` float32 (the same values)."""
        n1 = self.size - 1
        x0, y0 = xy0[0] * self.size - 0.5, xy0[1] * self.size - 0.5
        x1, y1 = xy1[0] * self.size - 0.5, xy1[1] * self.size - 0.5
        if abs(x1 - x0) >= abs(y1 - y0):
            a0, a1, b0, b1, smaj, smin = x0, x1, y0, y1, 1, self.size
        else:
            a0, a1, b0, b1, smaj, smin = y0, y1, x0, x1, self.size, 1
        if a1 < a0:
            a0, a1, b0, b1 = a1, a0, b1, b0
        slope = (b1 - b0) / max(a1 - a0, 1e-12)
        scale = 1.0 / math.sqrt(1.0 + slope * slope) / _LUT_STEP
        lo, hi = max(math.ceil(a0), 0), min(math.floor(a1), n1)
        if hi < lo:
            return (np.zeros(0, np.int32), np.zeros(0, np.float32)) if compact else (np.zeros(0, np.int64), np.zeros(0))
        t = np.arange(lo, hi + 1, dtype=np.float64)
        m = b0 + (t - a0) * slope
        base = np.floor(m)
        mp = base[:, None] + self.offsets
        d = mp - m[:, None]
        np.abs(d, out=d)
        d *= scale
        idx = d.astype(np.int64)
        np.minimum(idx, self.top, out=idx)
        cov = self.table[idx]
        ok = cov > 0
        first, last = self.offsets[0], self.offsets[-1]
        if min(base[0], base[-1]) + first < 0 or max(base[0], base[-1]) + last > n1:  # near the edge
            ok &= (mp >= 0) & (mp <= n1)
        mp *= smin
        mp += (t * smaj)[:, None]
        if compact:
            return mp[ok].astype(np.int32), cov[ok]
        return mp[ok].astype(np.int64), cov[ok].astype(np.float64)


def footprints(xy0, xy1, size, width_px):
    """The pixels each thread covers and by how much.

    Parameters
    ----------
    xy0, xy1 : array_like of float, shape (k, 2)
        Thread ends, normalised ``(x, y)`` in the frame's square (see the module notes).
    size : int
        Canvas side in pixels.
    width_px : float
        Thread width in pixels, > 0.

    Returns
    -------
    seg : ndarray of int32, shape (n,)
        Which thread (0..k-1) each entry belongs to, in non-decreasing order.
    flat : ndarray of int32, shape (n,)
        Flat pixel index ``row * size + col``.
    cover : ndarray of float32, shape (n,)
        The share of that pixel the thread covers, in (0, 1].  A pixel appears
        once per thread (twice at most where a thread ends on a pixel's edge).
    """
    parts = [(s[c > 0], f[c > 0], c[c > 0]) for s, f, c in _chunks(xy0, xy1, size, width_px)]
    if not parts:
        return np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0, np.float32)
    return tuple(np.concatenate(x) for x in zip(*parts))


def saturate(total):
    """Coverage of a pixel under threads whose coverages add up to ``total``: capped at 1."""
    return np.minimum(total, 1.0)


def coverage(chords, pin_xy, *, size, width_px, saturated=True):
    """Coverage of a chord set on a ``size x size`` canvas.

    Parameters
    ----------
    chords : sequence of (int, int)
        Pin pairs.
    pin_xy : array_like of float, shape (pins, 2)
        Normalised pin positions (a plan's ``pin_xy``).
    size : int
    width_px : float
        Thread width in pixels (:meth:`ThreadModel.width_px`).
    saturated : bool
        Cap the summed coverage at 1 (:func:`saturate`); False returns the sum.

    Returns
    -------
    ndarray of float32, shape (size, size)
        0 where no thread passes, 1 where the board is hidden.
    """
    total = np.zeros(size * size, dtype=np.float64)
    c = np.asarray(chords, dtype=np.int64).reshape(-1, 2)
    xy = np.asarray(pin_xy, dtype=np.float64)
    if len(c):
        for _, flat, cov in _chunks(xy[c[:, 0]], xy[c[:, 1]], size, width_px, with_seg=False):
            total += np.bincount(flat, weights=cov, minlength=size * size)
    total = total.reshape(size, size).astype(np.float32)
    return saturate(total) if saturated else total


def composite(cov, *, board=1.0, thread=0.0):
    """What the piece looks like: the board showing through the uncovered part of each pixel.

    Parameters
    ----------
    cov : ndarray of float, shape (h, w)
        Coverage in [0, 1] (:func:`coverage`).
    board, thread : float or sequence of float
        Gray levels, or colours (one value per channel), in the units wanted
        out (0..1 or 0..255).

    Returns
    -------
    ndarray of float32, shape (h, w) or (h, w, channels)
        ``board * (1 - cov) + thread * cov``.
    """
    cov = np.clip(np.asarray(cov, dtype=np.float32), 0.0, 1.0)
    board, thread = np.asarray(board, dtype=np.float32), np.asarray(thread, dtype=np.float32)
    if board.ndim or thread.ndim:
        cov = cov[..., None]
    return board * (1.0 - cov) + thread * cov
