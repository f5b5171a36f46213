"""Refinement: local changes to a pin sequence that keep one thread and never make the picture worse.

After the residual planner (:mod:`stringbot.planner.methods.residual`) a thread chosen
early may no longer be the best one where it is, once the others are drawn.
As Birsak et al. (2018) remove and add threads, this pass revisits pins of
the sequence, each change judged by the exact change of the error of the
drawing as woven (:class:`~stringbot.planner.methods.canvas.Canvas`) and kept only
when it lowers it, so the picture can only get better and the thread stays
one continuous thread (a pin is replaced or dropped between its two
neighbours; no pin twice in a row):

* *reroute* pin ``k``: its two chords ``(p[k-1], p[k])``, ``(p[k], p[k+1])``
  are lifted off the drawing and the best pin ``q`` to go through instead is
  chosen by the same score as the planner's (the mean residual along both new
  chords); kept when the exact error is lower than with ``p[k]``;
* *remove* pin ``k`` (automatic line counts only): its two chords become one,
  ``(p[k-1], p[k+1])``, when that lowers the error.

The pins revisited are the ``budget`` whose chords draw where the picture is
already darker than wanted (most negative mean residual) -- a fixed number,
so that the same picture always gives the same plan.
"""

import logging

import numpy as np

from .canvas import fresh

log = logging.getLogger(__name__)

__all__ = ["refine_sequence"]


def _chord_score(canvas, pin_lines, a):
    """Mean residual of every chord from pin ``a``: ``(others, scores)``."""
    others, pix, starts, counts = pin_lines.get_with_counts(a)
    return others, fresh(np.add.reduceat(canvas.slope().take(pix), starts) / counts, canvas.uses[a, others])


def refine_sequence(canvas, seq, pin_lines, *, budget=300, remove=True):
    """Reroute (and with ``remove``, drop) pins of ``seq`` where that lowers the error (see module notes).

    Parameters
    ----------
    canvas : Canvas
        Holds ``seq`` drawn; kept in step with the changes.
    seq : list of int
    pin_lines : PinLines
    budget : int
        How many pins to revisit.
    remove : bool
        Also drop pins (fewer lines); False keeps the line count.

    Returns
    -------
    seq : list of int
    stats : dict
        ``rerouted``, ``removed``, ``tried`` and ``error_drop`` (exact, >= 0).
    """
    seq = [int(p) for p in seq]
    n = len(seq)
    if n < 3 or budget <= 0:
        return seq, {"rerouted": 0, "removed": 0, "tried": 0, "error_drop": 0.0}
    # badness of each inner pin: the mean residual of its two chords (negative: drawn where too dark)
    g = canvas.slope()
    bad = np.zeros(n)
    chords = list(zip(seq[:-1], seq[1:]))
    means = np.empty(len(chords))
    for i, (a, b) in enumerate(chords):
        flat, cov = canvas.footprint(a, b)
        means[i] = float(np.dot(g[flat], cov) / max(cov.sum(), 1e-12))
    bad[1:-1] = means[:-1] + means[1:]
    order = [int(k) for k in np.argsort(bad[1:-1], kind="stable")[:budget] + 1]
    drop = 0.0
    rerouted = removed = 0
    alive = np.ones(n, dtype=bool)
    for k in order:
        # neighbours among the pins still in the sequence
        i = k - 1
        while i >= 0 and not alive[i]:
            i -= 1
        j = k + 1
        while j < n and not alive[j]:
            j += 1
        if i < 0 or j >= n:
            continue
        a, p, c = seq[i], seq[k], seq[j]
        old = [(a, p), (p, c)]
        # lifted, so that the scores see the picture without them; putting them back would change the
        # error by minus what lifting did: the bar to beat
        base = -canvas.apply(chords_out=old)
        best, best_pins = base, None
        oa, sa = _chord_score(canvas, pin_lines, a)
        oc, sc = _chord_score(canvas, pin_lines, c)
        total = np.full(len(canvas.pin_xy), -np.inf)
        ta = np.full_like(total, -np.inf)
        ta[oa] = sa
        total[oc] = sc
        total += ta
        total[[a, c, p]] = -np.inf
        q = int(np.argmax(total))
        if np.isfinite(total[q]):
            d = canvas.delta(chords_in=[(a, q), (q, c)])
            if d < best - 1e-12:
                best, best_pins = d, [q]
        if remove and a != c and pin_lines.space.index[a, c] >= 0:
            d = canvas.delta(chords_in=[(a, c)])
            if d < best - 1e-12:
                best, best_pins = d, []
        if best_pins is None:
            canvas.apply(chords_in=old)
            continue
        drop += base - best
        if best_pins:
            seq[k] = best_pins[0]
            canvas.apply(chords_in=[(a, best_pins[0]), (best_pins[0], c)])
            rerouted += 1
        else:
            alive[k] = False
            canvas.apply(chords_in=[(a, c)])
            removed += 1
    out = [p for p, keep in zip(seq, alive) if keep]
    log.info("refine: %d rerouted, %d removed of %d tried; error %.4g lower", rerouted, removed, len(order), drop)
    return out, {"rerouted": rerouted, "removed": removed, "tried": len(order), "error_drop": float(drop)}

