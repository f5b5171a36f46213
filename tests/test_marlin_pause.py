"""The simulated Marlin's M0: a colour job's spool change pauses the machine until the operator
continues (M108, which Marlin's emergency parser acts on ahead of the queue)."""

import pytest

from firmware_protocol.emulators.marlin import MarlinEmulator
from firmware_protocol.emulators.testing import run_exchange
from firmware_protocol.machine import load_machine
from firmware_protocol.world import World
from stringbot.motion import gcode_job
from test_colour_plan import colour_plan
from test_gcode_on_emulators import send

pytestmark = pytest.mark.timeout(60)

OK = b"ok\n"
PAUSED = b"echo:busy: paused for user\n"


def emulator():
    m = load_machine("marlin-ring")
    emu = MarlinEmulator(m, world=World(m))
    emu.transmit()                          # the banner
    return emu


def test_m0_waits_for_m108_with_paused_for_user_every_two_seconds():
    emu = emulator()
    emu.receive(b"M0\n")
    assert emu.transmit() == b""            # no ok: waiting for the operator
    emu.advance(4.5)
    assert emu.transmit() == PAUSED * 2
    run_exchange(emu, [(b"M108\n", OK + OK)])   # M0 done, then the M108 line itself


def test_m0_with_a_time_ends_by_itself():
    emu = emulator()
    run_exchange(emu, [(b"M0 S3\n", PAUSED + OK)])


def test_a_colour_job_pauses_at_each_spool_change_and_winds_the_rest_after_m108():
    machine = load_machine("marlin-ring")
    emu = MarlinEmulator(machine, world=World(machine))
    world = emu.world
    emu.transmit()
    plan = colour_plan(pins=300, n=(12, 9, 6))
    ends = [len(plan.layers[0].sequence), len(plan.layers[0].sequence) + len(plan.layers[1].sequence)]
    lines = [raw.split(";", 1)[0].strip() for raw in gcode_job(plan, machine).splitlines()]
    pauses = 0
    for line in filter(None, lines):
        if line != "M0":
            assert "ok" in send(emu, line), line
            continue
        emu.receive(b"M0\n")
        emu.advance(10.0)                   # time passes: the machine stays paused
        out = emu.transmit()
        assert b"ok" not in out and PAUSED in out
        assert len(world.wraps) == ends[pauses]     # this layer wound, nothing of the next one
        emu.receive(b"M108\n")
        assert emu.transmit().count(b"ok") == 2
        pauses += 1
    assert pauses == 2
    assert [w.pin for w in world.wraps] == [int(p) for p in plan.sequence]
    assert world.collisions == []
