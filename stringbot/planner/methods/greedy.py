"""The greedy baseline the paper compares with: ThreadTone as published.

ThreadTone (theveloped/ThreadTone, ``threadTone.py``) works like this, and so
does this module:

* The gray picture is reversed (``255 - gray``) and is 0 outside the frame.
* From the current pin, each chord's *line sum* is the sum of the picture at
  ``int(hypot(dx, dy))`` points spaced evenly from pin to pin (ThreadTone's
  ``linePixels``: ``np.linspace`` with as many points as the chord is long in
  pixels; :mod:`stringbot.planner.model.lines`).  The count of points is proportional to the chord's length in
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

from ..model.lines import PinLines

log = logging.getLogger(__name__)

__all__ = ["greedy_sequence", "plan_greedy", "band_pixels", "cv_half_width"]


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
    pins = PinLines(space, size)
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
    stats = {}
    if len(seq) - 1 < int(job.lines):
        stats["stopped"] = (f"no chord from pin {seq[-1]} darkens what is left of the picture; "
                            "ask for fewer --lines, or a picture with more dark parts")
    return seq, dict(gk, weight_at_size=round(gk["weight"] * scale, 4)), stats
