"""The guided way back to a reference: jog the head IN and pin N to the station, then declare.

When nothing else can say where the machine stands (no switch; the ring was
turning when the position went; the firmware and the journal disagree), the
operator brings it to a reference that can be checked by eye -- the head IN,
pin N facing the head station -- with jog commands typed in the terminal::

    ring +1.2     turn the ring by +1.2 degrees (ring -0.6, r+3, ...)
    pin -1        turn the ring by one pitch (pin +2, p-1, ...)
    head -12      move the head by -12 mm (h+6, ...)
    done          it is there
    quit          stop (the machine stays where it is)

The host moves each axis by the amount asked (relative moves: the absolute
position is what is unknown), remembers every jog, and at ``done`` declares the
reference (``G10 L20`` / ``G92``), reads it back, and works out from the jogs
where the head crossed the pin circle: through the hook's far gap (the pin is
hooked), back through the gap it went out by (it is not), or anywhere else
(refused: the thread would go round pins the plan did not ask for).  Then the
winding goes on with a ring move with the head IN, safe from anywhere.
"""

import logging
import re

from ..errors import BadInput, Interrupted
from ..motion.safety import gap_offset_deg
from .locate import Found, continue_point, side_of

__all__ = ["guide_to_reference", "bring_head_in", "jog_loop", "crossings", "parse_jog", "JOG_HELP"]

log = logging.getLogger(__name__)

_JOG = re.compile(r"^\s*(ring|r|pin|p|head|h)\s*([+-]?\s*\d+(?:\.\d*)?)\s*$", re.IGNORECASE)
JOG_HELP = ("jog with 'ring +1.2' / 'ring -0.6' (degrees), 'pin +1' / 'pin -1' (one pitch), "
            "'head +12' / 'head -12' (mm); 'done' when it is there, 'quit' to stop")


def parse_jog(text, machine):
    """``"pin -2"`` -> ``("ring", -2 * pitch)``; ``"done"``/``"quit"``/``"help"`` as such; None if not a command."""
    word = text.strip().lower()
    if word in ("done", "d", "ok"):
        return "done"
    if word in ("quit", "q", "exit"):
        return "quit"
    if word in ("help", "?", "h", ""):
        return "help"
    m = _JOG.match(text)
    if not m:
        return None
    axis, amount = m.group(1).lower()[0], float(m.group(2).replace(" ", ""))
    if axis == "p":
        return ("ring", amount * machine.pitch_deg)
    return ("ring" if axis == "r" else "head", amount)


def jog_loop(op, link, machine, question, *, quit_text):
    """Move the machine by the operator's jog commands until ``done`` and a yes to ``question``;
    returns the jogs ``[(axis, delta), ...]``.  ``quit`` raises :class:`Interrupted` (``quit_text``)."""
    h_in = machine["head.in_mm"]
    jogs = []
    while True:
        answer = op.jog("jog> ")
        cmd = parse_jog(answer or "", machine)
        if cmd is None:
            op.tell(f"not a jog command: {answer!r}; {JOG_HELP}")
            continue
        if cmd == "help":
            op.tell(JOG_HELP)
            continue
        if cmd == "quit":
            raise Interrupted(quit_text)
        if cmd == "done":
            if op.confirm is None or op.confirm(question):
                return jogs
            continue
        axis, delta = cmd
        span = 360.0 if axis == "ring" else 2.0 * abs(machine["head.out_mm"] - h_in)
        if abs(delta) > span:
            op.tell(f"{axis} {delta:+g} is more than {span:g} at once; jog in smaller moves")
            continue
        link.jog(**{axis: delta})
        jogs.append((axis, delta))


def crossings(machine, start, jogs):
    """Where the jogs from ``start`` ``(ring_deg, head_mm)`` took the head across the pin circle:
    ``[(side after, ring_deg), ...]``; a crossing away from a gap is refused (it went through a pin)."""
    tol = machine.gap_tolerance_deg + 1e-6
    ring, head = start
    out = []
    for axis, d in jogs:
        if axis == "head":
            before, after = side_of(machine, head), side_of(machine, head + d)
            if before != after:
                gap, off = gap_offset_deg(machine, ring)
                if off > tol:
                    raise BadInput(f"by your jogs the head crossed the pin circle at ring {ring:.3f}, {off:.2f} "
                                   f"deg from the nearest gap ({gap}|{(gap + 1) % machine.pins}): it went "
                                   "through a pin; check the pins and the thread, then resume again")
                out.append((after, ring))
            head += d
        else:
            ring += d
    return out


def bring_head_in(link, machine, op, why):
    """At a start, with the head OUT away from a gap (or where nobody knows): the operator jogs it
    IN through a gap.  Returns the jogs (the caller checks them against what it knows)."""
    op.tell(f"{why}.  Bring the head IN through a gap: turn the ring until a gap between two pins faces "
            "the head (the gap it went out by, if a thread is on), then bring the head IN there (nowhere "
            "else: it would hit a pin).  Then " + JOG_HELP + ".")
    return jog_loop(op, link, machine, "The head is IN (the eyelet inside the pin circle)?",
                    quit_text="stopped by the operator while bringing the head IN; the machine stays where "
                              "it was jogged")


def _near_angle(a, b, tol):
    return abs((a - b + 180.0) % 360.0 - 180.0) <= tol


def guide_to_reference(rec, why):
    """Run the guide for recovery ``rec`` (:class:`~stringbot.winding.recover.GcodeRecovery`);
    returns a :class:`~stringbot.winding.locate.Found`."""
    sit, machine, link, op = rec.sit, rec.machine, rec.link, rec.op
    pitch, h_in = machine.pitch_deg, machine["head.in_mm"]
    pin = sit.pin
    last = sit.s >= len(sit.steps)
    g1 = g2 = None
    if not last:
        moves = sit.steps[sit.s].moves
        g1, g2 = moves[sit.approach].ring_deg, moves[-1].ring_deg
    out_gap = g1 if sit.m == sit.approach + 1 else g2
    text = (f"Guided resume: {why}.  Bring the machine to a reference you can check by eye: the head IN, "
            f"and pin {pin} facing the head station.")
    if sit.phase is not None and rec.from_step is None:      # before the first hook: no hook's gap
        text += ("  If the head is OUT, first turn the ring until a gap between two pins faces the head (the "
                 "one it went out by), and bring the head IN through it (nowhere else: it would hit a pin).")
    elif sit.side != "in" and not last and rec.from_step is None:
        text += (f"  If the head is OUT, first turn the ring until {sit.gap_text(out_gap)} faces the head, "
                 "and bring the head IN through it (nowhere else: it would hit a pin).")
    op.tell(text + "  Then " + JOG_HELP + ".")
    jogs = jog_loop(op, link, machine, f"Pin {pin} faces the head station and the head is IN?",
                    quit_text="stopped by the operator during the guided resume; the machine stays where it "
                              "was jogged: resume again to be guided")
    # the reference, in the journal's turn of the ring
    ref = sit.after[0]
    ring = machine.pin_angle(pin)
    ring += 360.0 * round((ref - ring) / 360.0)
    hooked = _hooked(rec, jogs, (ring, h_in), g1, g2, last)
    here = rec.declare(ring, h_in, f"the operator's reference: pin {pin} at the station, the head IN "
                                   f"(after {len(jogs)} jog(s))")
    if rec.from_step is not None:
        return Found(here, (rec.from_step - 1, 0), True, "your reference (guided)", on_path=False)
    return Found(here, continue_point(sit, hooked=hooked), True,
                 f"your reference, pin {pin} at the station with the head IN (guided)", on_path=False)


def _hooked(rec, jogs, final, g1, g2, last):
    """From the jogs back to the start: where the head crossed the pin circle, and so whether
    the interrupted step's pin is hooked.  Refuses a crossing away from a gap, or through a gap
    that is not the hook's."""
    sit, machine = rec.sit, rec.machine
    tol = machine.gap_tolerance_deg + 1e-6
    ring, head = final
    for axis, d in reversed(jogs):                        # back to where the guide started
        if axis == "ring":
            ring -= d
        else:
            head -= d
    start_side = side_of(machine, head)
    crossed = crossings(machine, (ring, head), jogs)
    if rec.from_step is not None or last:
        return False
    gaps = {round(((r - machine["ring.pin0_angle_deg"]) / machine.pitch_deg - 0.5)) % machine.pins
            for _, r in crossed}
    if len(gaps) > 1:
        raise BadInput("by your jogs the head went out and in through different gaps: the thread now goes "
                       "round pins the plan did not ask for; unwind it by hand, then restart with --from-step")
    if sit.phase is not None:            # moving to the start: nothing was to be hooked
        return False
    if start_side == "in" and sit.side == "out":
        raise BadInput("by your jogs the head was IN when the guide began, but the journal says it was OUT "
                       "(turning the ring behind a pin): was the machine moved by hand?  Check the thread at "
                       f"pin {sit.pin}, then restart with --from-step")
    if not crossed:
        if start_side == "out":
            raise BadInput("the head never came IN during the guide, yet it is IN now?  Resume again")
        return sit.side is None and sit.m == sit.approach + 3     # it had finished coming IN at the far gap
    last_in = [r for s, r in crossed if s == "in"][-1]
    if start_side == "in":
        return sit.side is None and sit.m == sit.approach + 3   # out and back through one gap: no change
    if g2 is not None and _near_angle(last_in, g2, tol):
        return True
    if g1 is not None and _near_angle(last_in, g1, tol):
        return False
    raise BadInput(f"by your jogs the head came IN at ring {last_in:.3f}, through neither of the hook's gaps "
                   f"({sit.gap_text(g1)} or {sit.gap_text(g2)}): the thread now goes round pins the plan did "
                   "not ask for; unwind it by hand, then restart with --from-step")
