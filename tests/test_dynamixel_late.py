"""Servos that answer late (a loaded computer running the simulator, a slow USB adapter): the
link's retries wait longer each time, so an answer 150 ms late is caught, not missed four times."""

import time

import pytest

from firmware_protocol.emulators.dynamixel import DynamixelEmulator
from firmware_protocol.machine import load_machine
from firmware_protocol.world import World
from stringbot.errors import MachineFailure
from stringbot.links.dynamixel import DynamixelLink
from test_dynamixel_sdk import PtyServer


class LateEmulator(DynamixelEmulator):
    """The emulator, its answers held back ``late_s`` seconds of wall-clock time."""

    late_s = 0.15

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self._held = []                 # (due, bytes)

    def transmit(self):
        out = super().transmit()
        now = time.monotonic()
        if out:
            self._held.append((now + self.late_s, out))
        due = b"".join(b for t, b in self._held if t <= now)
        self._held = [(t, b) for t, b in self._held if t > now]
        return due


def late_server(late_s):
    machine = load_machine("dynamixel-ring")
    world = World(machine)
    emu = LateEmulator(machine, world=world, realtime=False)
    emu.late_s = late_s
    return PtyServer(emu, idle_s=0.005), machine, world


@pytest.mark.realtime
def test_answers_150_ms_late_are_caught_by_the_retries():
    server, machine, world = late_server(0.15)
    link = DynamixelLink(machine, server.path)
    try:
        link.connect()
        link.prepare()
        link.move_to(90.0, 12.0)
        assert (world.ring_deg, world.head_mm) == (pytest.approx(90.0), pytest.approx(12.0))
        assert link.bus.retried > 0              # the first attempts did time out
    finally:
        link.close()
        server.close()


def test_a_servo_later_than_every_grace_still_fails_with_one_line():
    server, machine, _world = late_server(2.0)             # later than every retry's grace (0.75 s in all)
    link = DynamixelLink(machine, server.path)
    try:
        with pytest.raises(MachineFailure, match="COMM_RX_TIMEOUT after 4 attempts"):
            link.connect()
    finally:
        link.close()
        server.close()


@pytest.mark.realtime
def test_a_fault_at_move_n_strikes_move_n_however_often_the_host_retries():
    """Late answers (a loaded computer) make the link write a Goal Position again; the servo moving
    to that goal already is still on the same move, so ``power@11`` strikes the pitch turn of step 2
    (the head OUT) as on an idle computer, and the resume from the stop record is exact (it counted
    every retried write as a move: ``power@39`` struck the head's move of step 4, not step 9's turn)."""
    from stringbot.motion import hook_steps
    from dynamixel_helpers import PLANS, resume
    from test_gcode_replay import make_plan

    machine = load_machine("dynamixel-ring")
    world = World(machine)
    emu = LateEmulator(machine, world=world, realtime=False, faults="power@11")
    emu.late_s = 0.04                                   # later than a first attempt waits (35 ms)
    server = PtyServer(emu, idle_s=0.005)
    plan = make_plan(PLANS["long jumps"])
    try:
        link = DynamixelLink(machine, server.path)
        link.identify()
        steps = hook_steps(plan, machine, start_ring_deg=link.prepare()[0])
        with pytest.raises(MachineFailure, match="lost torque"):
            link.execute(steps)
        stop = link.stop_point()
        assert link.bus.retried > 0
        link.close()
        assert (stop["step_index"], stop["move"]) == (2, 2) and world.head_out
        emu.late_s = 0.0                                # the rest at full speed: only the fault's place matters
        resume(server, machine, steps, stop, declare=True)
    finally:
        server.close()
    assert world.collisions == [] and [w.pin for w in world.wraps] == plan.sequence
