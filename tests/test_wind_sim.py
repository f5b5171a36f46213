"""End to end: plan -> wind -> the simulated world's wraps equal the plan's sequence.

Through ``sim://`` (the same pyserial code path as a real port) for every
bundled machine (tests/bundled.py), with small hand-made plans on the 300-pin rings.
"""

import json

import numpy as np
import pytest

from firmware_protocol.machine import load_machine
from stringbot.errors import BadInput, MachineFailure
from stringbot.links import open_link, sim_url
from stringbot.motion import hook_steps
from stringbot.planner import Plan
from stringbot.winding import Journal, Winder, read_journal

from bundled import GCODE_MACHINES, MACHINES


def eyes_at(url):
    """An in-process simulated machine's operator, looking at it: where its world's ring and head
    stand (what a start that homes asks when the firmware cannot say)."""
    from firmware_protocol.urlhandler import protocol_sim
    return lambda: protocol_sim.look(url)


def small_plan(pins=300, sequence=None, seed=1, n=24):
    a = np.arange(pins) * 2 * np.pi / pins
    xy = np.stack([0.5 + 0.5 * np.sin(a), 0.5 - 0.5 * np.cos(a)], axis=1)
    if sequence is None:
        rng = np.random.default_rng(seed)
        sequence = [0]
        while len(sequence) < n:
            nxt = int(rng.integers(pins))
            if nxt != sequence[-1]:
                sequence.append(nxt)
    return Plan(pins=pins, frame="circle", pin_xy=xy, crop={"cx": 50, "cy": 50, "r": 50},
                sequence=list(sequence), method="hand", parameters={}, stats={"lines": len(sequence) - 1},
                source={"path": "x.png", "sha256": "0" * 64, "width": 100, "height": 100})


class EmulatorPort:
    """An emulator behind the pyserial surface the links use (virtual time jumps on a dry read)."""

    def __init__(self, emulator):
        self.emu, self.buf = emulator, bytearray()

    @property
    def in_waiting(self):
        self.buf += self.emu.transmit()
        return len(self.buf)

    def write(self, data):
        self.emu.receive(bytes(data))
        return len(data)

    def read(self, n=1):
        self.buf += self.emu.transmit()
        while not self.buf and self.emu.busy:
            self.emu.advance(None)
            self.buf += self.emu.transmit()
        out = bytes(self.buf[:n])
        del self.buf[:n]
        return out

    def close(self):
        pass


def emulator_link(name, faults=None):
    """A link straight onto the emulator object (no URL), and the world it drives."""
    from firmware_protocol.emulators.factory import build_emulator
    from stringbot.links import gcode_machine_link
    machine = load_machine(name)
    emu, world = build_emulator(machine, faults=faults)
    return gcode_machine_link(EmulatorPort(emu), machine), world, emu


def wraps_of(record_path):
    rec = json.loads(open(record_path).read())
    return [w["pin"] for w in rec["wraps"]], rec["collisions"]


@pytest.mark.parametrize("name", MACHINES)
def test_wind_through_sim_equals_the_plan(tmp_path, name):
    machine = load_machine(name)
    plan = small_plan()
    steps = hook_steps(plan, machine)
    record = tmp_path / "rec.json"
    link = open_link(sim_url(name, record=record), machine)
    journal = Journal.create(tmp_path / "j", plan_path="p", plan_sha256=plan.sha256(),
                             machine=name, steps=len(steps))
    seen = []
    try:
        w = Winder(link, steps, machine, journal=journal, progress=seen.append)
        w.start(home=machine["controller.homing"])
        result = w.wind(0)
    finally:
        link.close()
        journal.close()
    pins, collisions = wraps_of(record)
    assert pins == plan.sequence
    assert collisions == []
    assert result.steps_done == len(steps)
    assert [p.done for p in seen] == list(range(1, len(steps) + 1))
    state = read_journal(tmp_path / "j")
    assert state.done == list(range(len(steps))) and state.finished


def test_wrong_dialect_is_refused_through_sim(tmp_path):
    marlin = load_machine("marlin-ring")
    link = open_link(sim_url("grbl-ring"), marlin)
    try:
        with pytest.raises(MachineFailure, match="runs GRBL"):
            link.identify()
    finally:
        link.close()


def test_port_that_does_not_exist_is_bad_input():
    with pytest.raises(BadInput, match="does not exist"):
        open_link("/dev/ttyNOPE_stringbot", load_machine("grbl-ring"))


@pytest.mark.parametrize("name", GCODE_MACHINES)
def test_wind_on_the_emulator_equals_the_plan(tmp_path, name):
    machine = load_machine(name)
    plan = small_plan(n=30, seed=4)
    steps = hook_steps(plan, machine)
    link, world, _ = emulator_link(name)
    journal = Journal.create(tmp_path / "j", plan_path="p", plan_sha256=plan.sha256(),
                             machine=name, steps=len(steps))
    w = Winder(link, steps, machine, journal=journal)
    w.start(home=machine["controller.homing"])
    result = w.wind(0)
    journal.close()
    assert [x.pin for x in world.wraps] == plan.sequence
    assert world.collisions == []
    assert result.steps_done == 30 and read_journal(tmp_path / "j").finished
    if hasattr(link.proto, "max_inflight_bytes"):   # character counting: within the receive buffer
        assert link.proto.max_inflight_bytes <= link.proto.rx_size


def test_error_from_the_emulator_stops_with_pin_and_step(tmp_path):
    machine = load_machine("grbl-ring")
    plan = small_plan(n=20, seed=5)
    steps = hook_steps(plan, machine)
    link, world, _ = emulator_link("grbl-ring", faults="error@40")
    journal = Journal.create(tmp_path / "j", plan_path="p", plan_sha256=plan.sha256(),
                             machine="grbl-ring", steps=len(steps))
    w = Winder(link, steps, machine, journal=journal)
    w.start(home=False)
    with pytest.raises(MachineFailure, match=r"error:20.*pin \d+, step \d+"):
        w.wind(0)
    journal.close()
    state = read_journal(tmp_path / "j")
    assert state.last_stop["reason"] == "failed"
    # the journal holds only executed steps: all of them are among the world's wraps, in order
    assert [x.pin for x in world.wraps][:len(state.done)] == [plan.sequence[i] for i in state.done]
