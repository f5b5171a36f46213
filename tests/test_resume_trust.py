"""A resume that cannot lie: nothing unknowable is assumed, every attempt keeps its evidence.

Through sim:// in this process; the operator's answers come from the simulated world, as a
person looking at the machine would give them (tests/scripted_operator.py).
"""

import json

import pytest

from firmware_protocol.machine import load_machine, machine_from_dict, bundled_dir
from firmware_protocol.urlhandler import protocol_sim
from stringbot.errors import BadInput, Interrupted, MachineFailure
from stringbot.links import sim_url
from stringbot.planner import write_plan
from stringbot.winding import Job, read_journal, wind_plan
from stringbot.winding.resume import resume_plan

from scripted_operator import ScriptedOperator, world_looker
from test_resume_sim import check_world, head_side_from_world, make_job
from test_wind_sim import eyes_at, small_plan

FAST = {"response_timeout": 1.0}


def world(job):
    return protocol_sim.session(job.url).world


def kinds(job):
    return [json.loads(x)["kind"] for x in job.journal_path.read_text().splitlines()]


def test_yes_never_answers_where_the_head_is_and_refusals_never_lock_out(tmp_path):
    """Issue 13: a power loss during a head move on grbl-ring (no switches).  ``--yes`` alone is
    refused, twice, each attempt journaling what it learned; the second is not fooled by the
    wiped 0,0 it reads now that the alarm is gone; --head-side (after looking) then finishes."""
    job, plan, record = make_job(tmp_path, "grbl-ring", "power@15")
    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=None, link_options=FAST, eyes=eyes_at(job.url))
    assert world(job).head_out                                   # stopped mid-hook, the head OUT
    for _ in range(2):
        with pytest.raises(BadInput, match="--head-side in or --head-side out"):
            resume_plan(job, confirm=None, link_options=FAST)
    state = read_journal(job.journal_path)
    recovers = [r for r in state.epoch if r["kind"] == "recover"]
    assert len(recovers) == 2 and recovers[0]["position_wiped"] and recovers[0]["banner"]
    assert recovers[1]["position_wiped"] and not recovers[1]["banner"]   # known from the journal
    assert [r["kind"] for r in state.epoch].count("refused") == 2
    assert world(job).moves == world(job).moves                  # nothing moved (checked below)
    moves = world(job).moves
    resume_plan(job, confirm=None, head_side=head_side_from_world(job.url), link_options=FAST)
    assert world(job).moves > moves
    check_world(record, plan)


def test_a_head_side_that_contradicts_the_machines_report_is_refused(tmp_path):
    job, plan, record = make_job(tmp_path, "grbl-ring", "disconnect@15")
    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=None, link_options=FAST, eyes=eyes_at(job.url))
    wrong = "in" if head_side_from_world(job.url) == "out" else "out"
    moves = world(job).moves
    with pytest.raises(BadInput, match=f"--head-side {wrong} contradicts the machine's own report"):
        resume_plan(job, confirm=None, head_side=wrong, link_options=FAST)
    assert world(job).moves == moves
    resume_plan(job, confirm=None, link_options=FAST)
    check_world(record, plan)


def test_a_head_side_that_contradicts_the_journal_is_refused(tmp_path):
    """A power loss while the ring turned behind a pin (the head OUT): 'in' cannot be true."""
    job, plan, record = make_job(tmp_path, "grbl-ring", "power@21")
    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=None, link_options=FAST, eyes=eyes_at(job.url))
    with pytest.raises(BadInput, match="--head-side in contradicts the journal: the head was OUT"):
        resume_plan(job, confirm=None, head_side="in", link_options=FAST)


@pytest.mark.parametrize("n", [18, 21])          # the approach (head IN), the pitch turn (head OUT)
def test_the_ring_lost_while_turning_needs_the_operator_and_the_guide_finds_it(tmp_path, n):
    job, plan, record = make_job(tmp_path, "grbl-ring", f"power@{n}")
    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=None, link_options=FAST, eyes=eyes_at(job.url))
    with pytest.raises(BadInput, match="without --yes, in a terminal: it guides you"):
        resume_plan(job, confirm=None, head_side=head_side_from_world(job.url), link_options=FAST)
    op = ScriptedOperator(job.machine, world_looker(lambda: world(job)))
    resume_plan(job, confirm=op.confirm, choose=op.choose, jog=op.jog, say=op.say, link_options=FAST)
    assert op.jogs and any("Guided resume" in t for t in op.told)
    check_world(record, plan)
    declared = [r for r in read_journal(job.journal_path).resumes]
    assert "guided" in declared[-1]["how"]


def test_a_guided_head_brought_in_through_the_wrong_gap_is_refused(tmp_path):
    """The operator brings the head IN one pitch away from the gap the guide names: the thread
    would go round pins the plan did not ask for.  Refused, journaled as moved; the next
    attempt guides again (the journal's path no longer describes the machine)."""
    job, plan, record = make_job(tmp_path, "grbl-ring", "power@21")
    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=None, link_options=FAST, eyes=eyes_at(job.url))
    op = ScriptedOperator(job.machine, world_looker(lambda: world(job)))
    say = op.say

    def wrong_gap(text):
        say(text)
        if op._gap is not None:
            op._gap += 3                         # three gaps further on
    with pytest.raises(BadInput, match="neither of the hook's gaps"):
        resume_plan(job, confirm=op.confirm, choose=op.choose, jog=op.jog, say=wrong_gap, link_options=FAST)
    assert read_journal(job.journal_path).epoch[-1] == {**read_journal(job.journal_path).epoch[-1],
                                                        "kind": "refused", "moved": True}
    with pytest.raises(BadInput, match="terminal"):
        resume_plan(job, confirm=None, link_options=FAST)        # --yes cannot know either


def test_a_measured_stop_position_is_the_truth_after_a_reboot(tmp_path):
    """Issue 15: Ctrl-C holds the machine and journals the held position; the board then
    reboots (an Uno resets when its port opens): --resume --yes declares that position."""
    job, plan, record = make_job(tmp_path, "grbl-ring", None)

    def progress(p):
        if p.done == 4:
            raise KeyboardInterrupt
    with pytest.raises(Interrupted):
        wind_plan(job, confirm=None, progress=progress, link_options=FAST, eyes=eyes_at(job.url))
    stop = read_journal(job.journal_path).last_stop
    assert stop["position"] is not None
    emu = protocol_sim.session(job.url).emulator
    emu._reboot()                                      # the reboot: the firmware's position is wiped
    resume_plan(job, confirm=None, link_options=FAST)
    check_world(record, plan)
    state = read_journal(job.journal_path)
    assert "measured" in state.resumes[-1]["how"]


def _machine_file(tmp_path, name, **controller):
    import tomllib
    doc = tomllib.loads((bundled_dir() / f"{name}.toml").read_text())
    doc["controller"].update(controller)
    lines = []
    for section, table in doc.items():
        if isinstance(table, dict):
            continue
        lines.append(f"{section} = {json.dumps(table)}")
    for section, table in doc.items():
        if isinstance(table, dict):
            lines.append(f"[{section}]")
            lines += [f"{k} = {json.dumps(v)}" for k, v in table.items()]
    path = tmp_path / f"{name}-custom.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("n", [14, 17, 20])     # head OUT, the pitch turn, head IN
def test_a_head_switch_alone_makes_a_resume_after_a_head_move_automatic(tmp_path, n):
    """Marlin without ring homing but with a head switch: a power loss during a head move is
    resumed under --yes with no statement: the head homes alone through the gap it stands at."""
    path = _machine_file(tmp_path, "marlin-ring", homing=False, head_homing=True)
    machine = load_machine(str(path))
    plan = small_plan(n=12, seed=3)
    write_plan(plan, tmp_path / "plan.json")
    record = tmp_path / "rec.json"
    url = sim_url(str(path), record=record, faults=f"power@{n}")
    job = Job(tmp_path / "plan.json", machine, port=url, journal=tmp_path / "j")
    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=None, link_options=FAST, eyes=eyes_at(job.url))
    try:
        resume_plan(job, confirm=None, link_options=FAST)
    except BadInput as exc:                   # a ring move was running: the switch cannot help
        assert "turning the ring" in str(exc)
        op = ScriptedOperator(machine, world_looker(lambda: world(job)))
        resume_plan(job, confirm=op.confirm, choose=op.choose, jog=op.jog, say=op.say, link_options=FAST)
    else:
        assert "head homed" in read_journal(job.journal_path).resumes[-1]["how"]
    check_world(record, plan)
