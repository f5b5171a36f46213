"""Before a start homes: the head IN, or OUT at a gap, and the host sure of it.

Homing takes the head to its switch first (on the IN side: ``$H``, ``G28``,
``$HY`` for a head switch alone), then the ring to its own.  From a head OUT
with a pin in front of it that first move drags the eyelet across the pin.
So a start homes only from a position it has checked safe -- the head IN, or
OUT (or part way) with the ring at a gap -- and it knows that position from:

* **the firmware**, when it can vouch for it: a GRBL or grblHAL that did not
  just start (no start banner as the port opened), is not in alarm (a GRBL
  that homes starts in alarm: it does not know where it is) and does not read
  0 on every axis (what it reads when it starts) -- it has kept its position
  since it was last homed (by an earlier winding, say).  Marlin never vouches:
  it has no alarm for "not homed" and counts from wherever the axes stood when
  it started.  Anywhere unsafe,
  the start is refused before anything moves; at a terminal the operator is
  first offered the guided way to bring the head IN through a gap;
* otherwise **the operator**: ``--head-side in`` (a statement, after looking)
  or the question at a terminal (IN, OUT at a gap, or be guided).  ``--yes``
  never answers it.  A dry run's simulated operator looks at the simulated
  machine (``Operator.look``, which the command line gives a dry run).

The check is journaled (``{"kind": "homing", "from": ..., "how": ...}``) before
the first homing line, so a stop while homing leaves the machine on a path the
journal knows (the head going IN at a checked gap, then the ring with the head
IN): a resume homes again from there.
"""

import logging

from ..errors import BadInput, MachineFailure
from ..motion.safety import gap_offset_deg, side
from .guide import bring_head_in, crossings

__all__ = ["check_before_homing", "unsafe_to_home", "firmware_vouches"]

log = logging.getLogger(__name__)


def unsafe_to_home(machine, ring_deg, head_mm):
    """None where homing (the head first) is safe from ``(ring_deg, head_mm)``, else why not."""
    if side(machine, head_mm) == "in":
        return None
    gap, off = gap_offset_deg(machine, ring_deg)
    if off <= machine.gap_tolerance_deg:
        return None
    return (f"the head stands OUT (head {head_mm:.3f} mm) with the ring at {ring_deg:.3f} deg, {off:.2f} deg "
            f"from the nearest gap ({gap}|{(gap + 1) % machine.pins}): a pin is in front of it")


def firmware_vouches(link):
    """``(True, None)`` when the firmware's position can be trusted before homing, else
    ``(False, why)``."""
    from ..links.job_recovery import started
    info = getattr(link, "info", None)
    if getattr(info, "dialect", "") == "marlin":
        return False, ("Marlin knows no position before it homes: it counts from wherever the axes stood "
                       "when it started")
    if any(started(x) for x in (getattr(info, "lines", ()) or ())):
        return False, "it restarted as the port opened"
    st = link.status()
    if st.state == "Alarm":
        return False, "it is in alarm: it has not been homed since it started"
    if st.mpos is not None and all(abs(v) < 1e-9 for v in st.mpos):
        return False, "it reads 0 on every axis, as a firmware does when it starts"
    return True, None


def check_before_homing(link, machine, op, *, vouched=None, journal=None):
    """Make sure homing starts from a safe position; returns the ``homing`` record to journal.

    Parameters
    ----------
    link : a G-code step-level link (``status()``, ``position()``, ``jog()``)
    machine : Machine
    op : Operator (``head_side``, ``choose``, ``jog``, ``confirm``, ``say``; ``look``: a dry run's
        simulated operator's eyes on its world)
    vouched : ``False`` to skip the firmware (its position is known lost), None to ask it
    journal : Journal or None: the operator's jogs are journaled before they start

    Raises
    ------
    MachineFailure
        The firmware's position is unsafe and nobody can be guided (nothing moved).
    BadInput
        Nobody can say (``--yes`` without ``--head-side in``), or ``--head-side`` contradicts
        the firmware.
    """
    trusted, why = firmware_vouches(link) if vouched is None else (False, "it lost its position")
    if trusted:
        here = link.position()
        if here is not None:
            return _from_firmware(link, machine, op, tuple(here), journal)
        trusted, why = False, "it reports no position"
    stated = op.head_side
    if stated is None:
        stated = _simulated_operator(machine, op.look)
    if stated == "in" or stated == "gap":
        return {"from": None, "how": f"the operator: the head {'IN' if stated == 'in' else 'OUT at a gap'}"}
    if stated == "out":
        raise BadInput("--head-side out: homing brings the head IN first, which is safe from OUT only where a "
                       "gap faces it, and the host cannot see the ring; bring the head IN by hand (through a "
                       "gap), then give --head-side in, or run without --yes in a terminal to be asked")
    question = (f"Before homing: the firmware cannot say where the machine stands ({why}), and homing "
                "brings the head IN first, across a pin if one is in front of it.  Look at the thread head: "
                "is it IN (the eyelet inside the pin circle), or OUT with a gap between two pins in front of "
                "it (gap)?" + (" If neither, answer guide to jog it IN through a gap." if op.jog else ""))
    if op.choose is not None:
        answer = op.choose(question, ["in", "gap"] + (["guide"] if op.jog else []))
        if answer in ("in", "gap"):
            return {"from": None, "how": f"the operator: the head {'IN' if answer == 'in' else 'OUT at a gap'}"}
        _jogging(journal, None)
        _unlock(link)
        bring_head_in(link, machine, op, "Before homing: the head is neither IN nor at a gap")
        return {"from": None, "how": "the operator jogged the head IN (guided)"}
    raise BadInput(f"before homing, the firmware cannot say where the machine stands ({why}), so only you "
                   "can say whether homing is safe (it brings the head IN first, across a pin if one is in "
                   "front of it): look, and if the head is IN add --head-side in; otherwise bring it IN by "
                   "hand through a gap, or run without --yes in a terminal to be guided")


def _unlock(link):
    """A GRBL in alarm takes no jog: unlock it first (``$X``: nothing moves)."""
    if getattr(link, "unlock", None) is not None:
        link.unlock()


def _jogging(journal, here):
    """Journal that the operator is about to jog the machine (from ``here``, if known)."""
    if journal is not None:
        journal.append({"kind": "approach", "from": None if here is None else [float(v) for v in here],
                        "to": None})


def _from_firmware(link, machine, op, here, journal=None):
    """The firmware's position, trusted: safe, or guided IN, or refused."""
    problem = unsafe_to_home(machine, *here)
    if op.head_side is not None and op.head_side != side(machine, here[1]).replace("on", "out"):
        raise BadInput(f"--head-side {op.head_side} contradicts the machine's own report: its head stands at "
                       f"{here[1]:.3f} mm ({side(machine, here[1]).upper()}); look again (leave out --head-side)")
    if problem is None:
        return {"from": [float(v) for v in here], "how": "the firmware's position"}
    if op.jog is None:
        raise MachineFailure(f"before homing: the machine reports {problem}; homing brings the head IN first "
                             "and would drag it across that pin: turn the ring until a gap faces the head and "
                             "bring the head IN by hand (or run without --yes in a terminal to be guided), then "
                             "start again")
    _jogging(journal, here)
    _unlock(link)
    jogs = bring_head_in(link, machine, op, f"Before homing: the machine reports {problem}")
    crossings(machine, here, jogs)              # a crossing away from a gap is refused
    now = link.position()
    if now is None or side(machine, now[1]) != "in":
        raise MachineFailure("after the jogs the machine does not report the head IN; bring it IN through a "
                             "gap, then start again")
    return {"from": [float(v) for v in now], "how": "the firmware's position, after the operator's jogs"}


def _simulated_operator(machine, look):
    """A dry run's operator, looking at the simulated machine: "in", "gap" or None (cannot say)."""
    seen = look() if look is not None else None
    if seen is None:
        return None
    ring, head = seen
    if side(machine, head) == "in":
        return "in"
    return "gap" if unsafe_to_home(machine, ring, head) is None else None
