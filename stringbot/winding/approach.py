"""The first move of a winding or of a resume: from where the machine reports standing.

Before the first planned move the machine is asked where it stands.  The head
goes IN alone first (through the gap the ring stands at, if it is OUT), then
the ring turns alone to the job's start with the head IN: no move combines the
two, and the head never crosses the pin circle away from a gap.  A head that
reports OUT with the ring away from any gap is refused: no move can bring it
in safely: the operator must, by hand or (at a terminal) guided by jog commands.
Each of these moves is journaled before it is sent (``{"kind": "approach",
"from": ..., "to": ...}``; ``"to": null`` while the operator jogs), so a stop
among them leaves the machine on a path the journal knows.
"""

import logging

from ..errors import MachineFailure
from ..motion.safety import gap_offset_deg, side
from .guide import bring_head_in, crossings

__all__ = ["approach"]

log = logging.getLogger(__name__)


def approach(link, machine, target, tol, *, journal=None, op=None):
    """Bring the machine from where it reports standing to ``target`` ``(ring_deg, head_mm IN)``.

    Parameters
    ----------
    link : a step-level link (``position()``, ``move_to(ring, head, axis=)``, ``jog``)
    machine : Machine
    target : (float, float)
    tol : (float, float) how far a reported position may be from a point reached
    journal : Journal or None: each move is journaled before it is sent
    op : Operator or None: at a terminal (``op.jog``), a head OUT away from a gap is brought IN
        by the operator's jogs instead of refused

    Returns
    -------
    (float, float) where the machine reported standing before the approach.
    """
    here = link.position()
    if here is None:
        raise MachineFailure("the machine reports no position; check it, then start again")
    ring, head = first = (float(here[0]), float(here[1]))
    h_in = machine["head.in_mm"]

    def note(frm, to):
        if journal is not None:
            journal.append({"kind": "approach", "from": [float(v) for v in frm],
                            "to": None if to is None else [float(v) for v in to]})

    if abs(head - h_in) > tol[1]:
        if side(machine, head) != "in":
            gap, off = gap_offset_deg(machine, ring)
            if off > machine.gap_tolerance_deg:
                problem = (f"the machine reports the head OUT (head {head:.3f} mm) with the ring at {ring:.3f} "
                           f"deg, {off:.2f} deg from the nearest gap ({gap}|{(gap + 1) % machine.pins})")
                if op is None or op.jog is None or not hasattr(link, "jog"):
                    raise MachineFailure(f"{problem}: bringing it in there would hit a pin; turn the ring to a "
                                         "gap and bring the head IN by hand (or run without --yes in a terminal "
                                         "to be guided), then start again")
                note((ring, head), None)
                crossings(machine, (ring, head), bring_head_in(link, machine, op, problem[0].upper() + problem[1:]))
                here = link.position()
                if here is None or side(machine, float(here[1])) != "in":
                    raise MachineFailure("after the jogs the machine does not report the head IN; bring it IN "
                                         "through a gap, then start again")
                ring, head = float(here[0]), float(here[1])
        if abs(head - h_in) > tol[1]:
            log.info("first move: the head alone, %.3f -> %.3f mm", head, h_in)
            note((ring, head), (ring, h_in))
            link.move_to(ring, h_in, axis="head")
    if abs(ring - target[0]) > tol[0]:
        log.info("first move: the ring alone, %.3f -> %.3f deg", ring, target[0])
        note((ring, h_in), (target[0], h_in))
        link.move_to(target[0], h_in, axis="ring")
    return first
