"""A dry run winds the machine file it was given, and says so when the world is not the plan."""

import json

import pytest

from stringbot.cli import main
from stringbot.planner import write_plan
from stringbot.winding import session

from test_wind_sim import small_plan

GRBL = __import__("pathlib").Path(__file__).resolve().parents[1] / "machines" / "grbl-ring.toml"


def run(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    out, err = capsys.readouterr()
    return info.value.code, out, err


def copy_machine(tmp_path, filename, *, name=None, pin0=None):
    text = GRBL.read_text()
    if name is not None:
        text = text.replace('name = "grbl-ring"', f'name = "{name}"', 1)
    if pin0 is not None:
        old = "pin0_angle_deg = 0.0 "
        assert old in text
        text = text.replace(old, f"pin0_angle_deg = {pin0} ", 1)
    path = tmp_path / filename
    path.write_text(text)
    return path


@pytest.fixture
def plan(tmp_path):
    p = small_plan(n=12, seed=3)
    path = tmp_path / "plan.json"
    write_plan(p, path)
    return path, p


@pytest.mark.parametrize("name", ["my-ring", "grbl-ring"])
def test_a_users_machine_file_is_the_one_simulated(tmp_path, plan, capsys, name):
    # a folder with a space and an ampersand: the path must survive the URL's query string
    folder = tmp_path / "my machines & more"
    folder.mkdir()
    machine = copy_machine(folder, "ring=0.6.toml", name=name, pin0=0.6)
    record = tmp_path / "rec.json"
    code, out, err = run(["wind", str(plan[0]), "--machine", str(machine), "--yes",
                          "--record", str(record)], capsys)
    assert code == 0, err
    rec = json.loads(record.read_text())
    assert [w["pin"] for w in rec["wraps"]] == plan[1].sequence
    assert rec["collisions"] == []
    job = session.load_job(plan[0], str(machine), record=record)
    assert "0.6.toml" in job.url and "grbl-ring.toml" not in job.url


def test_a_dry_run_whose_world_is_not_the_plan_exits_1(tmp_path, plan, capsys, monkeypatch):
    # the host moves for pin0 = 0.6 while the simulated machine has its pin 0 at 0.0: the
    # head meets pins (what a machine file that disagrees with its machine does)
    machine = copy_machine(tmp_path, "mine.toml", pin0=0.6)
    monkeypatch.setattr(session, "_machine_ref", lambda m: str(GRBL))
    record = tmp_path / "rec.json"
    code, out, err = run(["wind", str(plan[0]), "--machine", str(machine), "--yes",
                          "--record", str(record)], capsys)
    assert code == 1, err
    lines = [x for x in err.splitlines() if x.startswith("stringbot:")]
    assert len(lines) == 1 and "Traceback" not in err
    assert "collision" in lines[0] and "mine.toml" in lines[0] and "--resume" not in lines[0]


def test_dry_run_problem_names_wraps_that_differ(tmp_path, plan):
    record = tmp_path / "rec.json"
    job = session.load_job(plan[0], "grbl-ring", record=record)
    seq = plan[1].sequence
    record.write_text(json.dumps({"wraps": [{"pin": p, "direction": 1} for p in seq], "collisions": []}))
    assert session.dry_run_problem(job) is None
    wrong = seq[:5] + [(seq[5] + 1) % 300] + seq[6:]
    record.write_text(json.dumps({"wraps": [{"pin": p, "direction": 1} for p in wrong], "collisions": []}))
    problem = session.dry_run_problem(job)
    assert problem is not None and "step 6" in problem and "collision" not in problem
    record.write_text(json.dumps({"wraps": [{"pin": p, "direction": 1} for p in seq[:-1]],
                                  "collisions": []}))
    assert f"wrapped {len(seq) - 1} pins" in session.dry_run_problem(job)
    # the head driven against the end of its travel: the world's crashes
    record.write_text(json.dumps({"wraps": [{"pin": p, "direction": 1} for p in seq], "collisions": [],
                                  "crashes": [{"head_mm": 15.0, "driven_to_mm": 24.0}]}))
    assert "1 crash(es)" in session.dry_run_problem(job)
    # no record asked for, or a real machine's port: nothing to check
    assert session.dry_run_problem(session.load_job(plan[0], "grbl-ring")) is None
