"""Never believe a move you did not see: the machine's own report is checked after every move.

A firmware that answers ``ok`` to a line without executing it is emulated here by a
test-only subclass of the GRBL emulator (the G1 line number ``skip`` is acknowledged and
dropped); the host must stop within the step, with exit-1's MachineFailure, and journal
nothing the machine did not do.
"""

import pytest

from firmware_protocol.emulators.grbl import GrblEmulator
from firmware_protocol.machine import load_machine
from firmware_protocol.world import World
from stringbot.errors import MachineFailure
from stringbot.links import gcode_machine_link
from stringbot.motion import hook_steps
from stringbot.winding import Journal, Winder, read_journal

from planner_helpers import for_machine
from test_wind_sim import EmulatorPort, eyes_at, small_plan


class SkippingGrbl(GrblEmulator):
    """Answers ``ok`` to the ``skip``-th G1 line without executing it."""

    def __init__(self, machine, *, world, skip):
        super().__init__(machine, world=world)
        self.skip, self.g1 = skip, 0

    def _execute(self, text, overflow):
        if text.startswith("G1"):
            self.g1 += 1
            if self.g1 == self.skip:
                return 0
        return super()._execute(text, overflow)


def wind_with_a_skipped_line(tmp_path, skip, sync="move"):
    machine = load_machine("grbl-ring")
    plan = small_plan(n=6, seed=8)
    steps = hook_steps(plan, machine)
    world = World(machine)
    link = gcode_machine_link(EmulatorPort(SkippingGrbl(machine, world=world, skip=skip)), machine,
                              sync=sync)
    journal = Journal.create(tmp_path / "j", plan_path="p", plan_sha256=plan.sha256(),
                             machine="grbl-ring", steps=len(steps))
    w = Winder(link, steps, machine, journal=journal)
    w.start(home=False)
    with pytest.raises(MachineFailure) as err:
        w.wind(0)
    journal.close()
    return plan, steps, world, read_journal(tmp_path / "j"), str(err.value), link


# the G1 lines: step 1 has 5 moves (head IN first), then 4 per step: 7 = step 2's head OUT,
# 8 its pitch turn, 10 step 3's approach; a step-boundary check alone would miss a skipped
# head OUT (the step still ends where planned, with no pin wrapped)
@pytest.mark.parametrize("skip, step, move", [(7, 2, 2), (8, 2, 3), (10, 3, 1)])
def test_a_line_acknowledged_but_not_executed_stops_the_winding(tmp_path, skip, step, move):
    plan, steps, world, state, message, link = wind_with_a_skipped_line(tmp_path, skip)
    assert "acknowledged but not executed" in message and f"step {step}" in message
    assert f"move {move} of step {step}" in message
    # journaled: exactly the steps before, and none of the unseen move
    assert state.done == list(range(step - 1))
    assert state.next_step == step - 1 and state.next_move <= move - 1
    assert state.last_stop["at"] == {"step_index": step - 1, "move": move - 1}
    assert [w.pin for w in world.wraps] == plan.sequence[:step - 1]
    assert world.collisions == []
    # the stop record keeps where the machine reported it stood (the start of the skipped move)
    start = steps[step - 1].moves[move - 2] if move > 1 else steps[step - 2].moves[-1]
    assert state.last_stop["position"] == [pytest.approx(start.ring_deg, abs=0.05),
                                           pytest.approx(start.head_mm, abs=0.05)]


def test_streaming_steps_checks_every_steps_end(tmp_path):
    """The library's streaming mode (one sync per step, not what ``wind`` uses) checks each
    step's end: a skipped pitch turn leaves step 2 a pitch away from its planned end."""
    plan, steps, world, state, message, link = wind_with_a_skipped_line(tmp_path, 8, sync="step")
    assert "acknowledged but not executed" in message and "after step 2" in message
    assert state.done == [0]                         # step 2 ended elsewhere: not journaled


def test_every_move_is_checked(tmp_path):
    machine = load_machine("grbl-ring")
    plan = small_plan(n=5, seed=8)
    steps = hook_steps(plan, machine)
    world = World(machine)
    link = gcode_machine_link(EmulatorPort(GrblEmulator(machine, world=world)), machine)
    w = Winder(link, steps, machine)
    w.start(home=False)
    w.wind(0)
    assert link.checks == sum(len(s.moves) for s in steps)
    assert [x.pin for x in world.wraps] == plan.sequence


def _grbl(tmp_path, n=4):
    machine = load_machine("grbl-ring")
    plan = small_plan(n=n, seed=9)
    world = World(machine)
    link = gcode_machine_link(EmulatorPort(GrblEmulator(machine, world=world)), machine)
    return machine, plan, world, link


def test_the_first_move_brings_the_head_in_alone_then_turns_the_ring(tmp_path):
    """Left with the head OUT at a gap (ring 30.6 deg: gap 25|26), a new winding first asks where
    the machine is, brings the head IN alone there, then turns the ring alone: no collision."""
    from stringbot.winding import Job, wind_plan
    from stringbot.planner import write_plan
    machine, plan, world, link = _grbl(tmp_path)
    link.identify()
    link.proto.prepare(preamble=["G21", "G90"])
    link.proto.run_lines(["G1 X30.6 F7200"], link.proto.where)
    link.proto.run_lines(["G1 Y12 F3000"], link.proto.where)     # out through the gap
    assert world.head_out and world.collisions == []
    sent = []
    write = link.proto.port.write
    link.proto.port.write = lambda data: sent.append(bytes(data)) or write(data)
    import stringbot.winding.session as session
    write_plan(plan, tmp_path / "p.json")
    job = Job(tmp_path / "p.json", machine, port="sim://", journal=tmp_path / "j")
    opened = session.open_link
    session.open_link = lambda *a, **k: link
    try:
        wind_plan(job, confirm=None, eyes=eyes_at(job.url))
    finally:
        session.open_link = opened
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    moves = [x for x in b"".join(sent).decode().replace("?", "").split("\n") if x.startswith("G1")]
    assert moves[:2] == ["G1 Y0 F3000", "G1 X0 F7200"]          # the head alone, then the ring alone


def test_a_head_out_away_from_a_gap_is_refused_before_any_move(tmp_path):
    from stringbot.winding.approach import approach
    from stringbot.winding.locate import tolerance
    machine, plan, world, link = _grbl(tmp_path)
    link.identify()
    link.proto.prepare(preamble=["G21", "G90"])
    link.set_position(30.0, 12.0)                 # the firmware believes: head OUT facing pin 25
    with pytest.raises(MachineFailure, match="head OUT .* would hit a pin"):
        approach(link, machine, (0.0, 0.0), tolerance(link))
    assert world.moves == 0


# the lines of the first steps each machine's firmware receives (after identification, the
# settings and the preamble): points on a move line and on its sync line
IGNORED = {"grbl-ring": [20, 21, 23, 26], "grblhal-ring": [22, 23, 25, 28], "marlin-ring": [16, 17, 19, 22]}


@pytest.mark.parametrize("name, n", [(name, n) for name, ns in IGNORED.items() for n in ns])
def test_a_firmware_that_acknowledges_without_executing_is_caught(tmp_path, name, n):
    """``ignore@N`` (the simulator answers ``ok`` to line N and does nothing): the winding stops
    within the step (exit 1) -- or, where the ignored line was a sync whose move still ran,
    goes on having seen the machine arrive -- and the journal holds only what the world did."""
    import json
    from stringbot.cli import main
    from stringbot.planner import write_plan
    plan = for_machine(small_plan(n=6, seed=8), name)
    write_plan(plan, tmp_path / "p.json")
    record = tmp_path / "rec.json"
    with pytest.raises(SystemExit) as info:
        main(["wind", str(tmp_path / "p.json"), "--machine", name, "--yes", "--record", str(record),
              "--faults", f"ignore@{n}", "--journal", str(tmp_path / "j")])
    rec = json.loads(record.read_text())
    wraps = [w["pin"] for w in rec["wraps"]]
    state = read_journal(tmp_path / "j")
    assert rec["collisions"] == [] and not rec.get("crashes")
    journaled = [plan.sequence[i] for i in state.done]
    if info.value.code == 0:
        assert wraps == plan.sequence and journaled == plan.sequence
    else:
        assert info.value.code == 1
        assert journaled == wraps                  # nothing journaled that the world did not do
        assert state.last_stop["step"] == len(state.done) + 1      # stopped in the very next step
