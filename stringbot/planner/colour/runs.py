"""The colour plan's order: threads laid in runs, a colour coming back, within a spool-change budget.

The planner lays threads in winding order on the :class:`~.model.Piece`, each
new one on top.  A *run* is one continuous thread of one colour (a layer of
the plan file); between two runs the maker changes the spool.  At most
``spool_changes + 1`` runs, each at least ``min_run`` chords (the last one
may be shorter: the line budget ends it).

*A run.*  It starts at an end of the chord of its colour that lowers the
error most, anywhere on the frame, and goes on from pin to pin, each time
the chord from the current pin that lowers the error most (a chord is laid
at most once in a colour; the last ``min_loop`` pins are not gone back to).

*When to change the spool, and to which colour.*  Every ``check`` chords of
a run (once it has ``min_run``), the best chord of every other colour
anywhere on the frame is weighed against what the current thread has been
doing (its mean gain over those last chords); the spool is changed when
another colour's best chord would lower the error more than ``switch`` times
that, and the budget allows: the changes are paced over the line budget, so
that by a share ``x`` of the lines at most ``1 + x * spool_changes`` of them
are spent (a change is left for the end's detail).  The next run is the
colour whose best chord is the best then.  A run whose colour has nothing
left to lay ends at once.
"""

import logging

import numpy as np

from ..progress import report

log = logging.getLogger(__name__)

__all__ = ["plan_runs", "RUN_DEFAULTS"]

RUN_DEFAULTS = {"spool_changes": 8, "min_run": 100, "check": 20, "switch": 1.0, "min_loop": 3, "schedule": None, "lengths": None, "under": False}


class _Fans:
    """The chords from each pin with their pixels, built lazily."""

    def __init__(self, space, indptr, indices, weights):
        self.space, self.indptr, self.indices, self.weights = space, indptr, indices, weights
        self.cache = {}

    def get(self, p):
        fan = self.cache.get(p)
        if fan is None:
            row = self.space.index[p]
            others = np.flatnonzero(row >= 0)
            chords = row[others]
            lo = self.indptr[chords]
            counts = self.indptr[chords + 1] - lo
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            pos = np.arange(counts.sum()) - np.repeat(starts, counts) + np.repeat(lo, counts)
            fan = self.cache[p] = (others, chords, self.indices[pos].astype(np.int64), starts,
                                   self.weights[chords].astype(np.float64))
        return fan


class _Everywhere:
    """Every chord's gain for a colour, judged by every ``stride``-th of its pixels, the best few again by all."""

    def __init__(self, indptr, indices, weights, *, stride=4, exact=48):
        counts = np.diff(indptr)
        thin = (counts + stride - 1) // stride
        self.indptr = np.concatenate([[0], np.cumsum(thin)])
        pos = (np.arange(int(thin.sum())) - np.repeat(self.indptr[:-1], thin)) * stride + np.repeat(indptr[:-1], thin)
        self.indices = indices[pos]
        self.scale = weights * (counts / thin)
        self.full = (indptr, indices, weights)
        self.exact = int(exact)

    def best(self, S, skip):
        """``(gain, chord)`` of the chord that lowers the error most (``skip``: chords not to take)."""
        g = self.scale * np.add.reduceat(S.take(self.indices), self.indptr[:-1])
        g[skip] = np.inf
        top = np.argpartition(g, self.exact)[:self.exact] if len(g) > self.exact else np.arange(len(g))
        indptr, indices, weights = self.full
        exact = [(float(weights[c] * S[indices[indptr[c]:indptr[c + 1]]].sum()), int(c)) for c in top
                 if np.isfinite(g[c])]
        return min(exact) if exact else (np.inf, -1)


def plan_runs(space, indptr, indices, weights, piece, lines, *, spool_changes=RUN_DEFAULTS["spool_changes"],
              min_run=RUN_DEFAULTS["min_run"], check=RUN_DEFAULTS["check"], switch=RUN_DEFAULTS["switch"],
              min_loop=RUN_DEFAULTS["min_loop"], first=None, schedule=None, lengths=None, under=False):
    """Lay up to ``lines`` threads in runs (see the module notes).

    Parameters
    ----------
    space : ChordSpace
    indptr, indices : ndarray
        Chord pixels on the working grid (:func:`stringbot.planner.chords.chord_pixels`).
    weights : ndarray of float, shape (m,)
        Each chord's share of its pixels (:func:`~.model.chord_weights_px`).
    piece : Piece
        Updated in place.
    lines : int
        Line budget over all runs.
    spool_changes : int
        Budget of spool changes (runs - 1), >= 0.
    min_run : int
        Chords a run lays at least before the spool may change.
    check : int
        Chords between two looks at the other colours.
    switch : float
        Another colour's best chord must beat the current thread's recent mean gain by this factor.
    min_loop : int
    first : int, optional
        The first run's first pin (None: where its best chord is).

    Returns
    -------
    list of (int, list of int)
        ``(colour index, pin sequence)`` of each run, in winding order.
    """
    K = piece.K
    fans = _Fans(space, indptr, indices, weights)
    laid = np.zeros((K, space.m), dtype=bool)
    runs = []
    total = 0

    everywhere = _Everywhere(indptr, indices, weights)

    def global_best(k):
        return everywhere.best(piece.S[k], laid[k])

    def lay(k, seq, a, b, chord):
        piece.lay(k, a, b)
        laid[k, chord] = True
        seq.append(b)

    def step(k, seq):
        others, chords, pix, starts, w = fans.get(seq[-1])
        gain = w * np.add.reduceat(piece.S[k].take(pix), starts)
        gain[laid[k, chords]] = np.inf
        for q in seq[-min_loop:]:
            i = int(np.searchsorted(others, q))
            if i < len(others) and others[i] == q:
                gain[i] = np.inf
        i = int(np.argmin(gain))
        return float(gain[i]), int(others[i]), int(chords[i])

    best = [global_best(k) for k in range(K)]
    current = None
    while total < lines and len(runs) <= spool_changes:
        options = [k for k in range(K) if k != current and best[k][0] < 0]
        if not options:
            break
        k = min(options, key=lambda j: best[j][0])
        if schedule is not None:
            if len(runs) >= len(schedule):
                break
            k = schedule[len(runs)]
        chord = best[k][1]
        a, b = (int(p) for p in space.ends[chord])
        if first is not None and not runs:
            a = int(first)
            gain, b, chord = step(k, [a])
            if gain >= 0:
                break
        seq = [a]
        lay(k, seq, a, b, chord)
        total += 1
        gains = []
        while total < lines:
            gain, nxt, chord = step(k, seq)
            if gain >= 0:
                break
            lay(k, seq, seq[-1], nxt, chord)
            total += 1
            gains.append(gain)
            if total % 200 == 0:
                report("colour", total, lines)
            n = len(seq) - 1
            if lengths is not None:
                if n >= lengths[len(runs)] and len(runs) < len(lengths) - 1:
                    break
                continue
            if K > 1 and n >= min_run and n % check == 0 and len(runs) < spool_changes \
                    and len(runs) <= spool_changes * total / lines:           # paced
                best = [global_best(j) for j in range(K)]
                rival = min(best[j][0] for j in range(K) if j != k)
                if rival < switch * best[k][0]:
                    break
        runs.append((k, seq))
        current = k
        best = [global_best(j) for j in range(K)]
    if piece.under:
        runs = [(k, seq[::-1]) for k, seq in runs[::-1]]
    return runs
