"""Resume after every kind of fault, through sim:// in this process (the machine is kept per URL).

After each interruption the same command runs with --resume until the job is
finished; the world's wraps must then equal the plan's sequence exactly, with
no collision.  The operator's answer to "where is the head?" (only asked when
the firmware lost its position while the head was moving) is read from the
world, as an operator would look at the machine.
"""

import json

import pytest

from firmware_protocol.machine import load_machine
from stringbot.errors import BadInput, Interrupted, MachineFailure
from stringbot.links import sim_url
from stringbot.planner import write_plan
from stringbot.winding import Job, read_journal, wind_plan
from stringbot.winding.resume import resume_plan, status_lines

from bundled import GCODE_MACHINES, LINE_KINDS, MACHINE_KINDS, POINTS, fault_point
from scripted_operator import ScriptedOperator, world_looker
from test_wind_sim import eyes_at, small_plan


def make_job(tmp_path, name, faults, n=12, seed=3):
    plan = small_plan(n=n, seed=seed)
    plan_path = tmp_path / "plan.json"
    write_plan(plan, plan_path)
    record = tmp_path / "rec.json"
    url = sim_url(name, record=record, faults=faults)
    job = Job(plan_path, load_machine(name), port=url, journal=tmp_path / "plan.journal")
    return job, plan, record


def head_side_from_world(url):
    """What an operator sees: the simulated machine's head."""
    from firmware_protocol.urlhandler import protocol_sim
    return "out" if protocol_sim.session(url).world.head_out else "in"


def operator_for(job):
    from firmware_protocol.urlhandler import protocol_sim
    return ScriptedOperator(job.machine, world_looker(lambda: protocol_sim.session(job.url).world))


def resume_as_an_operator(job, fast, tried):
    """As a person would: ``--resume --yes``; if that asks for ``--head-side``, look and give it;
    if it asks for a terminal, answer its questions and follow its guide (from the machine).
    ``tried`` collects the ways used."""
    try:
        tried.append("yes")
        return resume_plan(job, confirm=None, link_options=fast)
    except BadInput as exc:
        if "--head-side" not in str(exc) and "terminal" not in str(exc):
            raise
        side = operator_for(job).clear_side()          # stated only when clearly IN or OUT
        if side is not None and "--head-side" in str(exc) and "guided" not in str(exc).split("--head-side")[0]:
            tried.append("head-side")
            try:
                return resume_plan(job, confirm=None, head_side=side, link_options=fast)
            except BadInput as again:
                if "terminal" not in str(again):
                    raise
    except MachineFailure as exc:
        if "terminal" not in str(exc):
            raise
    tried.append("terminal")
    op = operator_for(job)
    return resume_plan(job, confirm=op.confirm, choose=op.choose, jog=op.jog, say=op.say, link_options=fast)


def wind_to_the_end(job, record, first=None, max_runs=10, tried=None):
    """Wind, then resume after every stop; returns the number of interruptions."""
    stops = 0
    fast = {"response_timeout": 1.0}
    tried = [] if tried is None else tried
    run = first or (lambda: wind_plan(job, confirm=None, link_options=fast, eyes=eyes_at(job.url)))
    for _ in range(max_runs):
        try:
            run()
            return stops
        except (MachineFailure, Interrupted):
            stops += 1
        run = lambda: resume_as_an_operator(job, fast, tried)
    raise AssertionError("still not finished after %d runs" % max_runs)


def check_world(record, plan):
    rec = json.loads(record.read_text())
    assert rec["collisions"] == []
    assert [w["pin"] for w in rec["wraps"]] == plan.sequence


# every bundled G-code machine, every fault kind a resume gets past (the registries: tests/bundled.py),
# at moves where the head is IN, mid-hook (OUT) and coming back IN; the machine kinds also halfway
# through the move of a line (kind@N+0.5) with the head going OUT and mid-hook
AT = {"machine": ("ring", "hook", "in"), "line": ("hook", "hook-sync")}
MID = ("out", "hook")
CASES = [(name, kind, point, "") for name in GCODE_MACHINES for kind in MACHINE_KINDS + LINE_KINDS
         for point in AT["machine" if kind in MACHINE_KINDS else "line"]]
MID_MOVE = [(name, kind, point, "+0.5") for name in GCODE_MACHINES for kind in MACHINE_KINDS for point in MID]
# the full set, slow: every kind at every kind of move
FULL = [(name, kind, point, mid) for name in GCODE_MACHINES for kind in MACHINE_KINDS + LINE_KINDS
        for point in POINTS for mid in ("", "+0.5") if not (mid and (kind in LINE_KINDS or point == "hook-sync"))
        if (name, kind, point, mid) not in CASES + MID_MOVE]


def _fault_then_resume(tmp_path, name, kind, point, mid):
    n = fault_point(name, small_plan(n=12, seed=3), point)
    job, plan, record = make_job(tmp_path, name, f"{kind}@{n}{mid}")
    wind_to_the_end(job, record)
    check_world(record, plan)
    assert read_journal(job.journal_path).finished


@pytest.mark.parametrize("name, kind, point, mid", CASES + MID_MOVE)
def test_fault_then_resume_winds_the_plan_exactly(tmp_path, name, kind, point, mid):
    _fault_then_resume(tmp_path, name, kind, point, mid)


@pytest.mark.slow
@pytest.mark.parametrize("name, kind, point, mid", FULL)
def test_fault_at_every_kind_of_move_then_resume_winds_the_plan_exactly(tmp_path, name, kind, point, mid):
    _fault_then_resume(tmp_path, name, kind, point, mid)


@pytest.mark.parametrize("name, at_step", [("grbl-ring", 1), ("grbl-ring", 9)]
                         + [(name, 4) for name in GCODE_MACHINES])
def test_ctrl_c_then_resume(tmp_path, name, at_step):
    job, plan, record = make_job(tmp_path, name, None)

    def progress(p):
        if p.done == at_step:
            raise KeyboardInterrupt
    with pytest.raises(Interrupted, match="stopped"):
        wind_plan(job, confirm=None, progress=progress, eyes=eyes_at(job.url))
    state = read_journal(job.journal_path)
    assert state.last_stop["reason"] == "interrupted"
    assert any("steps done" in line for line in status_lines(job))
    resume_plan(job, confirm=None)
    check_world(record, plan)


def test_journal_for_another_plan_or_machine_is_refused(tmp_path):
    job, plan, record = make_job(tmp_path, "grbl-ring", "disconnect@30")
    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=None, eyes=eyes_at(job.url))
    other = Job(job.plan_path, load_machine("grblhal-ring"), port=job.url, journal=job.journal_path)
    with pytest.raises(BadInput, match="machine 'grbl-ring'"):
        resume_plan(other, confirm=None)
    write_plan(small_plan(n=12, seed=99), tmp_path / "other.json")
    other = Job(tmp_path / "other.json", job.machine, port=job.url, journal=job.journal_path)
    with pytest.raises(BadInput, match="another plan"):
        resume_plan(other, confirm=None)


def test_from_step_rewinds_from_a_chosen_step(tmp_path):
    job, plan, record = make_job(tmp_path, "grbl-ring", None, n=8)
    wind_plan(job, confirm=None, eyes=eyes_at(job.url))
    asked = []
    resume_plan(job, from_step=6, confirm=lambda q: asked.append(q) or True)
    assert any("Restart from step 6" in q for q in asked)
    rec = json.loads(record.read_text())
    assert [w["pin"] for w in rec["wraps"]] == plan.sequence + plan.sequence[5:]
    assert rec["collisions"] == []


def test_locate_on_the_path_of_a_step():
    from stringbot.motion import hook_steps
    from stringbot.winding.resume import locate
    machine = load_machine("grbl-ring")
    plan = small_plan(n=6, seed=21)
    steps = hook_steps(plan, machine)
    s = 3
    mv = steps[s].moves
    a, b, c, d = [(m.ring_deg, m.head_mm) for m in mv]
    assert locate(a, steps, s, 0, machine) == (s, 1)                 # after the approach
    assert locate(b, steps, s, 1, machine) == (s, 2)                 # head out
    mid = ((b[0] + c[0]) / 2, b[1])
    assert locate(mid, steps, s, 2, machine) == (s, 2)               # inside the pitch turn
    assert locate(d, steps, s, 3, machine) == (s + 1, 0)             # the hook is done
    assert locate((d[0] + 50.0, 3.0), steps, s, 3, machine) is None  # nowhere on the path


def test_locate_within_a_servo_links_arrival_tolerance():
    """A servo arrives within a few ticks of a goal (0.0989 ring degrees on dynamixel-ring), more
    than the fixed 0.01: resume locates it with the link's ``position_tolerance``, and a link
    without one (G-code) keeps 0.01."""
    from types import SimpleNamespace

    from stringbot.links.dynamixel import DynamixelLink
    from stringbot.motion import hook_steps
    from stringbot.winding.resume import TOL, locate, tolerance
    machine = load_machine("dynamixel-ring")
    steps = hook_steps(small_plan(n=6, seed=21), machine)
    s = 3
    a, b, c, d = [(m.ring_deg, m.head_mm) for m in steps[s].moves]
    tol = tolerance(DynamixelLink(machine, "loop://"))
    assert tol == (pytest.approx(0.0989, abs=1e-4), pytest.approx(0.132))
    assert tolerance(SimpleNamespace()) == (TOL, TOL)
    assert tolerance(SimpleNamespace(position_tolerance=(0.001, 0.5))) == (TOL, 0.5)
    # arrived 3 ticks past the approach's end, or 3 ticks short of the pitch turn's, with the
    # head 4 ticks off IN: the fixed 0.01 finds neither
    short = 3 / 45.51
    prev = steps[s - 1].moves[-1].ring_deg
    ahead = 1.0 if a[0] > prev else -1.0             # the approach's direction
    at_a = (a[0] + ahead * short, a[1] + 0.09)
    turn = 1.0 if c[0] > b[0] else -1.0
    at_c = (c[0] - turn * short, c[1] + 0.09)
    assert locate(at_a, steps, s, 0, machine) is None
    assert locate(at_a, steps, s, 0, machine, tol) == (s, 1)
    assert locate(at_c, steps, s, 3, machine) is None
    assert locate(at_c, steps, s, 3, machine, tol) == (s, 3)
    mid = ((b[0] + c[0]) / 2, b[1])                   # inside the pitch turn, the head OUT
    assert locate((mid[0], mid[1] - 0.1), steps, s, 2, machine, tol) == (s, 2)
    assert locate((mid[0], mid[1] - 0.3), steps, s, 2, machine, tol) is None    # 0.3 mm is off the path


def test_ctrl_c_just_after_a_step_is_journaled_counts_that_step(tmp_path, monkeypatch):
    """Ctrl-C landing after a step's ``done`` line is written (in its fsync) but before the winder
    counted it: the stop line, the stop record and the resume all say that step is done."""
    from stringbot.winding import journal as journal_mod
    job, plan, record = make_job(tmp_path, "grbl-ring", None)
    real_done = journal_mod.Journal.done

    def done(self, step, pin):
        real_done(self, step, pin)
        if step == 4:                       # the 5th step's line is on disk
            raise KeyboardInterrupt
    monkeypatch.setattr(journal_mod.Journal, "done", done)
    with pytest.raises(Interrupted, match=f"interrupted at pin {plan.sequence[5]}, step 6 of "
                                          f"{len(plan.sequence)}: .*; 5 of {len(plan.sequence)} steps done"):
        wind_plan(job, confirm=None, eyes=eyes_at(job.url))
    state = read_journal(job.journal_path)
    assert state.next_step == 5
    assert (state.last_stop["step"], state.last_stop["pin"], state.last_stop["next_step"]) == (6, plan.sequence[5], 5)
    monkeypatch.setattr(journal_mod.Journal, "done", real_done)
    resume_plan(job, confirm=None)
    check_world(record, plan)


@pytest.mark.parametrize("after", ["wrap", "head-out"])
def test_ctrl_c_in_a_steps_last_move_says_its_pin_is_wrapped(tmp_path, monkeypatch, after):
    """Ctrl-C landing once a step's pin is wrapped (its last move, the head back IN, left): the stop line
    says the pin is wrapped already, the head still out, and the step not counted done; earlier in the
    step it says nothing of the kind.  The resume winds the plan exactly either way."""
    from stringbot.winding.loop import Winder
    job, plan, record = make_job(tmp_path, "grbl-ring", None)
    real_moved = Winder._moved

    def moved(self, step, move):
        real_moved(self, step, move)
        if step.index == 4 and move == len(step.moves) - (2 if after == "wrap" else 3):
            raise KeyboardInterrupt
    monkeypatch.setattr(Winder, "_moved", moved)
    n, pin = len(plan.sequence), plan.sequence[4]
    with pytest.raises(Interrupted) as exc:
        wind_plan(job, confirm=None, eyes=eyes_at(job.url))
    line = str(exc.value)
    assert line.startswith(f"interrupted at pin {pin}, step 5 of {n}") and f"; 4 of {n} steps done" in line
    said = f"(pin {pin} is wrapped already, the head still out: step 5 lacks only the head's move back in"
    assert (said in line) == (after == "wrap"), line
    stop = read_journal(job.journal_path).last_stop
    moves = len(job.steps[4].moves)
    assert stop["at"]["step_index"] == 4 and stop["at"]["move"] == moves - (1 if after == "wrap" else 2)
    monkeypatch.setattr(Winder, "_moved", real_moved)
    resume_plan(job, confirm=None)
    check_world(record, plan)
