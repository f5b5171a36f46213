"""Winding a colour plan: spool changes, the journal's layer records, resume, the world's colours."""

import json

import pytest

from firmware_protocol.machine import load_machine
from stringbot.cli import main
from stringbot.errors import Interrupted, MachineFailure
from stringbot.links import sim_url
from stringbot.planner import write_plan
from stringbot.winding import Job, read_journal, wind_plan
from stringbot.winding.resume import resume_plan

from bundled import MACHINES
from planner_helpers import for_machine
from test_colour_plan import colour_plan
from test_wind_sim import eyes_at


def hands_at(url):
    """The operator's hands at an in-process simulated machine: each thread tied on when asked."""
    from firmware_protocol.urlhandler import protocol_sim
    return lambda color, pin: protocol_sim.tie_on(url, color, pin)


def check_layers(record, plan):
    """The world wound every layer exactly: its pins, in order, with its thread."""
    rec = json.loads(record.read_text())
    assert rec["collisions"] == []
    assert [(w["pin"], w["color"]) for w in rec["wraps"]] == \
        [(p, lay.color) for lay in plan.layers for p in lay.sequence]
    return rec


@pytest.mark.parametrize("name", MACHINES)
def test_dry_run_of_a_three_colour_plan_winds_every_layer_with_its_thread(tmp_path, capsys, name):
    plan = for_machine(colour_plan(), name)
    path, record = tmp_path / "c.json", tmp_path / "rec.json"
    write_plan(plan, path)
    with pytest.raises(SystemExit) as info:
        main(["wind", str(path), "--machine", name, "--yes", "--record", str(record)])
    out, err = capsys.readouterr()
    assert info.value.code == 0, err
    rec = check_layers(record, plan)
    assert [(s["color"], s["pin"], s["after_wraps"], s["head_out"]) for s in rec["spools"]] == \
        [(lay.color, lay.sequence[0], start, False) for lay, start in zip(plan.layers, plan.layer_starts)]
    layers = read_journal(tmp_path / "c.json.dry-run.journal").layers
    assert [(r["layer"], r["color"], r["step"], r["pin"]) for r in layers] == \
        [(k, lay.color, s, lay.sequence[0]) for k, (lay, s) in enumerate(zip(plan.layers, plan.layer_starts))]


def test_the_operator_is_asked_for_each_thread_at_its_pin(tmp_path):
    plan = colour_plan()
    path = tmp_path / "c.json"
    write_plan(plan, path)
    record = tmp_path / "rec.json"
    job = Job(path, load_machine("grbl-ring"), port=sim_url("grbl-ring", record=record),
              journal=tmp_path / "c.journal")
    asked = []
    wind_plan(job, confirm=lambda q: asked.append(q) or True, hands=hands_at(job.url), eyes=eyes_at(job.url))
    assert len(asked) == 3
    for k, (q, lay) in enumerate(zip(asked, plan.layers)):
        assert lay.color in q and f"at pin {lay.sequence[0]}" in q and f"layer {k + 1} of 3" in q
    assert "Spool change" in asked[1] and plan.layers[0].color in asked[1]   # the thread to cut
    check_layers(record, plan)


def test_a_dry_run_that_winds_a_layer_with_the_wrong_thread_fails(tmp_path, capsys, monkeypatch):
    """The record's colours are checked: an operator who ties on the wrong thread is caught."""
    from stringbot.cli import colour
    plan = colour_plan()
    path, record = tmp_path / "c.json", tmp_path / "rec.json"
    write_plan(plan, path)

    def clumsy(job):
        hands = hands_at(str(job.url))
        return lambda color, pin: hands("#00ff00" if color == "#c8102e" else color, pin)
    monkeypatch.setattr(colour, "simulated_hands", clumsy)
    with pytest.raises(SystemExit) as info:
        main(["wind", str(path), "--machine", "grbl-ring", "--yes", "--record", str(record)])
    _, err = capsys.readouterr()
    assert info.value.code == 1 and "layer 2 (#c8102e) was wound with thread #00ff00" in err


def asks_for(color, question):
    """The question asks the operator to tie the thread of ``color`` on."""
    return f"({color}) thread on at pin" in question


def make_job(tmp_path, faults):
    plan = colour_plan(n=(6, 6, 5))
    path = tmp_path / "c.json"
    write_plan(plan, path)
    record = tmp_path / "rec.json"
    job = Job(path, load_machine("grbl-ring"), port=sim_url("grbl-ring", record=record, faults=faults),
              journal=tmp_path / "c.journal")
    return job, plan, record


def test_resume_inside_layer_2_never_asks_for_layer_1(tmp_path):
    # GRBL receives $I, G21, G90, G94, then two lines per move ("G1 ...", "G4 P0"), 4 moves a step
    # (5 for the first): layer 1 (6 steps) ends near line 54; line 75 falls inside layer 2's steps
    job, plan, record = make_job(tmp_path, "disconnect@75")
    asked = []

    def confirm(q):
        asked.append(q)
        return True

    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=confirm, link_options={"response_timeout": 1.0}, hands=hands_at(job.url), eyes=eyes_at(job.url))
    state = read_journal(job.journal_path)
    assert plan.layer_starts[1] < state.next_step < plan.layer_starts[2]     # stopped inside layer 2
    assert [r["layer"] for r in state.layers] == [0, 1]
    before = len(asked)
    resume_plan(job, confirm=confirm, link_options={"response_timeout": 1.0}, hands=hands_at(job.url))
    again = asked[before:]
    assert not any(plan.colors[0] in q for q in again)                  # layer 1's thread: never again
    assert not any(asks_for(plan.colors[1], q) for q in again)          # layer 2's is on the machine
    assert sum(asks_for(plan.colors[2], q) for q in again) == 1         # layer 3's: once, at its change
    check_layers(record, plan)
    state = read_journal(job.journal_path)
    assert state.finished and [r["layer"] for r in state.layers] == [0, 1, 2]


def test_operator_declining_at_a_spool_change_then_resume_asks_for_that_thread(tmp_path):
    job, plan, record = make_job(tmp_path, None)
    answers = iter([True, False])            # layer 1 yes; at the change to layer 2: not yet
    with pytest.raises(Interrupted, match="spool change before step 7"):
        wind_plan(job, confirm=lambda q: next(answers), hands=hands_at(job.url), eyes=eyes_at(job.url))
    state = read_journal(job.journal_path)
    assert state.next_step == plan.layer_starts[1] and [r["layer"] for r in state.layers] == [0]
    asked = []
    resume_plan(job, confirm=lambda q: asked.append(q) or True, hands=hands_at(job.url))
    assert sum(asks_for(plan.colors[1], q) and "Spool change" in q for q in asked) == 1
    assert not any(asks_for(plan.colors[0], q) for q in asked)
    check_layers(record, plan)


def test_status_and_estimate_of_a_colour_plan(tmp_path, capsys):
    plan = colour_plan()
    path = tmp_path / "c.json"
    write_plan(plan, path)
    with pytest.raises(SystemExit) as info:
        main(["estimate", str(path), "--machine", "grbl-ring", "--json"])
    out, _ = capsys.readouterr()
    assert info.value.code == 0
    doc = json.loads(out)
    assert [le["color"] for le in doc["layers"]] == plan.colors
    assert abs(sum(le["thread_m"] for le in doc["layers"]) - doc["thread_m"]) < 1e-6
