"""Machine units <-> servo ticks for a Dynamixel machine, and the bounds they must keep.

Ring: ticks = ring_deg / 360 * gear_ratio * ticks_per_turn, the Goal Position
of a servo in Extended Position Control Mode (-1,048,575..1,048,575 ticks).
Head: ticks map linearly head_in_ticks..head_out_ticks <->
head.in_mm..head.out_mm (Position Control Mode, one turn).
"""

import math

from firmware_protocol import dynamixel as dx

from ..errors import BadInput

__all__ = ["ServoAxes"]


class ServoAxes:
    """Conversions, the travel check and the arrival tolerances of one Dynamixel machine.

    Raises
    ------
    BadInput
        When ``ring.travel_deg`` would take the ring servo beyond its extended-position
        range (less one turn, for the re-base after a power loss).
    """

    def __init__(self, machine):
        self.machine = machine
        c = lambda key: machine[f"controller.{key}"]
        self.tpt, self.gear = c("ticks_per_turn"), c("gear_ratio")
        self.head_in, self.head_out = c("head_in_ticks"), c("head_out_ticks")
        self.in_mm, self.out_mm = machine["head.in_mm"], machine["head.out_mm"]
        self._check_travel()
        #: a servo within this many ticks of its goal, not moving, has arrived
        self.ring_arrival = max(1, int(self.ring_ticks(machine.gap_tolerance_deg) / 4))
        self.head_arrival = max(1, abs(self.head_out - self.head_in) // 100)

    def ring_ticks(self, ring_deg):
        return round(ring_deg / 360.0 * self.gear * self.tpt)

    def ring_deg(self, ticks):
        return ticks / self.tpt * 360.0 / self.gear

    def head_ticks(self, head_mm):
        return round(self.head_in + (head_mm - self.in_mm) * (self.head_out - self.head_in)
                     / (self.out_mm - self.in_mm))

    def head_mm(self, ticks):
        return self.in_mm + (ticks - self.head_in) * (self.out_mm - self.in_mm) / (self.head_out - self.head_in)

    def inside(self, head_ticks):
        """Head on the IN side of the pin circle (midway IN..OUT)."""
        return abs(head_ticks - self.head_in) < abs(head_ticks - self.head_out)

    @property
    def tolerance(self):
        """(ring_deg, head_mm): how far a position read back may be from a point the servos
        arrived at (the arrival tolerance plus half a tick of rounding)."""
        return ((self.ring_arrival + 0.5) / self.tpt * 360.0 / self.gear,
                (self.head_arrival + 0.5) * abs(self.out_mm - self.in_mm) / abs(self.head_out - self.head_in))

    def _check_travel(self):
        m = self.machine
        pin0, travel = m["ring.pin0_angle_deg"], m["ring.travel_deg"]
        worst = max(abs(self.ring_ticks(pin0 - travel)), abs(self.ring_ticks(pin0 + travel)))
        if worst + self.tpt > dx.EXTENDED_POSITION_MAX:
            limit = (dx.EXTENDED_POSITION_MAX - self.tpt) / self.tpt / self.gear * 360.0 - abs(pin0)
            raise BadInput(
                f"{m.path}: ring.travel_deg = {travel:g} takes the ring servo to {worst} ticks, beyond "
                f"its extended-position range of +-{dx.EXTENDED_POSITION_MAX} (less one turn); expected "
                f"ring.travel_deg <= {math.floor(limit)} with gear_ratio = {self.gear:g}")
