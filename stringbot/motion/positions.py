"""How exactly a machine can report where it stands: position tolerances from its steps.

A stepper firmware moves in whole steps and reports the step count divided by
its steps per unit, printed with a few decimals: after ``G0 X5`` at 44.4444
steps per degree GRBL reports ``MPos:4.995`` (222 steps), not ``5.000``.  So a
position read back may differ from the point the host planned by up to one
step of the axis (half a step of rounding to the nearest step, and the other
half for the firmware's own rounding of the work offset and of the move's
end), plus half the last printed digit, plus float32 rounding of a large
value (GRBL computes positions in single precision).

The step comes from the firmware's own setting when the host has read it
(GRBL/grblHAL ``$100``.. ``$105``), else from the machine file
(``ring.steps_per_deg``, ``head.steps_per_mm``).  An axis whose steps are not
known gets :data:`UNKNOWN_STEP`, a coarse step that still lies well inside
the gap tolerance of any machine whose pins fit.
"""

import math

__all__ = ["position_tolerance", "UNKNOWN_STEP", "FLOAT32_EPS"]

#: Axis units (degrees or mm) assumed for one step when no steps-per-unit figure is known.
UNKNOWN_STEP = 0.05
#: Relative rounding of a single-precision float (GRBL computes positions in float32).
FLOAT32_EPS = 2.0 ** -23


def _step(steps_per_unit):
    if steps_per_unit is None:
        return UNKNOWN_STEP
    steps_per_unit = float(steps_per_unit)
    if not math.isfinite(steps_per_unit) or steps_per_unit <= 0:
        return UNKNOWN_STEP
    return 1.0 / steps_per_unit


def position_tolerance(machine, *, ring_steps=None, head_steps=None, decimals=3):
    """``(ring_deg, head_mm)``: how far a reported position may be from a point reached.

    Parameters
    ----------
    machine : firmware_protocol.machine.Machine
    ring_steps, head_steps : float, optional
        Steps per unit the firmware reported (its ``$100``...); default: the
        machine file's ``ring.steps_per_deg`` / ``head.steps_per_mm`` when set.
    decimals : int
        Decimals the firmware prints positions with (GRBL 3, Marlin's ``M114`` 2).

    Returns
    -------
    tuple of float
        One step of each axis, plus half a printed digit, plus float32 rounding
        at the largest position the axis reaches (twice: position and offset).
    """
    values = machine.values
    if ring_steps is None:
        ring_steps = values.get("ring.steps_per_deg")
    if head_steps is None:
        head_steps = values.get("head.steps_per_mm")
    printed = 0.5 * 10.0 ** -int(decimals)
    ring_reach = abs(values["ring.pin0_angle_deg"]) + values["ring.travel_deg"]
    head_reach = max(abs(values["head.in_mm"]), abs(values["head.out_mm"]))
    ring = _step(ring_steps) + printed + 2.0 * FLOAT32_EPS * ring_reach
    head = _step(head_steps) + printed + 2.0 * FLOAT32_EPS * head_reach
    return (ring, head)
