"""Polish: reroute pins of a sequence where the picture as woven, seen from a step away, gets better.

After the residual planner (:mod:`stringbot.planner.residual`) has chosen its
threads pixel by pixel, this pass revisits pins of the sequence: pin ``k``'s
two chords ``(p[k-1], p[k])``, ``(p[k], p[k+1])`` may go through another pin
``q`` instead, the one whose two chords have the highest error slope.  The
change is judged by the exact change of the as-woven error of
:class:`~stringbot.planner.woven.WovenCanvas` (where the threads overlap, seen
through the eye's blur) and kept only when it lowers that error.  So the
thread stays one continuous thread with the same number of lines, and the
picture can only get better.  (Dropping pins as :mod:`~stringbot.planner.refine`
does was tried here too: it changed the as-woven error by less than 0.0001
on the horse and the camera, at a sixth more time.)

The pins revisited are the ``budget`` whose chords draw most where the picture
is already darker than wanted (a fixed number, so that the same picture
always gives the same plan).
"""

import logging

import numpy as np

from .greedy import _PinLines

log = logging.getLogger(__name__)

__all__ = ["polish_plan", "polish_pins", "badness_order", "POLISH_SPACING"]

#: pixels between the points a chord's slope is averaged over (the grid is 256 px: about 1/128 of the frame)
POLISH_SPACING = 2.0


def badness_order(canvas, seq, pin_lines):
    """Inner pins of ``seq`` (indices), those whose two chords draw most where it is too dark first."""
    n = len(seq)
    rows = {}
    means = np.empty(n - 1)
    for i in range(n - 1):
        a, b = seq[i], seq[i + 1]
        if a not in rows:
            rows[a] = canvas.scores(pin_lines, a)
        others, sc = rows[a]
        j = int(np.searchsorted(others, b))
        means[i] = float(sc[j]) if j < len(others) and others[j] == b else 0.0
    return [int(k) for k in np.argsort(means[:-1] + means[1:], kind="stable") + 1]


def polish_pins(canvas, seq, order, pin_lines):
    """Revisit pins ``order`` (indices into ``seq``, inner ones) in turn; ``seq`` is changed in place.

    Returns
    -------
    int
        How many pins were rerouted.
    """
    npins = len(canvas.pin_xy)
    from_a = np.empty(npins)
    from_c = np.empty(npins)
    rerouted = 0
    for k in order:
        a, p, c = seq[k - 1], seq[k], seq[k + 1]
        oa, sa = canvas.scores(pin_lines, a)
        oc, sc = canvas.scores(pin_lines, c)
        from_a.fill(-np.inf)
        from_a[oa] = sa
        from_c.fill(-np.inf)
        from_c[oc] = sc
        total = from_a + from_c
        total[[a, c, p]] = -np.inf
        q = int(np.argmax(total))
        if not np.isfinite(total[q]):
            continue
        old, new = [(a, p), (p, c)], [(a, q), (q, c)]
        if canvas.estimate(chords_out=old, chords_in=new) < 0.0:
            if canvas.apply(chords_out=old, chords_in=new) < 0.0:  # exact
                seq[k] = q
                rerouted += 1
                canvas.forget(old)
                continue
            canvas.apply(chords_out=new, chords_in=old)  # the estimate erred where the chords overlap
        canvas.forget(new)
    return rerouted


def polish_plan(canvas, seq, space, *, budget):
    """Polish a pin sequence against the picture as woven (see the module notes).

    Parameters
    ----------
    canvas : WovenCanvas
        Holds ``seq`` drawn (:meth:`WovenCanvas.build`); kept in step with the changes.
    seq : list of int
    space : ChordSpace
    budget : int
        Pins to revisit.

    Returns
    -------
    seq : list of int
    stats : dict
        ``tried``, ``rerouted``, ``woven_rms_before`` and ``woven_rms`` (the model's as-woven
        error, rms over the frame).
    cover : ndarray of float32, shape (F, F), or None
        The polished sequence's coverage on the fine canvas, capped at 1 (None when nothing was polished).
    """
    seq = [int(p) for p in seq]
    if len(seq) < 3 or budget <= 0:
        return seq, {"tried": 0, "rerouted": 0, "woven_rms_before": None, "woven_rms": None}, None
    e0 = canvas.error()
    pin_lines = _PinLines(space, canvas.size, nearest=True, spacing=POLISH_SPACING, keep=False)
    order = badness_order(canvas, seq, pin_lines)[:budget]
    rerouted = polish_pins(canvas, seq, order, pin_lines)
    area = max(float(np.sum(canvas.s ** 2)), 1e-12)
    stats = {"tried": len(order), "rerouted": rerouted,
             "woven_rms_before": round(float(np.sqrt(max(e0, 0.0) / area)), 5),
             "woven_rms": round(float(np.sqrt(max(canvas.error(), 0.0) / area)), 5)}
    log.info("polish: %d of %d pins rerouted; as-woven rms %.4f -> %.4f", rerouted, len(order),
             stats["woven_rms_before"], stats["woven_rms"])
    return seq, stats, np.minimum(canvas.Sf, 1.0).reshape(canvas.F, canvas.F)
