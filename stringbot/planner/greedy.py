"""The greedy baseline the paper compares with (ThreadTone, its original implementation).

The gray image is reversed (``255 - gray``, 0 outside the frame).  From the
current pin, the chord whose pixels have the largest sum is drawn, the
picture is lowered by ``weight`` (15 of 255) along it on a ``width``-pixel
line (3), and the next step starts from its far pin.  The last ``min_loop``
pins of the sequence (3, the current one included) are never gone back to.
The run stops early when no chord has a positive sum.

ThreadTone works on a picture of radius ``reference_radius`` = 500 pixels
(its ``imgRadius``); its 15-on-3-pixels is the darkness of one thread *at
that scale*.  On a working picture of radius ``R`` the removed line keeps
its 3-pixel width and its weight is scaled by ``R / 500``, so that one
thread removes the same share of the picture as in ThreadTone (at 401 px,
6 of 255).  Without this, a thread would remove 2.5 times too much darkness
and the run would stop after about 70 % of the lines.
"""

import logging

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["greedy_sequence"]


class _PinChords:
    """Per-pin concatenation of the pixels of all chords from that pin, built lazily."""

    def __init__(self, space, indptr, indices):
        self.space, self.indptr, self.indices = space, indptr, indices
        self.cache = {}

    def get(self, p):
        if p not in self.cache:
            row = self.space.index[p]
            others = np.flatnonzero(row >= 0)
            chords = row[others]
            lo, hi = self.indptr[chords], self.indptr[chords + 1]
            counts = hi - lo
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            pos = np.arange(counts.sum()) - np.repeat(starts - lo, counts)
            pix = self.indices[pos]
            self.cache[p] = (others, pix, starts)
        return self.cache[p]


def _thick(space, size, indptr, indices, chord, width):
    """Flat pixels of a ``width``-pixel-wide line along ``chord`` (offsets across its minor axis)."""
    pix = indices[indptr[chord]:indptr[chord + 1]].astype(np.int64)
    i, j = space.ends[chord]
    dx, dy = space.pin_xy[j] - space.pin_xy[i]
    r, c = pix // size, pix % size
    half = (int(width) - 1) // 2
    rs, cs = [], []
    for o in range(-half, int(width) - half):
        if abs(dx) >= abs(dy):  # mostly horizontal: widen along rows
            rs.append(r + o); cs.append(c)
        else:
            rs.append(r); cs.append(c + o)
    r, c = np.concatenate(rs), np.concatenate(cs)
    ok = (r >= 0) & (r < size) & (c >= 0) & (c < size)
    return r[ok] * size + c[ok]


def greedy_sequence(space, size, indptr, indices, gray, mask, lines, *, start_pin=0,
                    weight=15.0, width=3, min_loop=3, reference_radius=500.0):
    """ThreadTone's greedy pin sequence.

    Parameters
    ----------
    space : ChordSpace
    size : int
    indptr, indices : ndarray
        Chord pixels.
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
        Width in pixels of the removed line.
    min_loop : int
        The last ``min_loop`` pins are excluded.
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
    work = np.where(mask, 255.0 - np.asarray(gray, dtype=np.float32), 0.0).astype(np.float32).ravel()
    pins = _PinChords(space, indptr, indices)
    seq = [int(start_pin)]
    cur = int(start_pin)
    for _ in range(int(lines)):
        others, pix, starts = pins.get(cur)
        if not len(others):
            break
        sums = np.add.reduceat(work.take(pix), starts)  # every chord has >= 1 pixel
        for q in seq[-min_loop:]:
            k = int(np.searchsorted(others, q))
            if k < len(others) and others[k] == q:
                sums[k] = -np.inf
        k = int(np.argmax(sums))
        if not sums[k] > 0:
            log.info("greedy: no chord from pin %d has a positive sum; stopping after %d lines",
                     cur, len(seq) - 1)
            break
        nxt = int(others[k])
        chord = int(space.index[cur, nxt])
        work[_thick(space, size, indptr, indices, chord, width)] -= weight
        seq.append(nxt)
        cur = nxt
    return seq
