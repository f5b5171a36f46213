"""Passes of inserted and deleted pins after the polish (``--polish-passes``): never worse, recorded, checked."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from stringbot.planner.build import plan_picture
from stringbot.planner.methods.polish import move_passes, polish_lines
from stringbot.planner.model.chords import chord_space, frame_mask
from stringbot.planner.model.scoring import woven_error
from stringbot.planner.picture.resample import resize_square

from planner_helpers import picture
from test_polish import horse_like, polished_canvas, random_thread


def test_the_passes_lower_the_error_of_the_plan_they_start_from_and_keep_one_thread():
    space = chord_space(60)
    g = horse_like()
    mask = frame_mask(g.shape[0], "circle")
    t = np.where(mask, 1 - g / 255.0, 0.0)
    seq = random_thread(space, 120, seed=3)  # a deliberately poor thread: chords anywhere
    chords0 = list(zip(seq[:-1], seq[1:]))
    woven = polished_canvas(t, mask, space, chords0)
    out = list(seq)
    made = move_passes(woven, out, polish_lines(space, woven), passes=2, budget=len(seq))
    chords1 = list(zip(out[:-1], out[1:]))
    # as `stringbot score` sees the piece (its own drawing of the threads, at 512 px)
    gray = resize_square(g, 512)
    e0, e1 = (woven_error(c, space.pin_xy, gray, frame="circle") for c in (chords0, chords1))
    assert made["inserted"] > 0 and made["deleted"] > 0
    assert len(out) == len(seq) + made["inserted"] - made["deleted"]
    assert out[0] == seq[0] and out[-1] == seq[-1]
    assert all(space.index[a, b] >= 0 for a, b in chords1)  # every chord a chord; no pin twice in a row
    assert e1 < 0.97 * e0
    # the canvas kept in step, move by move: its error is that of the thread returned, drawn afresh
    assert woven.error() == pytest.approx(polished_canvas(t, mask, space, chords1).error(), rel=1e-6)


def _plan(**kw):
    return plan_picture("x.png", picture=picture(horse_like(101)), pins=60, size=101, **kw)


@pytest.fixture(scope="module")
def plans():
    """The default plan of a small picture, and with a pass of inserts and deletes on one process and on two."""
    old = os.environ.get("STRINGBOT_PROCESSES")
    try:
        os.environ["STRINGBOT_PROCESSES"] = "1"
        plain, one = _plan(), _plan(polish_passes=1)
        if hasattr(os, "fork"):
            os.environ["STRINGBOT_PROCESSES"] = "2"
        two = _plan(polish_passes=1)
    finally:
        if old is None:
            os.environ.pop("STRINGBOT_PROCESSES")
        else:
            os.environ["STRINGBOT_PROCESSES"] = old
    return plain, one, two


def test_the_passes_start_from_the_polished_plan_never_raise_its_error_and_are_recorded(plans):
    plain, more, _ = plans
    assert plain.parameters["polish_passes"] == 0 and "passes" not in plain.stats["polish"]
    assert more.parameters["polish_passes"] == 1
    ps = more.stats["polish"]
    assert ps["passes"] == 1 and ps["inserted"] > 0 and ps["deleted"] > 0
    # the passes start from the plan the polish alone makes, and only lower its error
    assert ps["woven_rms_rerouted"] == plain.stats["polish"]["woven_rms"]
    assert ps["woven_rms"] < ps["woven_rms_rerouted"]
    assert len(more.sequence) == len(plain.sequence) + ps["inserted"] - ps["deleted"]
    # as `stringbot score` sees the piece, too
    gray = resize_square(np.asarray(horse_like(101), dtype=float), 512)
    e_plain, e_more = (woven_error(p.chord_list(), p.pin_xy, gray, frame="circle") for p in (plain, more))
    assert e_more < e_plain


@pytest.mark.skipif(not hasattr(os, "fork"), reason="the helper processes are forked")
def test_one_process_and_two_make_the_same_plan(plans):
    _, one, two = plans
    assert one.stats["polish_processes"] == 1 and two.stats["polish_processes"] == 2
    assert two.sequence == one.sequence
    assert two.stats["polish"]["woven_rms"] == one.stats["polish"]["woven_rms"]


def test_polish_passes_on_the_command_line(tmp_path):
    from PIL import Image

    img = tmp_path / "blob.png"
    Image.fromarray(horse_like(160).astype(np.uint8)).save(img)
    out = tmp_path / "p.json"
    env = dict(os.environ, STRINGBOT_CACHE=str(tmp_path / "cache"))

    def run(*args):
        p = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", "plan", str(img),
                            "-o", str(out), "--pins", "60", "--size", "101", *args],
                           capture_output=True, text=True, env=env, timeout=120)
        return p.returncode, p.stderr.strip()

    code, err = run("--polish-passes", "1", "--polish", "50")
    assert code == 0, err
    doc = json.loads(out.read_text())
    assert doc["parameters"]["polish_passes"] == 1 and doc["stats"]["polish"]["passes"] == 1
    before = out.read_bytes()
    for bad in ("-1", "21"):
        code, err = run("--polish-passes", bad, "--force")
        assert code == 2 and err == f"stringbot: error: --polish-passes {bad}; expected 0..20 passes", err
    code, err = run("--polish-passes", "lots", "--force")
    assert code == 2 and len(err.splitlines()) == 1 and "--polish-passes" in err and "Traceback" not in err
    code, err = run("--polish-passes", "2", "--lines", "200", "--force")
    assert code == 2 and len(err.splitlines()) == 1 and "the polish, which is off here" in err, err
    code, err = run("--polish-passes", "2", "--method", "greedy", "--force")
    assert code == 2 and err == ("stringbot: error: --polish-passes is a knob of --method residual or euler only "
                                 "(not of greedy); leave it out")
    assert out.read_bytes() == before
