"""The first move of a winding or of a resume: from where the machine reports standing.

Before the first planned move the machine is asked where it stands.  The head
goes IN alone first (through the gap the ring stands at, if it is OUT), then
the ring turns alone to the job's start with the head IN: no move combines the
two, and the head never crosses the pin circle away from a gap.  A head that
reports OUT with the ring away from any gap is refused: no move can bring it
in safely, the operator must.
"""

import logging

from ..errors import MachineFailure
from ..motion.safety import gap_offset_deg, side

__all__ = ["approach"]

log = logging.getLogger(__name__)


def approach(link, machine, target, tol):
    """Bring the machine from where it reports standing to ``target`` ``(ring_deg, head_mm IN)``.

    Parameters
    ----------
    link : a step-level link (``position()``, ``move_to(ring, head, axis=)``)
    machine : Machine
    target : (float, float)
    tol : (float, float) how far a reported position may be from a point reached

    Returns
    -------
    (float, float) where the machine reported standing before the approach.
    """
    here = link.position()
    if here is None:
        raise MachineFailure("the machine reports no position; check it, then start again")
    ring, head = float(here[0]), float(here[1])
    h_in = machine["head.in_mm"]
    if abs(head - h_in) > tol[1]:
        if side(machine, head) != "in":
            gap, off = gap_offset_deg(machine, ring)
            if off > machine.gap_tolerance_deg:
                raise MachineFailure(
                    f"the machine reports the head OUT (head {head:.3f} mm) with the ring at {ring:.3f} deg, "
                    f"{off:.2f} deg from the nearest gap ({gap}|{(gap + 1) % machine.pins}): bringing it in "
                    "there would hit a pin; turn the ring to a gap and bring the head IN by hand, then "
                    "start again")
        log.info("first move: the head alone, %.3f -> %.3f mm", head, h_in)
        link.move_to(ring, h_in, axis="head")
    if abs(ring - target[0]) > tol[0]:
        log.info("first move: the ring alone, %.3f -> %.3f deg", ring, target[0])
        link.move_to(target[0], h_in, axis="ring")
    return (ring, head)
