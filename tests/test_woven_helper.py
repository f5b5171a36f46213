"""The polish on two cores: the same plan as on one, and a helper that fails costs only time."""

import logging
import os
import sys

import numpy as np
import pytest

from stringbot.planner.methods import woven_helper
from stringbot.planner.build import plan_picture
from stringbot.planner.methods.residual import PATIENCE, POLISH_ROUNDS

from planner_helpers import picture
from test_polish import horse_like

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="the helper processes are forked")


def _plan(monkeypatch, processes, **kw):
    monkeypatch.setenv("STRINGBOT_PROCESSES", str(processes))
    return plan_picture("x.png", picture=picture(horse_like(301)), pins=60, size=301, polish=160, **kw)


def _no_children_left():
    """True when this process has no child processes (running or not waited for)."""
    try:
        os.waitpid(-1, os.WNOHANG)
    except ChildProcessError:
        return True
    return False


def test_two_processes_make_the_plan_one_makes(monkeypatch):
    one = _plan(monkeypatch, 1)
    two = _plan(monkeypatch, 2)
    assert one.stats["polish_processes"] == 1 and two.stats["polish_processes"] == 2
    assert one.stats["polish"]["rerouted"] > 0 and len(one.stats["polish"]["rerouted_by_round"]) == POLISH_ROUNDS > 1
    assert two.sequence == one.sequence
    assert two.stats["polish"]["woven_rms"] == one.stats["polish"]["woven_rms"]
    # the helper drew the chosen threads while they were chosen (all but at most the last PATIENCE)
    assert len(two.sequence) - 1 - PATIENCE <= two.stats["polish"]["drawn_early"] <= len(two.sequence) - 1
    assert _no_children_left()


def test_a_helper_that_fails_leaves_the_polish_here(monkeypatch, caplog):
    one = _plan(monkeypatch, 1)

    def broken(conn, make_canvas, space):
        raise RuntimeError("the helper breaks")

    monkeypatch.setattr(woven_helper, "_serve", broken)
    with caplog.at_level(logging.WARNING, logger="stringbot.planner.methods.woven_helper"):
        two = _plan(monkeypatch, 2)
    assert "helper process failed" in caplog.text
    assert two.stats["polish_processes"] == 1
    assert two.sequence == one.sequence
    assert _no_children_left()


def test_a_twin_that_dies_leaves_the_polish_here(monkeypatch):
    one = _plan(monkeypatch, 1)

    def dying_twin(canvas, seq, order, pin_lines, **kw):
        from multiprocessing.connection import Pipe

        here, there = Pipe()
        pid = woven_helper._fork(lambda: os._exit(3))  # gone before its first proposal
        there.close()
        return woven_helper.Partner(here, 0, woven_helper.buffers(canvas, 2), pid)

    monkeypatch.setattr(woven_helper, "twin", dying_twin)
    two = _plan(monkeypatch, 2)
    assert two.stats["polish_processes"] == 1
    assert two.sequence == one.sequence
    assert _no_children_left()


def test_the_number_of_processes_follows_the_setting(monkeypatch):
    monkeypatch.setenv("STRINGBOT_PROCESSES", "1")
    assert not woven_helper.two_cores()
    monkeypatch.setenv("STRINGBOT_PROCESSES", "2")
    assert woven_helper.two_cores()
    monkeypatch.delenv("STRINGBOT_PROCESSES")
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert woven_helper.two_cores() == (cores >= 2 and sys.platform.startswith("linux"))


def test_the_twin_draws_the_preview_one_process_would(monkeypatch):
    from stringbot.planner.model.render import png_bytes, preview_drawing, preview_png

    one = _plan(monkeypatch, 1, preview=1001)
    two = _plan(monkeypatch, 2, preview=1001)
    assert one.woven_drawings is None and two.woven_drawings is not None
    np.testing.assert_array_equal(preview_drawing(two, 1001), preview_drawing(one, 1001))
    # the twin encoded the PNG too: the bytes the planner's own process would write
    assert two.woven_drawings.png(1001, 255, 0) == png_bytes(preview_drawing(one, 1001))
    assert preview_png(two, 1001) == preview_png(one, 1001)
    assert two.woven_drawings(501, 255, 0) is None  # another size: drawn by the caller
    assert two.woven_drawings.png(501, 255, 0) is None
    assert preview_png(two, 501) == png_bytes(preview_drawing(two, 501))  # drawn here
    two.woven_drawings.close()
    assert _no_children_left()


@pytest.mark.parametrize("missing", [(0, 1), (0,), (1,)])
def test_a_half_not_drawn_leaves_the_preview_here(monkeypatch, caplog, missing):
    from stringbot.planner.model.render import png_bytes, preview_drawing, preview_png

    one = _plan(monkeypatch, 1, preview=1001)
    make = woven_helper.TwinDrawing.make

    def no_drawing(self, canvas, seq, half):
        if half in missing:
            self._say.close()  # the twin (half 0) or the helper (half 1) ends without a word
        else:
            make(self, canvas, seq, half)

    monkeypatch.setattr(woven_helper.TwinDrawing, "make", no_drawing)
    two = _plan(monkeypatch, 2, preview=1001)
    with caplog.at_level(logging.WARNING, logger="stringbot.planner.methods.woven_helper"):
        img = preview_drawing(two, 1001)
    assert "did not draw the preview" in caplog.text
    # drawn here from the plan's threads: the drawing the twin would have made
    np.testing.assert_array_equal(img, preview_drawing(one, 1001))
    assert two.woven_drawings.png(1001, 255, 0) is None and preview_png(two, 1001) == png_bytes(img)
    assert two.sequence == one.sequence
    two.woven_drawings.close()
    assert _no_children_left()


def test_plan_on_the_command_line_is_the_same_on_one_core_and_two(tmp_path, monkeypatch):
    import subprocess
    import sys

    from PIL import Image

    img = tmp_path / "horse.png"
    Image.fromarray(horse_like(301).astype(np.uint8)).save(img)
    outs = {}
    for n in (1, 2):
        env = dict(os.environ, STRINGBOT_PROCESSES=str(n))
        out = tmp_path / f"p{n}.json"
        r = subprocess.run([sys.executable, "-m", "stringbot.cli", "plan", str(img), "-o", str(out), "--pins", "60",
                            "--polish", "120"], capture_output=True, text=True, env=env, timeout=300)
        assert r.returncode == 0, r.stderr
        outs[n] = (out.read_text(), np.asarray(Image.open(tmp_path / f"p{n}.png")))
    import json

    p1, p2 = (json.loads(outs[n][0]) for n in (1, 2))
    assert p1["sequence"] == p2["sequence"] and p2["stats"]["polish_processes"] == 2
    np.testing.assert_array_equal(outs[1][1], outs[2][1])


def test_a_wrong_setting_is_one_line_and_exit_2(tmp_path):
    import subprocess

    from PIL import Image

    img = tmp_path / "horse.png"
    Image.fromarray(horse_like(64).astype(np.uint8)).save(img)
    out = tmp_path / "p.json"
    r = subprocess.run([sys.executable, "-m", "stringbot.cli", "plan", str(img), "-o", str(out), "--pins", "40"],
                       capture_output=True, text=True, env=dict(os.environ, STRINGBOT_PROCESSES="two"), timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        "stringbot: error: STRINGBOT_PROCESSES='two'; expected 1 (one process) or 2 (a helper and its twin), "
        "or unset (two on Linux with two cores)"]
    assert not out.exists()


@pytest.mark.parametrize("helper_fills", [True, False])
def test_the_chord_points_laid_out_by_the_helper_are_the_ones_built_here(helper_fills):
    import time

    from stringbot.planner.model.chords import chord_space
    from stringbot.planner.model.lines import PinLines

    space = chord_space(24, "circle")
    fresh = [PinLines(space, 61, nearest=True, spacing=2.0), PinLines(space, 32, nearest=True)]
    lines = [PinLines(space, 61, nearest=True, spacing=2.0), PinLines(space, 32, nearest=True)]
    from stringbot.planner.methods.shared_points import SharedPoints

    shared = SharedPoints(lines, [(1, p) for p in range(24)] + [(0, p) for p in range(23, -1, -1)])
    assert lines[0].get_with_counts(0)[1] is not None  # built here before the helper: skipped by it
    pid = woven_helper._fork(shared.fill if helper_fills else lambda: None)
    shared.sent()
    os.waitpid(pid, 0)
    time.sleep(0.01)
    taken = 0
    for which in range(2):
        for p in range(24):
            taken += shared.points(lines[which], p) is not None
            got, want = lines[which].get_with_counts(p), fresh[which].get_with_counts(p)
            for a, b in zip(got, want):
                np.testing.assert_array_equal(a, b)
                assert a.dtype == b.dtype
    assert taken == (47 if helper_fills else 0)  # every pin's but the one built here, or none
    assert _no_children_left()
