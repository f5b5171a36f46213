"""`stringbot calibrate sheet` and `calibrate fit` through the real entry point (a subprocess), the way a maker
runs them: a sheet for a small ring, wound on its simulator, a (synthetic) photo of it, the fitted machine
file, a plan made with it; and every bad input as one line, exit 2, nothing written."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

from firmware_protocol.machine import bundled_dir, load_machine
from stringbot.planner import read_plan
from stringbot.planner.calibration.sheet import design_sheet

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from calibration_photos import camera, render_photo  # noqa: E402


def run(*args, cwd=None):
    p = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", *map(str, args)],
                       capture_output=True, text=True, cwd=cwd, timeout=120)
    return p.returncode, p.stdout, p.stderr


def refused(code, out, err, *needles):
    assert code == 2, (out, err)
    assert err.startswith("stringbot: error: ") and len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, err


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("STRINGBOT_CACHE", str(tmp_path / "cache"))


@pytest.fixture
def small(tmp_path):
    """grbl-ring's file with a smaller ring: 120 pins on 200 mm (its comments kept)."""
    text = (bundled_dir() / "grbl-ring.toml").read_text()
    text = text.replace('name = "grbl-ring"', 'name = "small-ring"').replace("pins = 300 ", "pins = 120 ")
    text = text.replace("diameter_mm = 500.0 ", "diameter_mm = 200.0 ")
    path = tmp_path / "small.toml"
    path.write_text(text)
    return path


def synthetic_photo(path, machine, width):
    m = load_machine(machine)
    sheet = design_sheet(pins=m.pins, diameter_mm=m["ring.diameter_mm"], pin_diameter_mm=m["ring.pin_diameter_mm"],
                         thread_mm=m["thread.diameter_mm"])
    shape = (480, 640)
    tf = camera(sheet, shape, tilt=(-0.1, 0.07), turn=8.0, fill=0.75)
    Image.fromarray(render_photo(sheet, tf, shape, width_mm=width, k=3, gradient=(0.4, 120.0))).save(path)


def test_a_sheet_winds_is_photographed_fitted_and_planned_with(tmp_path, small):
    code, out, err = run("calibrate", "sheet", "--machine", small, "-o", tmp_path / "sheet.json")
    assert code == 0, err
    plan = read_plan(tmp_path / "sheet.json")
    assert plan.pins == 120 and plan.thread_mm == 0.25 and plan.extra["calibration"]["machine"] == "small-ring"
    assert plan.extra["calibration"]["thread_mm"] == 0.25
    assert (tmp_path / "sheet.pdf").read_bytes().startswith(b"%PDF")
    assert f"{plan.stats['lines']} lines" in out and "-> " + str(tmp_path / "sheet.json") in out
    # it winds like any plan (on the machine it names): the simulated machine's record has every pin, in order,
    # and no collision
    code, out, err = run("wind", tmp_path / "sheet.json", "--yes", "--record", tmp_path / "rec.json")
    assert code == 0, err
    record = json.loads((tmp_path / "rec.json").read_text())
    assert [w["pin"] for w in record["wraps"]] == plan.sequence and not record["collisions"]

    synthetic_photo(tmp_path / "photo.png", small, 0.35)
    code, out, err = run("calibrate", "fit", tmp_path / "photo.png", "--machine", small, "--sheet",
                         tmp_path / "sheet.json", "-o", tmp_path / "mine.toml")
    assert code == 0, err
    mine = load_machine(tmp_path / "mine.toml")
    assert abs(mine["thread.effective_mm"] / 0.35 - 1) < 0.05
    assert mine["thread.thread_gray"] < mine["thread.board_gray"] < 1
    calibrated = ("thread.effective_mm", "thread.board_gray", "thread.thread_gray")
    assert {k: v for k, v in mine.values.items() if k not in calibrated} \
        == {k: v for k, v in load_machine(small).values.items() if k not in calibrated}
    text = (tmp_path / "mine.toml").read_text()
    assert "# cotton sewing thread" in text and "# calibrated by `stringbot calibrate fit photo.png`" in text
    assert f"effective width {mine['thread.effective_mm']:.4f} mm" in out
    # without --sheet the sheet is designed again: the same fit
    code, out2, err = run("calibrate", "fit", tmp_path / "photo.png", "--machine", small, "-o", tmp_path / "m2.toml")
    assert code == 0, err
    assert load_machine(tmp_path / "m2.toml").values == mine.values
    # an existing machine file other than --machine's own is not rewritten from --machine's keys (the user's
    # edits kept) unless --force; --machine's own file is calibrated in place, its edits kept
    (tmp_path / "mine.toml").write_text(text + "# my own note\n")
    refused(*run("calibrate", "fit", tmp_path / "photo.png", "--machine", small, "-o", tmp_path / "mine.toml"),
            "exists and is not --machine's file", f"--machine {tmp_path / 'mine.toml'}", "--force")
    assert (tmp_path / "mine.toml").read_text() == text + "# my own note\n"
    code, out, err = run("calibrate", "fit", tmp_path / "photo.png", "--machine", tmp_path / "mine.toml", "-o",
                         tmp_path / "mine.toml")
    assert code == 0, err
    assert "# my own note" in (tmp_path / "mine.toml").read_text()
    assert load_machine(tmp_path / "mine.toml").values == mine.values
    (tmp_path / "m2.toml").write_text(text + "# my own note\n")
    code, out, err = run("calibrate", "fit", tmp_path / "photo.png", "--machine", small, "-o", tmp_path / "m2.toml",
                         "--force")
    assert code == 0, err
    assert "# my own note" not in (tmp_path / "m2.toml").read_text()
    assert load_machine(tmp_path / "m2.toml").values == mine.values

    code, out, err = run("machines", "show", tmp_path / "mine.toml")
    assert code == 0, err
    assert f"effective_mm = {mine['thread.effective_mm']!r}" in out
    assert f"# thread:         calibrated: the planner draws {mine['thread.effective_mm']:g} mm" in out
    # the planner draws the fitted width; without calibration, the diameter as before
    for machine, width in ((tmp_path / "mine.toml", mine["thread.effective_mm"]), (small, 0.25)):
        code, out, err = run("plan", ROOT / "examples" / "camera.png", "-o", tmp_path / "cam.json", "--machine",
                             machine, "--lines", "40", "--size", "101")
        assert code == 0, err
        assert read_plan(tmp_path / "cam.json").thread_mm == width
    # a plan made with the calibrated machine is that machine's: estimate (as wind, gcode, pins) takes it;
    # so is a sheet made with it
    code, out, err = run("plan", ROOT / "examples" / "camera.png", "-o", tmp_path / "cam.json", "--machine",
                         tmp_path / "mine.toml", "--lines", "40", "--size", "101")
    assert code == 0, err
    for plan_path in (tmp_path / "cam.json", tmp_path / "sheet2.json"):
        if plan_path.name == "sheet2.json":
            code, out, err = run("calibrate", "sheet", "--machine", tmp_path / "mine.toml", "-o", plan_path)
            assert code == 0, err
            assert read_plan(plan_path).sequence == plan.sequence      # the same sheet: designed for the diameter
        code, out, err = run("estimate", plan_path, "--machine", tmp_path / "mine.toml")
        assert code == 0, err
    code, out, err = run("estimate", tmp_path / "cam.json", "--machine", small)
    refused(code, out, err, "thread", "--force")
    code, out, err = run("plan", ROOT / "examples" / "camera.png", "-o", tmp_path / "cam2.json", "--machine",
                         tmp_path / "mine.toml", "--lines", "40", "--size", "101", "--thread-mm", "0.25")
    refused(code, out, err, f"(thread.effective_mm = {mine['thread.effective_mm']:g})")


def test_bad_inputs_are_one_line_and_change_nothing(tmp_path, small):
    mine = tmp_path / "mine.toml"            # not written by any of these
    picture = ROOT / "examples" / "camera.png"
    code, out, err = run("calibrate", "sheet", "--machine", "grbl-ring", "-o", tmp_path / "big.json")
    assert code == 0, err
    not_a_picture = tmp_path / "photo.jpg"
    not_a_picture.write_text("hello\n")
    code, out, err = run("plan", picture, "-o", tmp_path / "cam.json", "--pins", "60", "--lines", "20",
                         "--size", "101")
    assert code == 0, err
    cases = [
        (("calibrate", "fit", picture, "--machine", small, "-o", mine),
         ("marks were not found", "expected a photo of the whole wound sheet from `stringbot calibrate sheet`")),
        (("calibrate", "fit", not_a_picture, "--machine", small, "-o", mine),
         ("is not a picture PIL can read; expected PNG, JPEG",)),
        (("calibrate", "fit", picture, "--machine", small, "--sheet", tmp_path / "big.json", "-o", mine),
         ("is a calibration sheet for machine 'grbl-ring' (300 pins on 500.0 mm), not for machine 'small-ring'",)),
        (("calibrate", "fit", picture, "--machine", small, "--sheet", tmp_path / "cam.json", "-o", mine),
         ("is a plan but not a calibration sheet",)),
        (("calibrate", "fit", picture, "--machine", small, "-o", tmp_path / "mine.txt"),
         ("expected a machine file name ending in .toml",)),
        (("calibrate", "fit", picture, "--machine", small, "-o", bundled_dir() / "grbl-ring.toml"),
         ("among the bundled machine files",)),
        (("calibrate", "sheet", "--machine", small, "-o", tmp_path / "s.json", "--template", tmp_path / "s.png"),
         ("expected a file name ending in .pdf or .svg",)),
    ]
    keep = tmp_path / "keep.toml"
    keep.write_text("[tool.mine]\nkeep = true\n")
    (tmp_path / "notes.json").write_text('{"mine": 1}\n')
    other = tmp_path / "other.toml"          # a machine file of the user's own, not --machine's
    other.write_text(small.read_text().replace('name = "small-ring"', 'name = "other-ring"'))
    other_text = other.read_text()
    cases += [
        (("calibrate", "fit", picture, "--machine", small, "-o", keep),
         ("exists and is not a machine file; not replacing it",)),
        (("calibrate", "fit", picture, "--machine", small, "-o", other),
         (f"machine file {str(other)!r} exists and is not --machine's file", "give another -o, or --force")),
        (("calibrate", "sheet", "--machine", small, "-o", tmp_path / "notes.json"),
         ("exists and is a JSON file stringbot did not write",)),
    ]
    for args, needles in cases:
        refused(*run(*args), *needles)
    assert other.read_text() == other_text
    assert keep.read_text() == "[tool.mine]\nkeep = true\n" and (tmp_path / "notes.json").read_text() == '{"mine": 1}\n'
    assert not mine.exists() and not (tmp_path / "s.json").exists() and not (tmp_path / "mine.txt").exists()
    few = tmp_path / "few.toml"
    few.write_text(small.read_text().replace("pins = 120 ", "pins = 40 "))
    refused(*run("calibrate", "sheet", "--machine", few, "-o", tmp_path / "s.json"), "at least 60 pins")


@pytest.mark.parametrize("line, needle", [
    ("effective_mm = 0.0", "thread.effective_mm is 0.0; expected a number > 0.0 and <= 5.0"),
    ("board_gray = 1.5", "thread.board_gray is 1.5; expected a number >= 0.0 and <= 1.0"),
    ("board_gray = 0.5\nthread_gray = 0.6", "thread.thread_gray 0.6 is not darker than thread.board_gray 0.5"),
])
def test_the_calibrated_keys_are_checked(tmp_path, small, line, needle):
    bad = tmp_path / "bad.toml"
    bad.write_text(small.read_text().replace("[thread]\n", f"[thread]\n{line}\n"))
    refused(*run("machines", "show", bad), needle)


def test_a_machine_file_without_a_thread_table_is_written_out_whole(tmp_path, small):
    from stringbot.cli.calibrate import calibrated_text

    dotted = tmp_path / "dotted.toml"
    text = small.read_text().replace("[thread]\ndiameter_mm = 0.25", "")
    text = text.replace('name = "small-ring"', 'name = "small-ring"\nthread.diameter_mm = 0.25')
    dotted.write_text(text)
    m = load_machine(dotted)
    out = tmp_path / "out.toml"
    out.write_text(calibrated_text(m, {"effective_mm": 0.3, "board_gray": 0.9, "thread_gray": 0.2}, note="test"))
    back = load_machine(out)
    assert back.values == dict(m.values, **{"thread.effective_mm": 0.3, "thread.board_gray": 0.9,
                                            "thread.thread_gray": 0.2})
    assert os.path.getsize(out) > 0
