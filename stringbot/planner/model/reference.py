"""The reference rendering: a plan as it will hang, converged, with no model in between.

Every thread is a band of its real width with a sharp edge, centred on the
straight line between its two pins.  A point of the board is covered when it
lies in any band (the union: two threads on one spot are as dark as one,
two side by side twice as dark, a chord drawn twice no darker than once).
An output pixel's coverage is the share of its area that is covered.

That share is measured by sampling: the union is tested exactly (the
distance from a sample to each thread's line) at the centres of a fine
canvas ``k`` times the output's side, at least :data:`SAMPLES_PER_WIDTH`
samples across one thread, and the samples are box-filtered (averaged per
``k x k`` block) to the output.  A point sample is an unbiased estimate of
an area whatever the resolution, so the mean converges fast: doubling the
fine canvas changes the mean lightness of a real plan by well under 0.002
(``tests/test_reference.py``; docs/planner.md, "The reference rendering").

The fine canvas is never held whole: it is drawn in strips of rows (about
:data:`STRIP_SAMPLES` samples each), each thread a run of samples per
column (threads nearer horizontal) or per row (nearer vertical), marked by
differences and summed along the run, so memory stays bounded whatever the
size and the time grows with the threads' length in fine pixels.

This is what ``stringbot render``, the preview of ``stringbot plan``,
``stringbot score`` and the benchmarks draw (:func:`reference_coverage`).
"""

import math

import numpy as np

__all__ = ["reference_coverage", "reference_shares", "reference_gray", "thread_samples", "fine_factor", "SAMPLES_PER_WIDTH",
           "STRIP_SAMPLES"]

#: samples across one thread's width (at least): the thread 4 fine pixels wide
SAMPLES_PER_WIDTH = 4.0
#: at least this many samples per output pixel's side (the box filter's anti-aliasing)
MIN_FACTOR = 4
#: samples of the fine canvas per strip: bounds the memory (a strip's arrays are about 20 bytes a sample)
STRIP_SAMPLES = 1 << 21


def fine_factor(size, thread_fraction, *, samples=SAMPLES_PER_WIDTH):
    """Fine samples per output pixel's side: a thread ``thread_fraction`` of the frame wide is at least
    ``samples`` fine pixels wide (and at least :data:`MIN_FACTOR` samples a side)."""
    w = float(thread_fraction) * int(size)  # thread width in output pixels
    if not (math.isfinite(w) and w > 0):
        raise ValueError(f"thread_fraction {thread_fraction!r}; expected a number > 0")
    return max(MIN_FACTOR, int(math.ceil(float(samples) / w - 1e-9)))


def _lines(chords, pin_xy, F):
    """The chords on the fine canvas, split by their major axis.

    Returns two tuples ``(a0, a1, b0, slope)``, one for threads nearer
    horizontal (major axis x: a run of rows per column) and one for those
    nearer vertical (major axis y: a run of columns per row), in fine pixels,
    ``a0 <= a1``: the major coordinate runs from ``a0`` to ``a1`` and the minor
    one is ``b0 + (a - a0) slope`` there.
    """
    c = np.asarray(chords, dtype=np.int64).reshape(-1, 2)
    xy = np.asarray(pin_xy, dtype=np.float64) * F
    p, q = xy[c[:, 0]], xy[c[:, 1]]
    dx, dy = q[:, 0] - p[:, 0], q[:, 1] - p[:, 1]
    out = []
    for major, ia, ib in ((np.abs(dx) >= np.abs(dy), 0, 1), (np.abs(dx) < np.abs(dy), 1, 0)):
        a0, a1 = p[major, ia], q[major, ia]
        b0, b1 = p[major, ib], q[major, ib]
        swap = a1 < a0
        a0, a1 = np.where(swap, a1, a0), np.where(swap, a0, a1)
        b0, b1 = np.where(swap, b1, b0), np.where(swap, b0, b1)
        slope = (b1 - b0) / np.maximum(a1 - a0, 1e-12)
        out.append((a0, a1, b0, slope))
    return out


def _runs(line, half, major, minor):
    """The runs of covered samples of threads ``line`` within ``major = (lo, hi)`` whose centre is near
    ``minor = (lo, hi)``.

    A sample at fine pixel ``(a, b)`` (centre ``(a + 0.5, b + 0.5)``) is covered
    when its distance to the thread's line is at most ``half`` and its major
    coordinate is within the thread's ends.  Returns ``(a, start, length)``: for
    each major index ``a`` a run of minor indices ``start <= b < start + length``
    (not clipped: a run reaches at most ``2 half sqrt(2) + 3`` beyond the
    minor range; ``length`` may be 0).
    """
    a0, a1, b0, slope = line
    lo, hi = minor
    empty = np.zeros(0, np.int64)
    if not len(a0):
        return empty, empty, empty
    hh = half * np.sqrt(1.0 + slope * slope)  # half the band's extent along the minor axis
    # major indices whose centre is within the thread's ends, and whose run's centre
    # m(a) = b0 + (a + 0.5 - a0) slope lies within [lo - 1.5 - hh, hi + 1.5 + hh]
    first = np.maximum(np.ceil(a0 - 0.5), float(major[0]))
    last = np.minimum(np.floor(a1 - 0.5), major[1] - 1.0)
    lo_m, hi_m = lo - 1.5 - hh, hi + 1.5 + hh
    flat = np.abs(slope) < 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = np.where(flat, 0.0, (lo_m - b0) / np.where(flat, 1.0, slope)) + a0 - 0.5
        tb = np.where(flat, 0.0, (hi_m - b0) / np.where(flat, 1.0, slope)) + a0 - 0.5
    inside = (b0 >= lo_m) & (b0 <= hi_m)
    first = np.where(flat, np.where(inside, first, np.inf), np.maximum(first, np.floor(np.minimum(ta, tb))))
    last = np.where(flat, last, np.minimum(last, np.ceil(np.maximum(ta, tb))))
    keep = last >= first
    if not keep.any():
        return empty, empty, empty
    first, last = first[keep], last[keep]
    n = (last - first + 1).astype(np.int64)
    slope, hh = slope[keep], hh[keep]
    c0 = b0[keep] + (0.5 - a0[keep]) * slope  # m(a) = c0 + a slope
    seg = np.repeat(np.arange(len(n)), n)
    a = np.arange(int(n.sum()), dtype=np.int64)
    a += np.repeat(first.astype(np.int64) - (np.cumsum(n) - n), n)
    m = a * slope[seg]
    m += c0[seg]
    start = np.ceil(m - (hh + 0.5)[seg])
    length = np.floor(m + (hh - 0.5)[seg])
    length -= start
    length += 1.0
    return a, start.astype(np.int64), length.astype(np.int64)


def _mark(cov, start, length, step, value=1):
    """Set ``cov[start + i * step] = value`` for ``0 <= i < length`` of every run."""
    if not len(start):
        return
    start = start[length > 0]
    length = length[length > 0]
    if not len(start):
        return
    short, longest = int(length.min()), int(length.max())
    idx = start.copy()
    for _ in range(short):
        cov[idx] = value
        idx += step
    for i in range(short, longest):  # the longer runs (of steeper threads, or a sample more)
        more = length > i
        cov[start[more] + i * step] = value


def thread_samples(xy0, xy1, F, half):
    """The samples one thread covers on a whole ``F x F`` fine canvas, by the test the reference
    rendering makes: flat indices ``row * F + col`` (int32, each once).

    Parameters
    ----------
    xy0, xy1 : array_like of float, shape (2,)
        The thread's ends, normalised (``x`` right, ``y`` down, in [0, 1]).
    F : int
        Side of the canvas in samples.
    half : float
        Half the thread's width in samples.
    """
    (xmaj, ymaj) = _lines([(0, 1)], np.array([xy0, xy1], dtype=np.float64), F)
    if len(xmaj[0]):
        a, start, n = _runs(xmaj, half, (0, F), (0, F))
        stride, step = 1, F  # a run of rows in column a
    else:
        a, start, n = _runs(ymaj, half, (0, F), (0, F))
        stride, step = F, 1  # a run of columns in row a
    if not len(a):
        return np.zeros(0, np.int32)
    top = int(n.max(initial=0))
    off = np.arange(top, dtype=np.int64)
    minor = start[:, None] + off[None, :]
    ok = (off[None, :] < n[:, None]) & (minor >= 0) & (minor < F)
    flat = a[:, None] * stride + minor * step
    return flat[ok].astype(np.int32)


def reference_coverage(chords, pin_xy, *, size, thread_fraction, samples=SAMPLES_PER_WIDTH, factor=None, rows=None):
    """The share of each output pixel the threads cover (their union), converged.

    Parameters
    ----------
    chords : sequence of (int, int)
        Pin pairs (a chord drawn twice is no darker than once).
    pin_xy : array_like of float, shape (pins, 2)
        Normalised pin positions (``x`` right, ``y`` down, in [0, 1]; a plan's ``pin_xy``).
    size : int
        Side of the output in pixels (it spans the frame's square).
    thread_fraction : float
        The thread's width as a fraction of the frame's side (``thread_mm / diameter_mm``).
    samples : float
        Fine pixels across one thread, at least (:data:`SAMPLES_PER_WIDTH`).
    factor : int, optional
        Fine pixels per output pixel's side (default: :func:`fine_factor`).
    rows : (int, int), optional
        Only the output rows ``r0 <= r < r1`` (the same values as those rows of the whole).

    Returns
    -------
    ndarray of float32, shape (size, size), or (r1 - r0, size) with ``rows``
        0 where no thread passes, 1 where the board is hidden.
    """
    return reference_shares([chords], pin_xy, size=size, thread_fraction=thread_fraction, samples=samples,
                            factor=factor, rows=rows)[0]


def reference_shares(layers, pin_xy, *, size, thread_fraction, ids=None, samples=SAMPLES_PER_WIDTH, factor=None,
                     rows=None):
    """The share of each output pixel in which each kind of thread lies on top, converged.

    The layers lie in the order given, later ones on top: a sample shows the
    last layer whose thread covers it (a sharp, opaque thread hides what it
    covers), or the board.  ``ids`` names each layer's kind (a colour plan's
    thread colour: the layers of one colour, however far apart, share an id).

    Parameters
    ----------
    layers : sequence of sequence of (int, int)
        Each layer's chords, in winding order.
    pin_xy, size, thread_fraction, samples, factor, rows
        As for :func:`reference_coverage`.
    ids : sequence of int, optional
        The kind of each layer, 0..254 (default: each layer its own, ``0, 1, ...``).

    Returns
    -------
    ndarray of float32, shape (max(ids) + 1, size, size), or (.., r1 - r0, size) with ``rows``
        For each kind, the share of each pixel where it is on top; the board shows in ``1 - sum``.
    """
    size = int(size)
    ids = list(range(len(layers))) if ids is None else [int(i) for i in ids]
    if len(ids) != len(layers) or (ids and not 0 <= min(ids) <= max(ids) < 255):
        raise ValueError(f"ids {ids!r}; expected one id in 0..254 per layer")
    kinds = max(ids, default=-1) + 1
    k = int(factor) if factor is not None else fine_factor(size, thread_fraction, samples=samples)
    F = size * k
    half = float(thread_fraction) * F / 2.0
    lines = [_lines(chords, pin_xy, F) for chords in layers]
    hh = max([0.0] + [float(half * np.sqrt(1.0 + np.max(ln[3] ** 2))) for two in lines for ln in two if len(ln[3])])
    M = int(math.ceil(2.0 * hh)) + 4  # margin around a strip: where runs reach beyond it
    W = F + 2 * M
    first, end = (0, size) if rows is None else (max(0, int(rows[0])), min(size, int(rows[1])))
    out = np.zeros((kinds, max(0, end - first), size), dtype=np.float32)
    step = max(1, min(size, STRIP_SAMPLES // (F * k)))  # output rows per strip
    strip = np.zeros((step * k + 2 * M) * W, dtype=np.uint8)
    inv = np.float32(1.0 / (k * k))
    for r0 in range(first, end, step):
        r1 = min(end, r0 + step)
        lo, hi = r0 * k, r1 * k
        R = hi - lo
        cov = strip[:(R + 2 * M) * W]
        cov.fill(0)
        for (xmaj, ymaj), kind in zip(lines, ids):  # later layers overwrite earlier ones: they lie on top
            # threads nearer horizontal: per column a run of rows; nearer vertical: per row a run of columns
            col, s, n = _runs(xmaj, half, (0, F), (lo, hi))
            _mark(cov, (s + (M - lo)) * W + (col + M), n, W, kind + 1)
            row, s, n = _runs(ymaj, half, (lo, hi), (0, F))
            _mark(cov, (row + (M - lo)) * W + (s + M), n, 1, kind + 1)
        # the box filter: the mean of each k x k block of samples (the margin left out)
        inner = cov.reshape(R + 2 * M, W)[M:M + R, M:M + F]
        for kind in range(kinds):
            hit = inner > 0 if kinds == 1 else inner == kind + 1
            block = hit.reshape(r1 - r0, k, F).sum(axis=1, dtype=np.uint16)
            out[kind, r0 - first:r1 - first] = block.reshape(r1 - r0, size, k).sum(axis=2, dtype=np.uint32) * inv
    return out


def reference_gray(chords, pin_xy, *, size, thread_fraction, board=1.0, thread=0.0, **kw):
    """:func:`reference_coverage` composited: ``board * (1 - cov) + thread * cov`` (float32, 1 white)."""
    cov = reference_coverage(chords, pin_xy, size=size, thread_fraction=thread_fraction, **kw)
    return np.float32(board) * (1.0 - cov) + np.float32(thread) * cov
