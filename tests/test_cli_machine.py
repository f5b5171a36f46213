"""The machine commands: machines, machines show, gcode, estimate; bad input is one line, exit 2."""

import json

import pytest

from firmware_protocol.machine import bundled_dir, load_machine
from bundled import GCODE_MACHINES
from gcode_replay import replay
from stringbot.cli import main
from stringbot.planner import write_plan
from planner_helpers import for_machine
from test_gcode_replay import make_plan, random_sequence


def run(capsys, *args):
    with pytest.raises(SystemExit) as info:
        main(list(args))
    out, err = capsys.readouterr()
    return info.value.code, out, err


@pytest.fixture
def plan_path(tmp_path):
    path = tmp_path / "p.json"
    write_plan(make_plan([0, 150, 3, 299, 0, 77] + random_sequence(60, seed=2)), path)
    return path


def test_machines_lists_the_bundled_ones(capsys):
    code, out, _ = run(capsys, "machines")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert {"grbl-ring", "grblhal-ring", "marlin-ring", "dynamixel-ring"} <= set(names)
    assert all("300 pins" in line for line in out.splitlines())


def test_machines_show_prints_values_and_derived_figures(capsys):
    code, out, _ = run(capsys, "machines", "show", "grbl-ring")
    assert code == 0
    m = load_machine("grbl-ring")
    assert 'dialect = "grbl"' in out and "pins = 300" in out
    assert f"{m.pitch_deg:.4f} deg = {m.pitch_mm:.3f} mm" in out
    assert f"{m.free_gap_mm:.3f} mm" in out and f"+-{m.gap_tolerance_deg:.4f} deg" in out


def test_machines_show_takes_a_users_file(capsys, tmp_path):
    text = (bundled_dir() / "grbl-ring.toml").read_text().replace("pins = 300", "pins = 200")
    path = tmp_path / "mine.toml"
    path.write_text(text)
    code, out, _ = run(capsys, "machines", "show", str(path))
    assert code == 0 and "pins = 200" in out and "1.8000 deg" in out


@pytest.mark.parametrize("name", GCODE_MACHINES)
def test_gcode_writes_a_job_that_replays_exactly(capsys, tmp_path, plan_path, name):
    from stringbot.planner import read_plan
    write_plan(for_machine(read_plan(plan_path), name), plan_path)
    out_path = tmp_path / "job.gcode"
    code, out, err = run(capsys, "gcode", str(plan_path), "--machine", name, "-o", str(out_path))
    assert code == 0, err
    assert str(out_path) in out
    text = out_path.read_text()
    lines = text.splitlines()
    assert lines[0].startswith("; stringbot") and any(f"machine: {name}" in x for x in lines[:8])
    assert "; pin 150 (step 2/66)" in lines
    machine = load_machine(name)
    marlin = machine["controller.dialect"] == "marlin"
    world, _ = replay(text, machine)
    plan = json.loads(plan_path.read_text())
    assert [w.pin for w in world.wraps] == plan["sequence"] and world.collisions == []
    if marlin:
        assert "M400" in lines and "G4 P0" not in lines and lines[-1].startswith("M117")
        assert "G94" not in lines
    else:
        assert "G4 P0" in lines and lines[-1] == "M2"
    home = f"G28 {machine['controller.head_axis']} {machine['controller.ring_axis']}" if marlin else "$H"
    assert (home in lines) == machine["controller.homing"]
    if home in lines:       # before any G-code: GRBL with homing on is locked in alarm until $H
        assert lines.index(home) < lines.index("G21")


def test_estimate_prints_time_travel_and_thread(capsys, plan_path):
    code, out, _ = run(capsys, "estimate", str(plan_path), "--machine", "grbl-ring", "--json")
    assert code == 0
    doc = json.loads(out)
    assert doc["machine"] == "grbl-ring" and doc["steps"] == 66
    assert doc["seconds"] > 0 and doc["thread_m"] > 0
    assert doc["ring_travel_deg"] >= doc["lower_bound_deg"] > 0
    code, out, _ = run(capsys, "estimate", str(plan_path), "--machine", "grbl-ring")
    assert code == 0 and "shortest-arc lower bound" in out and "thread" in out


def bad_machine(tmp_path, old, new):
    text = (bundled_dir() / "grbl-ring.toml").read_text()
    assert old in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new))
    return str(path)


@pytest.mark.parametrize("make, words", [
    (lambda t: bad_machine(t, "pins = 300 ", "pins = 300\npinz = 3 "), "unknown key 'ring.pinz'"),
    (lambda t: bad_machine(t, "diameter_mm = 500.0", 'diameter_mm = "big"'), "ring.diameter_mm is 'big'"),
    (lambda t: bad_machine(t, "[thread]", "[threads]"), "unknown section [threads]"),
    (lambda t: bad_machine(t, "[thread]\ndiameter_mm = 0.25", ""), "missing section [thread]"),
    (lambda t: bad_machine(t, "out_mm = 12.0", "out_mm = 0.0"), "head.in_mm equals head.out_mm"),
    (lambda t: bad_machine(t, "pin_diameter_mm = 1.5", "pin_diameter_mm = -1.5"), "ring.pin_diameter_mm"),
    (lambda t: bad_machine(t, "pin_diameter_mm = 1.5", "pin_diameter_mm = 5.2"), "the pins do not fit"),
    (lambda t: bad_machine(t, 'ring_axis = "X"', 'ring_axis = "A"'), "controller.ring_axis is 'A'"),
    (lambda t: bad_machine(t, 'head_axis = "Y"', 'head_axis = "X"'), "both 'X'"),
    (lambda t: bad_machine(t, 'wrap_direction = "auto"', 'wrap_direction = "left"'), "winding.wrap_direction"),
    (lambda t: str(t / "missing.toml"), "does not exist"),
    (lambda t: "no-such-machine", "unknown machine 'no-such-machine'"),
])
def test_bad_machine_files_are_one_line_exit_2(capsys, tmp_path, plan_path, make, words):
    for args in (["estimate", str(plan_path)], ["gcode", str(plan_path), "-o", str(tmp_path / "j.gcode")]):
        code, out, err = run(capsys, *args, "--machine", make(tmp_path))
        assert code == 2
        assert words in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "j.gcode").exists()


def test_bad_plans_are_one_line_exit_2(capsys, tmp_path):
    small = tmp_path / "small.json"
    write_plan(make_plan([0, 4, 1], pins=8), small)
    code, _, err = run(capsys, "gcode", str(small), "--machine", "grbl-ring", "-o", str(tmp_path / "j.gcode"))
    assert code == 2 and "has 8 pins" in err and "ring.pins = 300" in err
    loose = make_plan([0, 4])
    loose.connected, loose.sequence, loose.chords = False, [], [(0, 4), (5, 9)]
    write_plan(loose, tmp_path / "loose.json")
    code, _, err = run(capsys, "estimate", str(tmp_path / "loose.json"), "--machine", "grbl-ring")
    assert code == 2 and "disconnected" in err and len(err.strip().splitlines()) == 1
    fine = tmp_path / "fine.json"
    write_plan(make_plan([0, 4, 1]), fine)
    code, _, err = run(capsys, "gcode", str(fine), "--machine", "dynamixel-ring", "-o", str(tmp_path / "j.gcode"))
    assert code == 2 and "controller.kind = 'dynamixel'" in err
    code, _, err = run(capsys, "gcode", str(small), "--machine", "grbl-ring", "-o", str(tmp_path / "nope" / "j"))
    assert code == 2 and "does not exist" in err
    assert not (tmp_path / "j.gcode").exists()
