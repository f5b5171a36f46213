"""The Dynamixel link's moves: each Move written as Goal Position(s), then waited for until the servos are there.

A move returns only when the servos that move report Moving = 0 within their
arrival tolerance of the goal (one read, or one sync read when both move); a
servo that loses torque on the way, reports a hardware error or does not
arrive in time (twice the profile's time plus the slack) is one
:class:`~stringbot.errors.MachineFailure`.  Both axes move together only while
the head stays on the IN side, so servos that do not interpolate never cross
the pin circle away from a gap.
"""

import time

from firmware_protocol import dynamixel as dx

from .base import LinkState
from .dynamixel_bus import poll_field

__all__ = ["ServoMoves"]


class ServoMoves:
    """The moves of :class:`~stringbot.links.dynamixel.DynamixelLink` (whose ``__init__`` sets what they
    use: ``machine``, ``bus``, ``axes``, ``ids``, ``role``, ``goal``, ``present``, ``where``, the unit
    conversions, the arrival tolerances and ``_fail``)."""

    def run_step(self, step, *, moves=None, on_executed=None):
        """Execute one :class:`~stringbot.motion.HookStep` (or the rest of it: ``moves``)."""
        self.where = (step.index + 1, step.pin)       # people count steps from 1
        moves = step.moves if moves is None else moves
        first = len(step.moves) - len(moves)
        self._step_index = step.index
        for k, move in enumerate(moves):
            self._move_index = first + k
            self.move_to(move.ring_deg, move.head_mm)
            if self.on_move is not None:
                self.on_move(step, first + k)
        self._move_index = len(step.moves)            # all arrived; not yet handed over
        if step.dwell_s:
            time.sleep(step.dwell_s)
        if on_executed is not None:
            on_executed(step)
        else:
            self._executed.append(step)
        self._step_index, self._move_index = step.index + 1, 0

    def move_to(self, ring_deg, head_mm, *, axis=None):
        """Write the goals that change and wait until both servos are there.

        Both axes move together (one sync write) only while the head stays on the
        IN side; otherwise the head goes IN first, or OUT last, so that servos that
        do not interpolate never cross the pin circle away from a gap.
        """
        ring, head = self.ids["ring"], self.ids["head"]
        goals = {ring: self.ring_ticks(ring_deg), head: self.head_ticks(head_mm)}
        self._remember(ring_deg, head_mm)
        if not dx.EXTENDED_POSITION_MIN <= goals[ring] <= dx.EXTENDED_POSITION_MAX:
            raise self._fail(f"ring goal {ring_deg:.3f} deg = {goals[ring]} ticks is outside the servo's "
                             f"extended-position range +-{dx.EXTENDED_POSITION_MAX}")
        if not 0 <= goals[head] < self.tpt:
            raise self._fail(f"head goal {head_mm:.3f} mm = {goals[head]} ticks is outside one servo turn")
        changed = {i: g for i, g in goals.items() if g != self.goal.get(i)}
        if len(changed) == 2 and not (self.axes.inside(self.goal[head]) and self.axes.inside(goals[head])):
            order = (head, ring) if self.axes.inside(goals[head]) else (ring, head)
            for servo_id in order:
                self._go({servo_id: goals[servo_id]})
        elif changed:
            self._go(changed)

    def _go(self, changed):
        self.state = LinkState.STREAMING
        start = dict(self.present)
        self.bus.write_goals(changed)
        self.goal.update(changed)
        self._wait(changed, start)
        self.state = LinkState.READY

    def _estimate_s(self, distance_ticks):
        v = (self.machine["controller.profile_velocity"] or self._velocity_limit or 1023) * 0.229 / 60.0 * self.tpt
        a_units = self.machine["controller.profile_acceleration"]
        ramp = v / (a_units * 214.577 / 3600.0 * self.tpt) if a_units else 0.0
        return distance_ticks / v + ramp

    def _wait(self, changed, start):
        worst = max(abs(g - start.get(i, g)) for i, g in changed.items())
        deadline = time.monotonic() + 2.0 * self._estimate_s(worst) + self.arrival_slack_s
        tol = self._arrival_ticks
        while True:
            table = self._poll(changed)            # the servos that move (a sync read when both do)
            arrived, limp = True, []
            for servo_id, data in table.items():
                hw = poll_field(data, "Hardware Error Status")
                if hw:
                    raise self.bus.hardware_failure(servo_id, hw)
                if not poll_field(data, "Torque Enable"):
                    limp.append(self._name(servo_id))
                if poll_field(data, "Moving") or abs(self.present[servo_id] - self.goal[servo_id]) > tol[servo_id]:
                    arrived = False
            if limp:
                self.position_lost = True
                moving = " and ".join(f"the {self.role[i]} from {start.get(i)} to {g} ticks"
                                      for i, g in changed.items())
                raise self._fail(f"{' and '.join(limp)} lost torque (power loss or reboot?) while moving "
                                 f"{moving}; a position may be re-based to one turn: resume to continue")
            if arrived:
                return
            if time.monotonic() > deadline:
                late = ", ".join(f"{self._name(i)} at {self.present[i]} for goal {self.goal[i]}"
                                 for i in table if abs(self.present[i] - self.goal[i]) > tol[i])
                raise self._fail(f"move did not arrive in time: {late or 'still moving'}")

    def _poll(self, ids=None):
        """Torque, errors, Moving and positions of the servos ``ids`` (default both)."""
        table = self.bus.poll(list(self.ids.values()) if ids is None else list(ids))
        for servo_id, data in table.items():
            if poll_field(data, "Torque Enable"):   # torque off: the position may be re-based
                self.present[servo_id] = poll_field(data, "Present Position")
        return table
