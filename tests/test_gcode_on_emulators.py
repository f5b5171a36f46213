"""The written G-code job, sent line by line to the simulated firmware (send-response).

Every line must be accepted (no ``error:``, no ``Unknown command``), the
world behind the emulator must record exactly the plan's wraps with zero
collisions, and the firmware's virtual time must agree with ``estimate``.
Skipped for a dialect whose emulator is not there yet.
"""

import pytest

from firmware_protocol.machine import load_machine
from stringbot.motion import estimate, gcode_job
from test_gcode_replay import GCODE_MACHINES, PLANS, make_plan, random_sequence


def emulator_for(machine):
    factory = pytest.importorskip("firmware_protocol.emulators.factory")
    try:
        emu, world = factory.build_emulator(machine)
    except (factory.SimulatorError, ImportError) as exc:
        pytest.skip(f"no emulator for {machine.name}: {exc}")
    return emu, world


def send(emu, line, max_events=100000):
    """Send one line and collect the answer up to its ``ok``."""
    emu.receive((line + "\n").encode())
    out = bytearray(emu.transmit())
    events = 0
    while b"ok" not in out and events < max_events:
        if not emu.busy:
            break
        emu.advance(None)
        out += emu.transmit()
        events += 1
    return out.decode(errors="replace")


@pytest.mark.parametrize("name", GCODE_MACHINES)
def test_job_runs_on_the_emulated_firmware(name):
    machine = load_machine(name)
    emu, world = emulator_for(machine)
    # let the firmware boot (banner), then start the clock
    for _ in range(100):
        if not emu.busy:
            break
        emu.advance(None)
    emu.transmit()
    plan = make_plan(PLANS["seam"] + random_sequence(60, seed=4))
    t0 = emu.now
    refused = []
    for raw in gcode_job(plan, machine).splitlines():
        line = raw.split(";", 1)[0].strip()
        if not line:
            continue
        answer = send(emu, line)
        if "error" in answer.lower() or "unknown command" in answer.lower() or "ok" not in answer:
            refused.append((line, answer))
    assert refused == []
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    est = estimate(plan, machine)
    assert emu.now - t0 == pytest.approx(est.seconds, rel=0.05, abs=2.0)
