"""Polish: reroute pins of a sequence where the picture as woven, seen from a step away, gets better.

After the residual planner (:mod:`stringbot.planner.methods.residual`) has chosen its
threads pixel by pixel, this pass revisits pins of the sequence: pin ``k``'s
two chords ``(p[k-1], p[k])``, ``(p[k], p[k+1])`` may go through another pin
``q`` instead, the one whose two chords have the highest error slope.  The
change is judged by the exact change of the as-woven error of
:class:`~stringbot.planner.methods.woven.WovenCanvas` (where the threads overlap, seen
through the eye's blur) and kept only when it lowers that error.  So the
thread stays one continuous thread with the same number of lines, and the
picture can only get better.  (Dropping pins as :mod:`~stringbot.planner.methods.refine`
does was tried here too: it changed the as-woven error by less than 0.0001
on the horse and the camera, at a sixth more time.)

The pins revisited are the ``budget`` whose chords draw most where the picture
is already darker than wanted (a fixed number, so that the same picture
always gives the same plan).  They go in blocks of two, each block's
proposals made before the block ahead of it is settled, so that on two cores
two processes take turns (:mod:`stringbot.planner.methods.woven_helper`) and reach
the same plan.

It may go on in rounds (:func:`polish_rounds`; the residual planner's default
three): each round revisits the ``budget`` worst pins of the drawing the round
before left, since a pin's best way round depends on its neighbours', which
that round rerouted.

On request (``passes``, the ``--polish-passes`` option of ``stringbot plan``;
off by default: three passes about double the plan's CPU), passes of
Prem-Dharshan's two other moves follow, in one process: *inserting* a pin
(``a-c -> a-q-c`` at the ``budget`` chords of highest error slope, ``q``
among the :data:`INSERT_CANDIDATES` pins whose two chords have the highest
slope; the line count grows) and *deleting* one (``a-p-c -> a-c`` at the
``budget`` pins that draw most where it is too dark).  Each is judged as the
reroutes are, by the estimate first and then exactly, and kept only when the
exact as-woven error drops (:func:`move_passes`).
"""

import logging

import numpy as np

from ..model.lines import PinLines
from .eye import EyeError
from .woven import WovenCanvas

log = logging.getLogger(__name__)

__all__ = ["polish_plan", "polish_pins", "polish_rounds", "polish_lines", "propose", "settle", "badness_order", "move_passes",
           "Guarded", "POLISH_SPACING", "BLOCK", "INSERT_CANDIDATES",
           "MAX_PASSES"]

#: pixels between the points a chord's slope is averaged over (the grid is 256 px: about 1/128 of the frame)
POLISH_SPACING = 2.0
#: pins whose proposals are made at a time, before the block ahead is settled (on two cores, by one process)
BLOCK = 2
#: pins tried for each insert, those whose two chords have the highest error slope first (the first kept wins)
INSERT_CANDIDATES = 3
#: the most passes of inserts and deletes ``--polish-passes`` takes
MAX_PASSES = 20


class Guarded:
    """A drawing polished by one error and guarded by another (:func:`polish_plan`, one process): the
    moves are chosen and judged by ``lead``'s error, and a change is kept only where ``guard``'s error
    does not rise either (``--face``: the frame's error leads, the face's own error guards).

    Parameters
    ----------
    lead : WovenCanvas
        Holds the drawing.
    guard : EyeError
        Another error of the same drawing on the same grid (its ``D`` the lead's): kept in step with
        the change of ``D`` each of the lead's changes makes, with no fine canvas of its own.
    """

    def __init__(self, lead, guard):
        self.lead, self.guard = lead, guard

    def __getattr__(self, name):  # everything but helps and apply is the lead's
        return getattr(self.lead, name)

    def helps(self, chords_out=(), chords_in=()):
        """Whether the change lowers the lead's error by its estimate and does not raise the guard's by
        its own (exact but where the chords overlap): a change the guard would undo is not made."""
        cp, dD = self.lead._fine(chords_out, chords_in, "none")
        if cp is None or self.lead.change(cp, dD, sign=True)[0] >= 0.0:
            return False
        return not self.guard.s[cp].any() or self.guard.change(cp, dD, sign=True)[0] <= 0.0

    def apply(self, chords_out=(), chords_in=()):
        """The change on both; the lead's change of error, or a rise (so it is undone) where the guard's rose."""
        d, cp, dD = self.lead.apply_change(chords_out=chords_out, chords_in=chords_in)
        g = 0.0
        if cp is not None:
            if self.guard.s[cp].any():
                g = self.guard.take(cp, dD)
            else:  # where the guard weighs nothing its error and slope do not change
                self.guard.D[cp] += dD
        return d if g <= 0.0 else abs(d) + g


def polish_lines(space, canvas):
    """The chords' points the polish scores along (each pin's row is kept by the canvas)."""
    return PinLines(space, canvas.size, nearest=True, spacing=POLISH_SPACING, keep=False)


def badness_order(canvas, seq, pin_lines):
    """Inner pins of ``seq`` (indices), those whose two chords draw most where it is too dark first."""
    means = canvas.chord_scores(pin_lines, list(zip(seq[:-1], seq[1:])))
    return [int(k) for k in np.argsort(means[:-1] + means[1:], kind="stable") + 1]


def propose(canvas, seq, k, pin_lines, scratch):
    """The reroute of pin ``k`` worth trying: ``(k, a, p, c, q)`` when going through ``q`` instead of
    ``p = seq[k]`` (between ``a`` and ``c``) lowers the error by the estimate (which writes
    nothing), else None.  ``q`` is the pin whose two chords have the highest error slope."""
    a, p, c = seq[k - 1], seq[k], seq[k + 1]
    total = _slopes_from(canvas, pin_lines, a, c, scratch)
    total[p] = -np.inf
    q = int(np.argmax(total))
    if not np.isfinite(total[q]):
        return None
    if canvas.helps(chords_out=[(a, p), (p, c)], chords_in=[(a, q), (q, c)]):  # by the estimate
        return (int(k), int(a), int(p), int(c), q)
    return None


def settle(canvas, seq, proposal):
    """Make a proposal of :func:`propose` if its pins are still there and the exact error drops
    (else leave the drawing as it was); ``seq`` is changed in place.  Returns 1 if made, else 0."""
    if _touches(seq, proposal):
        if _keep_if_lower(canvas, *_changed(proposal)):
            seq[proposal[0]] = proposal[4]
            return 1
    return 0


def _keep_if_lower(canvas, out, inn):
    """Make the change; undo it unless the exact error dropped.  True if kept."""
    if canvas.apply(chords_out=out, chords_in=inn) < 0.0:  # exact
        return True
    canvas.apply(chords_out=inn, chords_in=out)  # the estimate erred where the chords overlap
    return False


def _touches(seq, proposal):
    """Whether settling ``proposal`` changes the drawing (made, or made and undone)."""
    if proposal is None:
        return False
    k, a, p, c, _ = proposal
    return (seq[k - 1], seq[k], seq[k + 1]) == (a, p, c)


def polish_pins(canvas, seq, order, pin_lines, *, partner=None):
    """Revisit pins ``order`` (indices into ``seq``, inner ones) in turn; ``seq`` is changed in place.

    The pins go in blocks of :data:`BLOCK`: the proposals for a block's pins
    (:func:`propose`) are made against the drawing as it is before the block
    ahead of it is settled; then that block's proposals are settled in turn
    (:func:`settle`: each kept only if the exact error drops).  So two
    processes can take turns (``partner``): each makes the proposals of every
    other block while the other settles the block before, and sends what its
    own settling did to the drawing, so that both hold the same drawing and
    the plan is the same pin for pin.

    Parameters
    ----------
    partner : optional
        The other process (:class:`~stringbot.planner.methods.woven_helper.Partner`):
        ``partner.run(blocks, make, settle, replay)`` makes and settles this
        process's blocks (``make(k)``, ``settle(proposal) -> (made, change)``)
        and replays the other's (``replay(proposal, made, change)``) in order.
        None: all of them here.

    Returns
    -------
    int
        How many pins were rerouted.
    """
    npins = len(canvas.pin_xy)
    scratch = (np.empty(npins), np.empty(npins))
    blocks = [order[j:j + BLOCK] for j in range(0, len(order), BLOCK)]

    def make(k):
        return propose(canvas, seq, k, pin_lines, scratch)

    if partner is not None:
        def settle_here(proposal):
            touched = _touches(seq, proposal)
            made = settle(canvas, seq, proposal)
            return made, ((canvas.change_record(sum(_changed(proposal), [])), canvas.G, canvas.E) if touched else None)

        def replay(proposal, made, change):
            if change is not None:
                record, G, E = change
                old, new = _changed(proposal) if made else ((), ())  # an undone change counts no chord
                canvas.replay(record, G, E, chords_out=old, chords_in=new)
            if made:
                seq[proposal[0]] = proposal[4]

        return partner.run(blocks, make, settle_here, replay)
    rerouted, pending = 0, []
    for block in blocks:
        proposals = [make(k) for k in block]
        rerouted += sum(settle(canvas, seq, proposal) for proposal in pending)
        pending = proposals
    return rerouted + sum(settle(canvas, seq, proposal) for proposal in pending)


def polish_rounds(canvas, seq, order, pin_lines, *, rounds=1, partner=None):
    """:func:`polish_pins` ``rounds`` times: first over ``order``, then each round over as many pins of
    :func:`badness_order` on the drawing as the round before left it (``seq`` changed in place).  A pin's
    best way round depends on its neighbours', which the rounds before rerouted: on the astronaut a
    second and a third round of 1000 pins reroute 125 and 102 pins more (docs/planner.md, "Polish").

    ``partner``: as :func:`polish_pins`, the same ``rounds`` on both sides (each finds the next round's
    pins on its own copy of the drawing, the same); the two wait for each other between rounds.

    Returns
    -------
    list of int
        The pins rerouted in each round.
    """
    made, budget = [], len(order)
    for r in range(int(rounds)):
        if r:
            order = badness_order(canvas, seq, pin_lines)[:budget]
            if partner is not None:
                partner.sync()
        made.append(polish_pins(canvas, seq, order, pin_lines, partner=partner))
    return made


def _changed(proposal):
    """The chords a proposal takes out and those it puts in: ``[(a, p), (p, c)], [(a, q), (q, c)]``."""
    _, a, p, c, q = proposal
    return [(a, p), (p, c)], [(a, q), (q, c)]


def _slopes_from(canvas, pin_lines, a, c, buf):
    """The error slope of going ``a -> q -> c``, for every pin ``q`` (-inf where a chord is missing)."""
    from_a, from_c = buf
    oa, sa = canvas.scores(pin_lines, a)
    oc, sc = canvas.scores(pin_lines, c)
    from_a.fill(-np.inf)
    from_a[oa] = sa
    from_c.fill(-np.inf)
    from_c[oc] = sc
    total = from_a + from_c
    total[[a, c]] = -np.inf
    return total


def _try(canvas, out, inn):
    """Make the change if the estimate says it helps and the exact error drops; True if made."""
    return canvas.helps(chords_out=out, chords_in=inn) and _keep_if_lower(canvas, out, inn)


def insert_pass(canvas, seq, pin_lines, *, budget):
    """Insert pins (``a-c -> a-q-c``) at the ``budget`` chords of highest error slope; ``seq`` is
    changed in place.  Returns how many pins were inserted."""
    npins = len(canvas.pin_xy)
    buf = (np.empty(npins), np.empty(npins))
    means = canvas.chord_scores(pin_lines, list(zip(seq[:-1], seq[1:])))
    top = sorted(int(j) for j in np.argsort(-means, kind="stable")[:budget])
    made = 0
    for j in reversed(top):  # from the end: an insert does not shift the positions still to come
        a, c = seq[j], seq[j + 1]
        total = _slopes_from(canvas, pin_lines, a, c, buf)
        for q in np.argsort(-total, kind="stable")[:INSERT_CANDIDATES]:
            q = int(q)
            if np.isfinite(total[q]) and _try(canvas, [(a, c)], [(a, q), (q, c)]):
                seq.insert(j + 1, q)
                made += 1
                break
    return made


def delete_pass(canvas, seq, pin_lines, *, budget):
    """Delete pins (``a-p-c -> a-c``) among the ``budget`` that draw most where it is too dark, where
    ``a-c`` is a chord not drawn yet; ``seq`` is changed in place.  Returns how many were deleted."""
    made = 0
    for k in sorted(badness_order(canvas, seq, pin_lines)[:budget], reverse=True):
        a, p, c = seq[k - 1], seq[k], seq[k + 1]
        if a == c or canvas.uses[a, c] > 0:
            continue
        if _try(canvas, [(a, p), (p, c)], [(a, c)]):
            del seq[k]
            made += 1
    return made


def move_passes(canvas, seq, pin_lines, *, passes, budget):
    """``passes`` passes of inserts then deletes (:func:`insert_pass`, :func:`delete_pass`), in this process;
    ``seq`` is changed in place.

    Parameters
    ----------
    canvas : WovenCanvas
        Holds ``seq`` drawn; kept in step with the changes.
    seq : list of int
    pin_lines : PinLines
        As :func:`polish_lines` makes them.
    passes : int
    budget : int
        Chords (inserts) and pins (deletes) tried in each pass.

    Returns
    -------
    dict
        ``inserted`` and ``deleted``: pins, over all the passes.
    """
    inserted = deleted = 0
    for n in range(passes):
        i = insert_pass(canvas, seq, pin_lines, budget=budget)
        d = delete_pass(canvas, seq, pin_lines, budget=budget)
        inserted, deleted = inserted + i, deleted + d
        log.info("polish pass %d: %d pins inserted, %d deleted", n + 1, i, d)
    return {"inserted": inserted, "deleted": deleted}


def polish_plan(canvas, seq, space, *, budget, rounds=1, passes=0, deletes=0, partner=None):
    """Polish a pin sequence against the picture as woven (see the module notes).

    Parameters
    ----------
    canvas : WovenCanvas
        Holds ``seq`` drawn (:meth:`WovenCanvas.build`); kept in step with the changes.
    seq : list of int
    space : ChordSpace
    budget : int
        Pins to revisit in each round (and, with ``passes``, chords and pins each pass tries).
    rounds : int
        Rounds of reroutes (:func:`polish_rounds`), on two processes where ``partner`` gives one.
    passes : int
        Passes of inserts and deletes after the reroutes (:func:`move_passes`), in this process
        once the partner is closed; 0: none.
    deletes : int
        Then passes of deletes alone (:func:`delete_pass`, ``budget`` pins each); 0: none.
    partner : callable, optional
        ``partner(canvas, seq, order, pin_lines, rounds=rounds)`` returns a partner for
        :func:`polish_pins` (a forked process: :func:`~stringbot.planner.methods.woven_helper.twin`),
        or None to polish alone.

    Returns
    -------
    seq : list of int
    stats : dict
        ``tried``, ``rerouted`` (over all the rounds), ``woven_rms_before`` and ``woven_rms`` (the model's as-woven
        error, rms over the frame); with ``rounds`` above 1, ``rounds`` and ``rerouted_by_round``; with ``passes``, ``passes``, ``inserted``, ``deleted`` and
        ``woven_rms_rerouted`` (the error before the passes); with ``deletes``, ``delete_passes``,
        ``deleted`` and ``woven_rms_rerouted``.
    """
    seq = [int(p) for p in seq]
    if len(seq) < 3 or budget <= 0:
        return seq, {"tried": 0, "rerouted": 0, "woven_rms_before": None, "woven_rms": None}
    e0 = canvas.error()
    pin_lines = polish_lines(space, canvas)
    order = badness_order(canvas, seq, pin_lines)[:budget]
    mate = None if partner is None else partner(canvas, seq, order, pin_lines, rounds=rounds)
    try:
        by_round = polish_rounds(canvas, seq, order, pin_lines, rounds=rounds, partner=mate)
    finally:
        if mate is not None:
            mate.close()
    area = max(float(np.sum(canvas.s ** 2)), 1e-12)

    def rms(e):
        return round(float(np.sqrt(max(e, 0.0) / area)), 5)

    rerouted = sum(by_round)
    stats = {"tried": len(order), "rerouted": rerouted, "woven_rms_before": rms(e0)}
    if rounds > 1:
        stats.update(rounds=int(rounds), rerouted_by_round=by_round)
    if passes > 0 or deletes > 0:
        stats["woven_rms_rerouted"] = rms(canvas.error())
    if passes > 0:
        stats.update(passes=int(passes), **move_passes(canvas, seq, pin_lines, passes=passes, budget=budget))
    if deletes > 0:
        made = sum(delete_pass(canvas, seq, pin_lines, budget=budget) for _ in range(int(deletes)))
        stats.update(delete_passes=int(deletes), deleted=stats.get("deleted", 0) + made)
        log.info("polish: %d pins deleted in %d passes of deletes", made, deletes)
    stats["woven_rms"] = rms(canvas.error())
    log.info("polish: %d of %d pins rerouted (%s rounds); as-woven rms %.4f -> %.4f", rerouted, len(order),
             rounds, stats["woven_rms_before"], stats["woven_rms"])
    return seq, stats
