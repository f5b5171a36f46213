"""The greedy baseline the paper compares with: ThreadTone as published.

ThreadTone (theveloped/ThreadTone, ``threadTone.py``) works like this, and so
does this module:

* The gray picture is reversed (``255 - gray``) and is 0 outside the frame.
* From the current pin, each chord's *line sum* is the sum of the picture at
  ``int(hypot(dx, dy))`` points spaced evenly from pin to pin (ThreadTone's
  ``linePixels``: ``np.linspace`` with as many points as the chord is long in
  pixels).  The count of points is proportional to the chord's length in
  every direction, so a diagonal chord is not under-counted as it would be
  with one point per step of its major axis.  (A point lands on the pixel
  nearest to it; ThreadTone truncates and shifts by one pixel, which only
  moves its lines by a pixel.)
* The chord with the largest positive sum is drawn; the pins of the last
  ``min_loop`` (3) chosen chords are never gone back to.  The run stops when
  no chord has a positive sum.
* The picture is lowered by ``weight`` (15 of 255) where ``cv2.line(...,
  thickness=3)`` draws: a band *perpendicular to the thread*, every pixel whose
  centre lies within 2 pixels of the chord (OpenCV offsets the sides of a
  thickness-3 line by 2 pixels and fills edges included; see
  :func:`cv_half_width`).  A chord may be drawn again later, as in ThreadTone.

ThreadTone works on a picture of radius ``reference_radius`` = 500 pixels
(its ``imgRadius``); its 15-on-3-pixels is the darkness of one thread *at
that scale*.  On a working picture of radius ``R`` the band keeps its 3-pixel
width and the weight is scaled by ``R / 500``, so that one thread removes the
same share of the picture as in ThreadTone (at 401 px, 6 of 255; at 1001 px,
15 exactly: ``--size 1001`` is ThreadTone's own resolution).
"""

import logging

import numpy as np

from ..model.chords import pin_pixels

log = logging.getLogger(__name__)

__all__ = ["greedy_sequence", "plan_greedy", "line_samples", "band_pixels", "cv_half_width"]


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
    n = np.maximum((np.hypot(dr, dc) / spacing).astype(np.int64), 1)
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


def cv_half_width(thickness):
    """Half-width of the band ``cv2.line`` fills for a thickness: ``t / 2``, plus 1/2 when ``t`` is odd.

    OpenCV's ``ThickLine`` offsets the polygon's sides by ``(t + (t & 1)) / 2``
    pixels from the line and fills it edges included, so ``thickness=3``
    lowers every pixel within 2 pixels of the thread (5 rows across a
    horizontal one), with round ends of the same radius.
    """
    return thickness / 2.0 + 0.5 * (int(thickness) & 1)


def band_pixels(r0, c0, r1, c1, size, half):
    """Flat pixels whose centres lie within ``half`` of the segment between two pixels (edges included).

    The band is perpendicular to the segment whatever its direction (as
    ``cv2.line`` draws a thick line), with round ends.
    """
    rlo, rhi = int(np.floor(min(r0, r1) - half)), int(np.ceil(max(r0, r1) + half))
    clo, chi = int(np.floor(min(c0, c1) - half)), int(np.ceil(max(c0, c1) + half))
    dr, dc = float(r1 - r0), float(c1 - c0)
    L2 = dr * dr + dc * dc
    steps = max(abs(dr), abs(dc))
    # walk the major axis; at each step the band spans a few pixels of the minor axis
    t = np.arange(-np.ceil(half) - 1, steps + np.ceil(half) + 2)
    k = np.arange(-int(np.ceil(half * 1.5)) - 1, int(np.ceil(half * 1.5)) + 2)
    if abs(dr) >= abs(dc):
        rr = r0 + np.sign(dr or 1.0) * t
        cc = c0 + (rr - r0) * (dc / dr if dr else 0.0)
        R = rr[:, None] + 0 * k[None, :]
        C = np.rint(cc)[:, None] + k[None, :]
    else:
        cc = c0 + np.sign(dc) * t
        rr = r0 + (cc - c0) * (dr / dc)
        C = cc[:, None] + 0 * k[None, :]
        R = np.rint(rr)[:, None] + k[None, :]
    R, C = R.ravel(), C.ravel()
    # distance from each pixel centre to the segment
    u = np.clip(((R - r0) * dr + (C - c0) * dc) / max(L2, 1e-12), 0.0, 1.0)
    d2 = (R - r0 - u * dr) ** 2 + (C - c0 - u * dc) ** 2
    # OpenCV fills the band's polygon row by row, rounding to the nearest pixel, and draws its sides
    # with Bresenham lines: a pixel counts when it lies within half a pixel, along the axis most
    # across the thread, of the band: within half + max(|n_row|, |n_col|) / 2 of the line
    tol = half + 0.5 * max(abs(dr), abs(dc)) / max(np.sqrt(L2), 1e-12)
    ok = (d2 <= tol * tol + 1e-9) & (R >= max(rlo, 0)) & (R <= min(rhi, size - 1)) \
        & (C >= max(clo, 0)) & (C <= min(chi, size - 1))
    flat = np.unique(R[ok].astype(np.int64) * size + C[ok].astype(np.int64))
    return flat


class _PinLines:
    """Per pin, the line points of every chord from it, built the first time the pin is visited.

    ``nearest``: points on their nearest pixel (else truncated, as ThreadTone does); ``spacing``:
    pixels between points (1: ThreadTone's); ``keep``: False builds them again each time (for a caller
    that keeps them itself).
    """

    def __init__(self, space, size, *, nearest=False, spacing=1.0, keep=True):
        self.space, self.size, self.nearest, self.spacing, self.keep = space, size, nearest, spacing, keep
        if nearest:
            self.rc = pin_pixels(space.pin_xy, size)
        else:  # ThreadTone truncates its pin coordinates: int(r + 1 + r cos a), sampled one pixel lower
            self.rc = np.clip(np.floor(np.asarray(space.pin_xy)[:, ::-1] * (size - 1) + 1e-9), 0,
                              size - 1).astype(np.int64)
        self.cache = {}

    def get_with_counts(self, p):
        """``(others, flat, starts, counts)``: the pins reachable from ``p`` and their chords' points."""
        row = self.cache.get(p)
        if row is None:
            others = np.flatnonzero(self.space.index[p] >= 0)
            r0, c0 = self.rc[p]
            starts, flat = line_samples(r0, c0, self.rc[others, 0], self.rc[others, 1], self.size,
                                        nearest=self.nearest, spacing=self.spacing)
            counts = np.diff(np.append(starts, len(flat))).astype(np.float32)
            row = (others, flat, starts, counts)
            if self.keep:
                self.cache[p] = row
        return row

    def get(self, p):
        return self.get_with_counts(p)[:3]


def greedy_sequence(space, size, gray, mask, lines, *, start_pin=0, weight=15.0, width=3, min_loop=3,
                    reference_radius=500.0):
    """ThreadTone's greedy pin sequence (see the module notes).

    Parameters
    ----------
    space : ChordSpace
    size : int
    gray : ndarray of float, shape (size, size)
        Gray levels in [0, 255].
    mask : ndarray of bool, shape (size, size)
        Pixels inside the frame.
    lines : int
        Upper bound on the number of chords.
    start_pin : int
    weight : float
        Darkness removed along a drawn chord, at ``reference_radius``.
    width : int
        ``cv2.line`` thickness of the band lowered along a drawn chord (see :func:`cv_half_width`).
    min_loop : int
        The pins of the last ``min_loop`` chosen chords are excluded.
    reference_radius : float or None
        Picture radius at which ``weight`` holds (ThreadTone's 500); the
        weight used is ``weight * R / reference_radius`` with ``R = (size - 1) / 2``.
        None: use ``weight`` as it is.

    Returns
    -------
    list of int
    """
    if reference_radius:
        weight = weight * ((size - 1) / 2.0) / float(reference_radius)
    half = cv_half_width(width)
    work = np.where(mask, 255.0 - np.asarray(gray, dtype=np.float32), 0.0).astype(np.float32).ravel()
    pins = _PinLines(space, size)
    rc = pins.rc
    seq = [int(start_pin)]
    cur = int(start_pin)
    for _ in range(int(lines)):
        others, pix, starts = pins.get(cur)
        if not len(others):
            break
        sums = np.add.reduceat(work.take(pix), starts)  # every chord has >= 1 point
        for q in seq[1:][-min_loop:]:  # ThreadTone's previousPins: the last chosen pins
            k = int(np.searchsorted(others, q))
            if k < len(others) and others[k] == q:
                sums[k] = -np.inf
        k = int(np.argmax(sums))
        if not sums[k] > 0:
            log.info("greedy: no chord from pin %d has a positive sum; stopping after %d lines",
                     cur, len(seq) - 1)
            break
        nxt = int(others[k])
        work[band_pixels(rc[cur, 0] + 1, rc[cur, 1] + 1, rc[nxt, 0] + 1, rc[nxt, 1] + 1, size, half)] -= weight
        seq.append(nxt)
        cur = nxt
    return seq


def plan_greedy(job):
    """``--method greedy`` through the methods' contract (:mod:`stringbot.planner.methods`):
    ThreadTone's weight of 15 on its 500-px radius, scaled to the working size."""
    from ..progress import report

    size = job.picture.gray.shape[0]
    radius = job.knobs["greedy_reference_radius"]
    gk = {"weight": job.knobs["greedy_weight"], "width": job.knobs["greedy_width"],
          "min_loop": job.knobs["greedy_min_loop"], "reference_radius": radius}
    scale = (size - 1) / 2 / radius if radius else 1.0
    report("greedy")
    seq = greedy_sequence(job.space, size, job.picture.gray, job.mask, job.lines, start_pin=job.start_pin, **gk)
    return seq, dict(gk, weight_at_size=round(gk["weight"] * scale, 4)), {}
