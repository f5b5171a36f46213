"""The plan and the machine agree or the command says so: ``wind``, ``gcode``, ``pins``, ``estimate``
take the machine from the plan when it names one, and refuse a plan made for another
thread-to-diameter ratio (more than 5 % off) unless ``--force``."""

import json
import shlex
import subprocess
from pathlib import Path

import pytest

from planner_helpers import for_machine
from stringbot.cli import main
from stringbot.planner import read_plan, write_plan
from test_colour_plan import colour_plan
from test_gcode_replay import make_plan, random_sequence
from test_wind_pty import STRINGBOT

ROOT = Path(__file__).resolve().parents[1]


def run(capsys, *args):
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return info.value.code, out, err


def hand_plan(tmp_path, name="p.json", *, machine=None, sized_for=None, diameter_mm=None, thread_mm=None):
    plan = make_plan(random_sequence(20, seed=3))
    if sized_for:
        for_machine(plan, sized_for)
    if diameter_mm is not None:
        plan.diameter_mm = diameter_mm
    if thread_mm is not None:
        plan.thread_mm = thread_mm
    if machine:
        plan.parameters["machine"] = machine
    path = tmp_path / name
    write_plan(plan, path)
    return path


def uses(tmp_path, command, plan, *extra):
    """``command`` on ``plan`` as a user types it: the arguments, and the files it would write."""
    if command == "wind":
        return ["wind", plan, "--yes", *extra], [Path(str(plan) + ".dry-run.journal")]
    if command == "gcode":
        return ["gcode", plan, "-o", tmp_path / "out.gcode", *extra], [tmp_path / "out.gcode"]
    if command == "pins":
        return ["pins", plan, "-o", tmp_path / "out.txt", *extra], [tmp_path / "out.txt"]
    return ["estimate", plan, *extra], []


COMMANDS = ["wind", "gcode", "pins", "estimate"]


@pytest.mark.parametrize("command", COMMANDS)
def test_a_plan_for_a_1000_mm_frame_is_refused_on_the_500_mm_ring_unless_forced(tmp_path, capsys, command):
    plan = hand_plan(tmp_path, diameter_mm=1000.0)
    args, outputs = uses(tmp_path, command, plan, "--machine", "grbl-ring")
    code, out, err = run(capsys, *args)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "0.25 mm thread on a 1000 mm frame" in err and "100 % thicker" in err and "darker" in err
    assert f"stringbot plan hand.png -o {tmp_path / 'p-grbl-ring.json'} --machine grbl-ring" in err
    assert "--force" in err
    assert not any(p.exists() for p in outputs)
    code, out, err = run(capsys, *args, "--force")
    assert code == 0, err
    assert all(p.exists() for p in outputs)


@pytest.mark.parametrize("command", COMMANDS)
def test_the_machine_comes_from_the_plan_when_it_names_one(tmp_path, capsys, command):
    plan = hand_plan(tmp_path, machine="marlin-ring", sized_for="marlin-ring")
    args, outputs = uses(tmp_path, command, plan)
    code, out, err = run(capsys, *args)
    assert code == 0, err
    if command == "gcode":
        assert "; machine: marlin-ring (marlin;" in (tmp_path / "out.gcode").read_text()
    elif command == "estimate":
        assert "marlin-ring" in out
    elif command == "pins":
        assert "for a 450 mm ring diameter, from machine marlin-ring" in (tmp_path / "out.txt").read_text()
    else:
        header = json.loads(outputs[0].read_text().splitlines()[0])
        assert header["machine"] == "marlin-ring"


@pytest.mark.parametrize("command", ["wind", "gcode", "estimate"])
def test_a_plan_naming_no_machine_needs_machine(tmp_path, capsys, command):
    args, outputs = uses(tmp_path, command, hand_plan(tmp_path))
    code, _, err = run(capsys, *args)
    assert code == 2 and "names no machine" in err and "give --machine NAME" in err
    assert not any(p.exists() for p in outputs)


def test_a_machine_file_named_beside_the_plan_is_found_from_anywhere(tmp_path, capsys, monkeypatch):
    shop = tmp_path / "shop"
    shop.mkdir()
    code, toml, _ = run(capsys, "machines", "show", "grbl-ring")
    (shop / "mine.toml").write_text(toml.replace('name = "grbl-ring"', 'name = "mine"'))
    hand_plan(shop, machine="./mine.toml")
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "estimate", "shop/p.json")
    assert code == 0, err
    assert "mine" in out and "mine.toml" in out
    (shop / "mine.toml").unlink()
    code, _, err = run(capsys, "estimate", "shop/p.json")
    assert code == 2 and "was made for machine './mine.toml'" in err and "give --machine" in err


def test_another_machine_than_the_plans_is_checked_the_same_way(tmp_path, capsys):
    plan = hand_plan(tmp_path, machine="grbl-ring")       # 0.25 mm on 500 mm, the defaults
    code, _, err = run(capsys, "estimate", plan, "--machine", "marlin-ring")
    assert code == 2 and "(made for machine 'grbl-ring')" in err and "11 % thinner" in err and "lighter" in err
    code, out, err = run(capsys, "estimate", plan, "--machine", "dynamixel-ring")   # the same ratio
    assert code == 0 and "dynamixel-ring" in out
    code, out, err = run(capsys, "estimate", plan, "--machine", "grblhal-ring")     # 0.3 mm on 600 mm: the same
    assert code == 0 and "grblhal-ring" in out


@pytest.mark.parametrize("thread_mm, ok", [(0.26, True), (0.2375, True), (0.27, False), (0.235, False)])
def test_five_percent_is_the_bound(tmp_path, capsys, thread_mm, ok):
    plan = hand_plan(tmp_path, thread_mm=thread_mm)
    code, _, err = run(capsys, "estimate", plan, "--machine", "grbl-ring")
    assert (code == 0) == ok, err


def test_a_plan_without_thread_and_diameter_is_read_as_the_planners_defaults(tmp_path, capsys):
    plan = hand_plan(tmp_path)
    doc = json.loads(plan.read_text())
    assert "thread_mm" not in doc and "diameter_mm" not in doc       # as written before the thread model
    assert run(capsys, "estimate", plan, "--machine", "grbl-ring")[0] == 0        # 0.25 mm / 500 mm
    code, _, err = run(capsys, "estimate", plan, "--machine", "marlin-ring")      # 0.2 mm / 450 mm
    assert code == 2 and "0.25 mm thread on a 500 mm frame" in err


def test_a_colour_plans_replan_command_keeps_its_threads(tmp_path, capsys):
    plan = colour_plan()
    plan.parameters.update(colors_requested="auto:3")
    path = tmp_path / "cat.json"
    write_plan(plan, path)
    code, _, err = run(capsys, "gcode", path, "--machine", "marlin-ring", "-o", tmp_path / "cat.gcode")
    assert code == 2 and "--machine marlin-ring --colors auto:3" in err
    assert not (tmp_path / "cat.gcode").exists()


def test_the_command_it_names_plans_for_the_machine_and_that_plan_winds(tmp_path):
    """Through the real planner: a 1000 mm plan refused on grbl-ring, the named command run, the new plan
    wound (no --machine: it names its machine) and its G-code written."""
    def stringbot(*args):
        return subprocess.run(STRINGBOT + [str(a) for a in args], capture_output=True, text=True, timeout=240,
                              cwd=tmp_path)
    quick = ["--lines", "40", "--size", "161", "--polish", "0"]
    p = stringbot("plan", ROOT / "examples" / "camera.png", "-o", "big.json", "--diameter-mm", "1000", *quick)
    assert p.returncode == 0, p.stderr
    p = stringbot("wind", "big.json", "--machine", "grbl-ring", "--yes")
    assert p.returncode == 2 and not (tmp_path / "big.json.dry-run.journal").exists()
    command = shlex.split(p.stderr.split("plan it for this machine: ", 1)[1].split(" (or --force")[0])
    assert command[:2] == ["stringbot", "plan"] and "big-grbl-ring.json" in command
    p = stringbot(*command[1:], *quick)
    assert p.returncode == 0, p.stderr
    assert read_plan(tmp_path / "big-grbl-ring.json").parameters["machine"] == "grbl-ring"
    p = stringbot("wind", "big-grbl-ring.json", "--yes", "--record", "rec.json")
    assert p.returncode == 0, p.stderr
    rec = json.loads((tmp_path / "rec.json").read_text())
    assert [w["pin"] for w in rec["wraps"]] == read_plan(tmp_path / "big-grbl-ring.json").sequence
    p = stringbot("gcode", "big-grbl-ring.json", "-o", "big.gcode")
    assert p.returncode == 0, p.stderr
