"""`stringbot pins`: the pin list for winding by hand, through the real entry point."""

import csv
import io
import json

import numpy as np
import pytest

from stringbot.planner.model.chords import pin_positions
from stringbot.planner.plan_file import Plan, write_plan
from test_cli_plan import one_error_line, run
from test_gcode_replay import make_plan, random_sequence


@pytest.fixture
def plan_file(tmp_path):
    path = tmp_path / "p.json"
    plan = make_plan(random_sequence(250, seed=4))
    plan.diameter_mm, plan.thread_mm = 500.0, 0.25      # as `plan` records them (a hand-made plan may not)
    write_plan(plan, path)
    return path


def rows_of_csv(text):
    body = [ln for ln in text.splitlines() if not ln.startswith("#")]
    return list(csv.DictReader(io.StringIO("\n".join(body))))


def test_wrap_directions_are_what_the_simulated_machine_winds(tmp_path, plan_file):
    out, rec = tmp_path / "pins.csv", tmp_path / "rec.json"
    code, stdout, err = run("pins", plan_file, "-o", out, "--machine", "grbl-ring")
    assert code == 0, err
    rows = rows_of_csv(out.read_text())
    assert [int(r["step"]) for r in rows] == list(range(1, 251))
    code, _, err = run("wind", plan_file, "--machine", "grbl-ring", "--yes", "--record", rec)
    assert code == 0, err
    wraps = json.loads(rec.read_text())["wraps"]
    assert [int(r["pin"]) for r in rows] == [w["pin"] for w in wraps]
    named = {1: "cw", -1: "ccw"}
    checked = 0
    for r, w in zip(rows, wraps):
        if r["wrap"] != "either":
            assert r["wrap"] == named[w["direction"]], (r, w)
            checked += 1
    assert checked >= 240


def test_text_has_a_header_and_pages_of_100_steps(tmp_path, plan_file):
    out = tmp_path / "pins.txt"
    code, stdout, err = run("pins", plan_file, "-o", out, "--diameter-mm", "500")
    assert code == 0, err
    text = out.read_text()
    pages = text.split("\f")
    assert len(pages) == 3
    head = pages[0].splitlines()[:6]
    assert head[1].startswith("plan:") and "p.json" in head[1]
    assert head[2].startswith("pins:") and "300 on a ring" in head[2] and "clockwise" in head[2]
    assert head[3].startswith("lines:") and "249" in head[3]
    plan = make_plan(random_sequence(250, seed=4))
    xy = plan.pin_xy[plan.sequence]
    metres = np.linalg.norm(np.diff(xy, axis=0), axis=1).sum() * 500 / 1000
    assert head[4].startswith("thread:") and f"{metres:.1f} m" in head[4] and "diameters" not in head[4]
    steps = [ln.split() for page in pages for ln in page.splitlines() if ln.strip()[:1].isdigit()]
    assert [int(s[0]) for s in steps] == list(range(1, 251))
    assert [len([ln for ln in p.splitlines() if ln.strip()[:1].isdigit()]) for p in pages] == [100, 100, 50]
    assert "page 2 of 3: steps 101-200 of 250" in pages[1]


def test_dash_writes_to_standard_output(tmp_path, plan_file):
    code, stdout, err = run("pins", plan_file, "-o", "-")
    assert code == 0, err
    assert stdout.startswith("stringbot pin list") and "500 mm ring diameter, from the plan" in stdout
    assert "250 steps" in err and not list(tmp_path.glob("-*"))


def test_without_o_the_list_goes_to_standard_output(tmp_path, plan_file):
    code, stdout, err = run("pins", plan_file)
    assert code == 0, err
    assert stdout.startswith("stringbot pin list") and "250 steps" in err and "Missing option" not in err


def test_a_square_frame_counts_from_the_top_left_corner(tmp_path):
    pins = 40
    seq = [0, 5, 10, 3, 20, 39, 1]
    plan = Plan(pins=pins, frame="square", pin_xy=pin_positions(pins, "square"), crop={"cx": 1, "cy": 1, "r": 1},
                sequence=seq, method="hand", source={"path": "x.png"})
    path, out = tmp_path / "sq.json", tmp_path / "sq.csv"
    write_plan(plan, path)
    code, _, err = run("pins", path, "-o", out, "--diameter-mm", "400")
    assert code == 0, err
    text = out.read_text()
    assert "numbered from the top-left corner, clockwise" in text and "400 mm frame side" in text
    rows = rows_of_csv(text)
    xy = pin_positions(pins, "square")
    corner = next(i for i in range(pins) if np.allclose(xy[i], [0, 0]))   # 40 pins: one on the corner
    for r in rows:
        assert int(r["pin"]) == (int(r["plan_pin"]) - corner) % pins
    assert rows[0]["plan_pin"] == "0" and rows[0]["pin"] == str(pins - corner)
    # counting clockwise from the corner: pin 1 lies along the top side, to the right of pin 0
    assert xy[(corner + 1) % pins][1] == 0 and xy[(corner + 1) % pins][0] > 0


@pytest.mark.parametrize("args, words", [
    (["-o", "x.pdf"], "expected a file name ending in .txt or .csv"),
    (["-o", "x.txt", "--machine", "marlin-ring", "--diameter-mm", "300"], "give one of them"),
    (["-o", "x.txt", "--diameter-mm", "3"], "--diameter-mm 3"),
])
def test_bad_pins_input_is_one_line(tmp_path, plan_file, args, words):
    code, _, err = run("pins", plan_file, *args, cwd=tmp_path)
    one_error_line(code, err, words)
    assert not (tmp_path / "x.txt").exists()


def test_a_plan_for_another_ring_or_a_square_plan_with_a_ring_machine_is_refused(tmp_path):
    path = tmp_path / "p.json"
    write_plan(make_plan([0, 5, 9], pins=40), path)
    one_error_line(*run("pins", path, "-o", tmp_path / "x.txt", "--machine", "grbl-ring")[::2],
                   "has ring.pins = 300")
    sq = Plan(pins=300, frame="square", pin_xy=pin_positions(300, "square"), crop={"cx": 1, "cy": 1, "r": 1},
              sequence=[0, 5, 9], method="hand", source={})
    write_plan(sq, path)
    one_error_line(*run("pins", path, "-o", tmp_path / "x.txt", "--machine", "grbl-ring")[::2],
                   "winds a ring")


def test_a_colour_plan_is_listed_thread_by_thread_as_the_simulated_machine_winds_it(tmp_path):
    from test_colour_plan import colour_plan
    path, out, rec = tmp_path / "c.json", tmp_path / "pins.csv", tmp_path / "rec.json"
    plan = colour_plan(pins=300, n=(40, 30, 25))
    plan.diameter_mm, plan.thread_mm = 500.0, 0.25
    write_plan(plan, path)
    code, _, err = run("pins", path, "-o", out, "--machine", "grbl-ring")
    assert code == 0, err
    text = out.read_text()
    assert "# threads: 3, wound in this order" in text and "#c8102e): steps 41-70, tie on at pin" in text
    rows = rows_of_csv(text)
    code, _, err = run("wind", path, "--machine", "grbl-ring", "--yes", "--record", rec)
    assert code == 0, err
    wraps = json.loads(rec.read_text())["wraps"]
    assert [(int(r["pin"]), r["color"]) for r in rows] == [(w["pin"], w["color"]) for w in wraps]
    named = {1: "cw", -1: "ccw"}
    assert all(r["wrap"] in ("either", named[w["direction"]]) for r, w in zip(rows, wraps))
    txt = tmp_path / "pins.txt"
    code, _, err = run("pins", path, "-o", txt)
    assert code == 0, err
    lines = txt.read_text().splitlines()
    k = next(i for i, x in enumerate(lines) if x.startswith("        -- thread 2 of 3: cut the thread; tie ")
             and x.endswith(f"(#c8102e) on at pin {plan.layers[1].sequence[0]} --"))
    assert lines[k + 1].split()[:2] == ["41", str(plan.layers[1].sequence[0])]
