"""Chord sampling with error diffusion (section 3.3 and the disconnected variant of 4.1).

The fitness is mapped to [0, 1] by ``f <- (tanh(f / T) + 1) / 2`` and kept
in a symmetric ``pins x pins`` table.  Choosing chord ``l`` creates the error
``1 - f_l``, spread evenly over the other members of its epsilon-neighbourhood
(the paper's chord distance: L-infinity in pin-index space, with
``(i, j) ~ (j, i)`` and wrap-around): each loses ``(1 - f_l) / (|N| - 1)``.

Connected: from the current pin take the unused chord of highest fitness.
A chord is used at most once: once drawn it leaves the table.  If every chord
from the current pin has been used the sequence stops early (the plan's
``stats.lines`` says how many were drawn).  A chord always joins two different
pins, so no pin comes twice in a row.

Disconnected: a priority queue (a heap with lazy updates; values only fall)
gives the best unused chord anywhere.
"""

import heapq
import logging

import numpy as np

from ..model.chords import neighbour_offsets
from ..progress import report

log = logging.getLogger(__name__)

__all__ = ["fitness_table", "sample_connected", "sample_disconnected"]


def fitness_table(space, f, *, T):
    """The symmetric table of mapped fitness.

    Parameters
    ----------
    space : ChordSpace
    f : ndarray of float, shape (m,)
        Raw fitness from the solve.
    T : float
        Sharpness; ``(tanh(f / T) + 1) / 2``.

    Returns
    -------
    ndarray of float64, shape (pins, pins)
        ``-inf`` where there is no chord (diagonal, sides of a square).
    """
    P = space.pins
    table = np.full((P, P), -np.inf)
    mapped = 0.5 * (np.tanh(np.asarray(f, dtype=np.float64) / float(T)) + 1.0)
    i, j = space.ends[:, 0], space.ends[:, 1]
    table[i, j] = mapped
    table[j, i] = mapped
    return table


class _Diffuser:
    """Spreads the error of a chosen chord over its epsilon-neighbourhood."""

    def __init__(self, space, epsilon):
        self.P = space.pins
        self.valid = space.index >= 0
        self.offsets = neighbour_offsets(epsilon)

    def neighbours(self, i, j):
        """Other chords of the neighbourhood of ``{i, j}``: arrays (a, b), a < b."""
        P = self.P
        a = (i + self.offsets[:, 0]) % P
        b = (j + self.offsets[:, 1]) % P
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        key = np.unique(lo * P + hi)
        lo, hi = key // P, key % P
        keep = (lo != hi) & self.valid[lo, hi]
        lo, hi = lo[keep], hi[keep]
        size = len(lo)  # |N|, the chord itself included
        other = ~((lo == min(i, j)) & (hi == max(i, j)))
        return lo[other], hi[other], size

    def spread(self, table, i, j, value):
        lo, hi, size = self.neighbours(i, j)
        if size > 1:
            delta = (1.0 - value) / (size - 1)
            table[lo, hi] -= delta
            table[hi, lo] -= delta
        return lo, hi


def sample_connected(space, table, lines, *, epsilon=2, start_pin=0):
    """Connected sampling: a pin sequence of up to ``lines`` chords.

    Parameters
    ----------
    space : ChordSpace
    table : ndarray of float, shape (pins, pins)
        From :func:`fitness_table`; modified in place.
    lines : int
    epsilon : int
    start_pin : int

    Returns
    -------
    list of int
        ``lines + 1`` pins (fewer if the sequence ran out of unused chords).
    """
    diff = _Diffuser(space, epsilon)
    seq = [int(start_pin)]
    cur = int(start_pin)
    for n in range(int(lines)):
        if n % 200 == 0:
            report("sampling", n, int(lines))
        row = table[cur]
        nxt = int(np.argmax(row))
        value = row[nxt]
        if not np.isfinite(value):
            log.info("every chord from pin %d is used; stopping after %d lines", cur, len(seq) - 1)
            break
        table[cur, nxt] = table[nxt, cur] = -np.inf
        diff.spread(table, cur, nxt, value)
        seq.append(nxt)
        cur = nxt
    return seq


def sample_disconnected(space, table, lines, *, epsilon=2):
    """Disconnected sampling: the ``lines`` best chords by priority queue with diffusion.

    Returns
    -------
    list of (int, int)
        Chords ``(i, j)``, ``i < j``, in the order chosen.
    """
    diff = _Diffuser(space, epsilon)
    i, j = space.ends[:, 0], space.ends[:, 1]
    vals = table[i, j]
    heap = [(-float(v), int(a), int(b)) for v, a, b in zip(vals, i, j) if np.isfinite(v)]
    heapq.heapify(heap)
    chosen = []
    while heap and len(chosen) < int(lines):
        negv, a, b = heapq.heappop(heap)
        cur = table[a, b]
        if not np.isfinite(cur):
            continue  # used
        if cur != -negv:  # stale entry: values only fall, re-queue with the current one
            heapq.heappush(heap, (-float(cur), a, b))
            continue
        table[a, b] = table[b, a] = -np.inf
        diff.spread(table, a, b, cur)
        chosen.append((a, b))
    return chosen
