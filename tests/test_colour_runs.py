"""Colour in runs: the planner returns to a colour within its spool-change budget, and such a plan
winds run by run (each run a layer: its spool change, its journal record, its resume)."""

import json

import numpy as np
import pytest

from firmware_protocol.machine import load_machine
from stringbot.cli import main
from stringbot.errors import MachineFailure
from stringbot.links import sim_url
from stringbot.planner import read_plan, write_plan
from stringbot.planner.colour.build import plan_colour
from stringbot.planner.colour.frames import colour_growth_frames
from stringbot.planner.colour.render import PREVIEW_SAMPLES, plan_layers, to_uint8, woven_rgb
from stringbot.planner.colour.runs import fit_schedule, no_short_runs
from stringbot.winding import Job, read_journal, wind_plan
from stringbot.winding.resume import resume_plan

from test_colour_plan import THICK, colour_plan, picture, run  # noqa: F401  (picture: a fixture)
from test_colour_wind import check_layers, hands_at
from test_spool_change import resume_command, seen, stringbot, tie_on
from test_wind_pty import Simulator
from test_wind_sim import eyes_at

pytestmark = pytest.mark.timeout(300)


def test_the_draft_is_merged_down_to_the_budget_each_colour_keeping_its_lines():
    runs = [(0, [0] * 6), (1, [0] * 4), (0, [0] * 5), (2, [0] * 2), (0, [0] * 3)]     # A5 B3 A4 C1 A2
    assert fit_schedule(runs, 5) == [(0, 5), (1, 3), (0, 4), (2, 1), (0, 2)]
    assert fit_schedule(runs, 3) == [(1, 3), (0, 11), (2, 1)]       # A's short runs joined, B and C kept
    assert fit_schedule(runs, 2) == [(1, 3), (0, 11)]               # fewer runs than colours: the least goes
    assert fit_schedule(runs, 1) == [(0, 11)]


def test_the_schedule_does_not_end_with_the_darkest_thread_while_it_has_a_run_before():
    runs = [(0, [0] * 6), (1, [0] * 4), (0, [0] * 5), (2, [0] * 2), (0, [0] * 3)]     # A5 B3 A4 C1 A2
    assert fit_schedule(runs, 5, darkest=0) == [(0, 5), (1, 3), (0, 6), (2, 1)]    # A's last two lines to A4
    assert fit_schedule(runs, 5, darkest=2) == fit_schedule(runs, 5)               # C not last: as it was
    assert fit_schedule([(0, [0] * 3), (1, [0] * 4)], 5, darkest=1) == [(0, 2), (1, 3)]   # B's only run stays


def test_the_darkest_threads_late_runs_join_its_run_before():
    runs = [(0, [0] * 6), (1, [0] * 4), (0, [0] * 5), (2, [0] * 2), (0, [0] * 3)]     # A5 B3 A4 C1 A2 (15)
    # late 0.5: A4 starts at 8 of 15, past the first half: it and A2 join A5
    assert fit_schedule(runs, 5, darkest=0, late=0.5) == [(0, 11), (1, 3), (2, 1)]
    assert fit_schedule(runs, 5, darkest=0, late=0.2) == [(0, 5), (1, 3), (0, 6), (2, 1)]   # A2 only (and not last)
    assert fit_schedule(runs, 5, darkest=1, late=0.9) == fit_schedule(runs, 5, darkest=1)   # B's one run: as it was


def test_auto_gives_n_threads_or_says_why_fewer(picture, tmp_path, capsys):
    from stringbot.planner.colour.reach import auto_palette
    from stringbot.planner.picture.read import read_picture

    rgb = read_picture(picture, size=64).rgb          # red, blue, black and white: the list has them all
    three = auto_palette(rgb, 3)
    assert len(three.colors) == 3 and three.why_fewer is None and three.reach[-1] < three.reach[0]
    six = auto_palette(rgb, 6)
    assert 3 <= len(six.colors) < 6 and "no nearer" in six.why_fewer
    assert "only 2 of the 3 threads" in auto_palette(rgb, 3, candidates=["#141414", "#1f5bb5", "#ffffff"]).why_fewer
    code, out, err = run(["plan", str(picture), "-o", str(tmp_path / "a.json"), "--pins", "40", "--size", "64",
                          "--lines", "60", "--colors", "auto:6", "--no-cache"], capsys)
    assert code == 0, err
    assert f"--colors auto:6: {len(six.colors)} thread(s): a thread more would bring" in out


def test_the_planner_returns_to_a_colour_within_its_spool_change_budget(picture):
    kw = dict(colors=["#141414", "#c8102e", "#1f5bb5"], pins=60, size=64, lines=400, cache=False, model=THICK)
    plan = plan_colour(picture, spool_changes=4, min_run=20, **kw)
    colours = plan.colors
    assert len(colours) <= 5 and len(set(colours)) < len(colours)                    # a colour came back
    assert all(a != b for a, b in zip(colours[:-1], colours[1:]))                   # a change is a change
    s = plan.stats
    assert s["spool_changes"] == len(colours) - 1 == s["runs"] - 1
    assert sum(v["lines"] for v in s["colors"].values()) == s["lines"] == len(plan.chord_list())
    assert plan.parameters["spool_changes"] == 4 and plan.parameters["min_run"] == 20
    one = plan_colour(picture, spool_changes=0, min_run=20, **kw)
    assert len(one.colors) == 1 and len(one.stats["unused"]) == 2 and one.stats["spool_changes"] == 0


def test_the_last_frame_of_the_animation_is_the_preview(tmp_path, picture, capsys):
    out = tmp_path / "c.json"
    code, _, err = run(["plan", str(picture), "-o", str(out), "--pins", "40", "--size", "64", "--lines", "120",
                        "--colors", "black,crimson,blue", "--spool-changes", "3", "--min-run", "15",
                        "--diameter-mm", "100", "--thread-mm", "0.5", "--no-cache"], capsys)
    assert code == 0, err
    plan = read_plan(out)
    from PIL import Image
    preview = np.asarray(Image.open(tmp_path / "c.png"))
    frames = list(colour_growth_frames(plan, frames=3, size=1001))
    assert frames[-1][1] == len(plan.chord_list())
    np.testing.assert_array_equal(frames[-1][0], preview)
    small = to_uint8(woven_rgb(plan_layers(plan), plan.pin_xy, background=plan.background, size=150,
                               thread_fraction=plan.thread_model().fraction, samples=PREVIEW_SAMPLES))
    np.testing.assert_array_equal(list(colour_growth_frames(plan, frames=2, size=150))[-1][0], small)
    assert not np.array_equal(frames[0][0], frames[-1][0])                       # it grows


@pytest.fixture
def runs_plan(tmp_path, capsys, picture):
    """A plan the planner made for grbl-ring in which a colour comes back (4 runs: crimson twice)."""
    path = tmp_path / "r.json"
    code, out, err = run(["plan", str(picture), "-o", str(path), "--machine", "grbl-ring", "--size", "150",
                          "--lines", "60", "--colors", "black,crimson,blue", "--spool-changes", "4",
                          "--min-run", "10"], capsys)
    assert code == 0, err
    assert "in 4 run(s)" in out and "spool change(s)" in out and "run(s)" in out.splitlines()[2]  # per colour
    plan = read_plan(path)
    assert len(plan.colors) == 4 and len(set(plan.colors)) == 3
    return plan, path


def test_a_plan_whose_colour_comes_back_stops_at_each_spool_change_and_resumes_run_by_run(tmp_path, capsys,
                                                                                         runs_plan):
    plan, path = runs_plan
    code, text, _ = run(["pins", str(path), "-o", "-"], capsys)
    assert code == 0
    for k, lay in enumerate(plan.layers):          # the pin list: thread by thread, run by run
        assert f"thread {k + 1} of 4: " in text and f"{lay.color}) on at pin {lay.sequence[0]}" in text
    assert "4 runs of 3 colours" in text
    head = dict(ln.split(":", 1) for ln in text.split("\n\n")[0].splitlines()[1:])
    # (a plan for a machine) the total with the turns round the pins, the runs' and colours' without them
    assert "m for a 500 mm ring" in head["thread"] and "with the turns" in head["thread"]
    assert "without the turns" in head["threads"] and "without the turns" in head["colours"]
    journal = tmp_path / "r.journal"
    sim = Simulator(tmp_path, "grbl-ring")
    want = [(pin, lay.color) for lay in plan.layers for pin in lay.sequence]
    try:
        tie_on(sim, plan.colors[0], plan.sequence[0])
        args = ["wind", path, "--machine", "grbl-ring", "--port", sim.pty, "--yes", "--journal", journal]
        for k in (1, 2, 3):
            p = stringbot(args)
            assert p.returncode == 3, p.stderr
            start = plan.layer_starts[k]
            assert f"(layer {k + 1} of 4)" in p.stderr.strip().splitlines()[-1]
            got, rec = seen(sim)
            assert got == want[:start] and rec["collisions"] == []
            tie_on(sim, plan.colors[k], plan.sequence[start])
            args = resume_command(p.stderr)
        p = stringbot(args)
        assert p.returncode == 0, p.stderr
    finally:
        sim.stop()
    got, rec = seen(sim)
    assert got == want and rec["collisions"] == []
    assert [s["color"] for s in rec["spools"]] == plan.colors                    # crimson tied on twice
    records = [json.loads(x) for x in journal.read_text().splitlines()]
    assert [(r["layer"], r["color"], r["step"]) for r in records if r["kind"] == "layer"] == \
        [(k, c, s) for k, (c, s) in enumerate(zip(plan.colors, plan.layer_starts))]
    assert [r["layer"] for r in records if r["kind"] == "stop"] == [1, 2, 3]


def test_a_dry_run_of_it_through_the_cli_winds_every_run_with_its_thread(tmp_path, capsys, runs_plan):
    plan, path = runs_plan
    record = tmp_path / "rec.json"
    code, _, err = run(["wind", str(path), "--yes", "--record", str(record)], capsys)
    assert code == 0, err
    rec = check_layers(record, plan)
    assert [(s["color"], s["pin"]) for s in rec["spools"]] == [(lay.color, lay.sequence[0]) for lay in plan.layers]
    code, text, _ = run(["gcode", str(path), "-o", "-"], capsys)
    assert code == 0 and text.splitlines().count("M0") == 3


def test_a_resume_inside_the_run_of_a_colour_that_came_back_asks_for_no_thread(tmp_path):
    plan = colour_plan(layers=[("#1f5bb5", [3, 150, 40, 200, 90, 260]), ("#c8102e", [10, 160, 50, 210, 100, 270]),
                               ("#1f5bb5", [20, 170, 60, 220, 110, 280])])
    path = tmp_path / "c.json"
    write_plan(plan, path)
    record = tmp_path / "rec.json"
    # GRBL receives $I, G21, G90, G94, then two lines per move, 4 moves a step (5 for the first):
    # the third run (steps 12-17) takes lines 103-150
    job = Job(path, load_machine("grbl-ring"), port=sim_url("grbl-ring", record=record, faults="disconnect@125"),
              journal=tmp_path / "c.journal")
    asked = []

    def confirm(q):
        asked.append(q)
        return True

    with pytest.raises(MachineFailure):
        wind_plan(job, confirm=confirm, link_options={"response_timeout": 1.0}, hands=hands_at(job.url),
                  eyes=eyes_at(job.url))
    state = read_journal(job.journal_path)
    assert plan.layer_starts[2] < state.next_step < len(plan.sequence)           # inside the third run
    assert [r["layer"] for r in state.layers] == [0, 1, 2]
    before = len(asked)
    resume_plan(job, confirm=confirm, link_options={"response_timeout": 1.0}, hands=hands_at(job.url))
    assert not any("thread on at pin" in q for q in asked[before:])             # blue is on: the third run's
    check_layers(record, plan)
    assert read_journal(job.journal_path).finished


def test_no_run_of_the_schedule_is_shorter_than_the_least_a_spool_change_is_worth():
    """A run under the least (the draft's last, cut by its budget) joins its colour's nearest run, else the
    run before it: the colour then has no run and the plan says it is unused; the lines are all kept."""
    sched = [(0, 1660), (2, 100), (0, 4671), (2, 200), (1, 14)]
    out = no_short_runs(sched, 100)
    assert out == [(0, 1660), (2, 100), (0, 4671), (2, 214)]
    assert sum(n for _, n in out) == sum(n for _, n in sched)
    assert no_short_runs([(1, 30), (0, 500), (1, 400)], 100) == [(0, 500), (1, 430)]  # to its own colour
    assert no_short_runs([(2, 20), (0, 500)], 100) == [(0, 520)]                       # the first: to the next
    assert no_short_runs([(0, 40)], 100) == [(0, 40)]                                    # one run stays
    assert no_short_runs(sched, 10) == sched                                             # none short: unchanged

