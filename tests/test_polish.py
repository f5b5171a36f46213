"""The as-woven polish: its canvas (exact error changes), the polish itself, and how a user gets it."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.ndimage import correlate

from stringbot.planner.build import plan_picture
from stringbot.planner.methods.polish import polish_plan
from stringbot.planner.methods.residual import POLISH_ROUNDS
from stringbot.planner.methods.woven import WovenCanvas
from stringbot.planner.model.chords import chord_space, frame_mask
from stringbot.planner.model.scoring import woven_error
from stringbot.planner.picture.resample import resize_square

from planner_helpers import picture, union_brute

M = 64  # the error's grid in these tests
WIDTH = 1.0 / 32  # thread width in grid pixels: the fine canvas is 2048 px, as the scorer's


def horse_like(size=M):
    """A dark blob (a body) with two legs, on white: the kind of picture the polish helps most."""
    y, x = np.mgrid[:size, :size] / size
    g = np.full((size, size), 255.0)
    g[((x - 0.5) / 0.3) ** 2 + ((y - 0.42) / 0.16) ** 2 < 1] = 10.0
    g[(y > 0.45) & (y < 0.8) & (np.abs(x - 0.3) < 0.04)] = 10.0
    g[(y > 0.45) & (y < 0.8) & (np.abs(x - 0.68) < 0.04)] = 10.0
    return g


def canvas_for(g, space):
    mask = frame_mask(g.shape[0], "circle")
    t = np.where(mask, 1 - g / 255.0, 0.0)
    return WovenCanvas(t, mask.astype(float), space.pin_xy, WIDTH), t, mask


def polished_canvas(t, mask, space, chords):
    """A canvas holding ``chords``, ready for :func:`polish_plan`."""
    c = WovenCanvas(t, mask.astype(float), space.pin_xy, WIDTH)
    c.build(chords)
    return c


def brute_error(canvas, chords, t, mask):
    """E from scratch: the chords' union on the canvas's fine grid (each sample tested against each
    thread), averaged to the grid, the error blurred by the canvas's own kernel."""
    D = union_brute(chords, canvas.pin_xy, canvas.size, canvas.f, WIDTH)
    x = np.sqrt(mask.astype(float)) * (t - D)
    k1 = canvas._kw1.reshape(int(np.sqrt(len(canvas._kw1))), -1)
    pad = np.pad(x, canvas.rad)
    b = correlate(pad, k1, mode="constant")
    return float(np.sum(b ** 2))


def test_the_canvas_knows_its_error_exactly_after_every_change():
    space = chord_space(60)
    g = horse_like()
    canvas, t, mask = canvas_for(g, space)
    chords = [(0, 30), (5, 40), (5, 40), (12, 47), (20, 51)]
    canvas.build(chords)
    assert canvas.error() == pytest.approx(brute_error(canvas, chords, t, mask), rel=1e-6)
    # a change: its predicted change of E is the change of the error recomputed from scratch
    out, new = [(5, 40), (12, 47)], [(7, 33), (33, 50)]
    d = canvas.delta(chords_out=out, chords_in=new)
    assert canvas.error() == pytest.approx(brute_error(canvas, chords, t, mask), rel=1e-6)  # delta changed nothing
    applied = canvas.apply(chords_out=out, chords_in=new)
    after = [(0, 30), (5, 40), (20, 51), (7, 33), (33, 50)]
    exact = brute_error(canvas, after, t, mask) - brute_error(canvas, chords, t, mask)
    assert d == pytest.approx(exact, rel=1e-5, abs=1e-6)
    assert applied == pytest.approx(exact, rel=1e-5, abs=1e-6)
    assert canvas.error() == pytest.approx(brute_error(canvas, after, t, mask), rel=1e-6)
    # a chord drawn again lies on the first: it changes nothing, and lifting one copy changes nothing
    once = canvas.delta(chords_in=[(2, 25)])
    canvas.apply(chords_in=[(2, 25)])
    assert once != 0.0 and canvas.delta(chords_in=[(2, 25)]) == 0.0
    canvas.apply(chords_in=[(25, 2)])
    assert canvas.delta(chords_out=[(2, 25)]) == 0.0
    assert canvas.delta(chords_out=[(2, 25)] * 2) == pytest.approx(-once, rel=1e-9)


def test_the_estimate_is_the_exact_change_where_the_chords_do_not_overlap():
    space = chord_space(60)
    canvas, t, mask = canvas_for(horse_like(), space)
    canvas.build([(0, 30), (10, 45), (3, 33)])
    far = dict(chords_out=[(10, 45)], chords_in=[(15, 20)])  # apart: neither crosses the other
    assert canvas.estimate(**far) == pytest.approx(canvas.delta(**far), rel=1e-9)
    near = dict(chords_out=[(10, 45)], chords_in=[(10, 44)])  # shares pin 10, overlaps near it
    assert canvas.estimate(**near) != pytest.approx(canvas.delta(**near), rel=1e-9)


def test_helps_says_what_the_estimate_says():
    space = chord_space(60)
    canvas, t, mask = canvas_for(horse_like(), space)
    chords = [(0, 30), (5, 40), (12, 47), (20, 51), (30, 12), (44, 8)]
    canvas.build(chords)
    rng = np.random.default_rng(3)
    said = set()
    for _ in range(60):
        (a, p), q = chords[int(rng.integers(len(chords)))], int(rng.integers(60))
        if q in (a, p):
            continue
        change = dict(chords_out=[(a, p)], chords_in=[(a, q), (q, p)])
        assert canvas.helps(**change) == (canvas.estimate(**change) < 0.0)
        said.add(canvas.helps(**change))
    assert said == {True, False}


def _state(canvas):
    return [canvas.Sf, canvas.D, canvas.G, canvas.u, canvas.g, canvas.uses, np.array(canvas.E)]


@pytest.mark.parametrize("undone", [False, True])
def test_a_change_replayed_in_a_copy_leaves_it_the_same_to_the_bit(undone):
    """What a second process takes in (the values, not computed again) is what the first holds."""
    space = chord_space(60)
    chords = [(0, 30), (5, 40), (12, 47), (20, 51), (30, 12)]
    first, t, mask = canvas_for(horse_like(), space)
    second, _, _ = canvas_for(horse_like(), space)
    first.build(chords)
    second.build(chords)
    old, new = [(5, 40), (12, 47)], [(5, 33), (33, 47)]
    first.apply(chords_out=old, chords_in=new)
    if undone:
        first.apply(chords_out=new, chords_in=old)  # as settle undoes a change that did not help
    if not undone:  # the change did change every part of the state
        assert not any(np.array_equal(a, b) for a, b in zip(_state(first), _state(second)))
    second.replay(first.change_record(old + new), first.G, first.E,
                  chords_out=() if undone else old, chords_in=() if undone else new)
    for a, b in zip(_state(first), _state(second)):
        np.testing.assert_array_equal(a, b)
    # the copy goes on as the first does
    more = dict(chords_out=[(20, 51)], chords_in=[(21, 50)])
    assert first.apply(**more) == second.apply(**more)
    for a, b in zip(_state(first), _state(second)):
        np.testing.assert_array_equal(a, b)


def random_thread(space, steps, *, seed):
    """A thread of ``steps`` random chords from pin 0 (every step a chord of ``space``)."""
    rng = np.random.default_rng(seed)
    seq = [0]
    for _ in range(steps):
        nxt = int(rng.integers(0, space.pins))
        while space.index[seq[-1], nxt] < 0:
            nxt = int(rng.integers(0, space.pins))
        seq.append(nxt)
    return seq


def test_polish_never_makes_the_woven_picture_worse_and_keeps_one_thread():
    space = chord_space(60)
    g = horse_like()
    canvas, t, mask = canvas_for(g, space)
    # a deliberately poor start: chords everywhere
    seq = random_thread(space, 120, seed=3)
    chords0 = list(zip(seq[:-1], seq[1:]))
    e0 = brute_error(canvas, chords0, t, mask)
    out, stats = polish_plan(polished_canvas(t, mask, space, chords0), seq, space, budget=len(seq))
    chords1 = list(zip(out[:-1], out[1:]))
    e1 = brute_error(canvas, chords1, t, mask)
    assert len(out) == len(seq) and out[0] == seq[0] and out[-1] == seq[-1]
    assert all(space.index[a, b] >= 0 for a, b in chords1)  # every chord a chord; no pin twice in a row
    assert stats["rerouted"] > 5 and stats["tried"] == len(seq) - 2
    assert e1 < 0.95 * e0
    assert stats["woven_rms"] < stats["woven_rms_before"]
    # the model's error is the error of the plan it returns (kept in step change by change)
    area = mask.sum()
    assert stats["woven_rms"] == pytest.approx(np.sqrt(e1 / area), rel=1e-4)
    # the same input, the same plan
    again, _ = polish_plan(polished_canvas(t, mask, space, chords0), seq, space, budget=len(seq))
    assert again == out


def test_rounds_of_reroutes_go_on_where_the_round_before_stopped():
    space = chord_space(60)
    g = horse_like()
    canvas, t, mask = canvas_for(g, space)
    seq = random_thread(space, 150, seed=5)
    chords0 = list(zip(seq[:-1], seq[1:]))
    budget = 40  # a part of the pins a round: the next round finds others (and the rerouted ones' neighbours)
    one, s1 = polish_plan(polished_canvas(t, mask, space, chords0), seq, space, budget=budget)
    three, s3 = polish_plan(polished_canvas(t, mask, space, chords0), seq, space, budget=budget, rounds=3)
    assert "rounds" not in s1 and s3["rounds"] == 3 and len(s3["rerouted_by_round"]) == 3
    assert s3["rerouted_by_round"][0] == s1["rerouted"]  # the first round is the polish of one round
    assert s3["rerouted"] == sum(s3["rerouted_by_round"]) and s3["rerouted_by_round"][1] > 0
    assert s3["woven_rms"] < s1["woven_rms"]
    assert len(three) == len(seq) and all(space.index[a, b] >= 0 for a, b in zip(three[:-1], three[1:]))
    area = mask.sum()
    e3 = brute_error(canvas, list(zip(three[:-1], three[1:])), t, mask)
    assert s3["woven_rms"] == pytest.approx(np.sqrt(e3 / area), rel=1e-4)
    again, _ = polish_plan(polished_canvas(t, mask, space, chords0), seq, space, budget=budget, rounds=3)
    assert again == three


def test_auto_lines_are_polished_and_a_line_count_is_not():
    g = horse_like(101)
    pic = picture(g)
    auto = plan_picture("x.png", picture=pic, pins=60, size=101)
    fixed = plan_picture("x.png", picture=pic, pins=60, size=101, lines=200)
    assert auto.parameters["polish"] == 1000 and auto.parameters["refine"] == 0
    assert auto.parameters["polish_rounds"] == POLISH_ROUNDS == auto.stats["polish"]["rounds"]
    assert fixed.parameters["polish_rounds"] == 0
    assert auto.stats["polish"]["rerouted"] > 0
    assert auto.stats["polish"]["woven_rms"] < auto.stats["polish"]["woven_rms_before"]
    assert fixed.parameters["polish"] == 0 and fixed.parameters["refine"] == 300 and "polish" not in fixed.stats
    # the stop's figure, the error as the eye sees it before the polish, is the polish's own of that plan
    assert "eye_rms" not in fixed.stats
    assert auto.stats["eye_rms"] == pytest.approx(auto.stats["polish"]["woven_rms_before"], abs=0.02)
    # without the polish the same choice is made; the polish reroutes some of it and the piece as the
    # scorer sees it gets better
    plain = plan_picture("x.png", picture=pic, pins=60, size=101, polish=0, refine=0)
    assert len(plain.sequence) == len(auto.sequence) and plain.sequence != auto.sequence
    gray = resize_square(np.asarray(g, dtype=float), 512)  # the picture at the scorer's 512 px
    e_plain = woven_error(plain.chord_list(), plain.pin_xy, gray, frame="circle")
    e_auto = woven_error(auto.chord_list(), auto.pin_xy, gray, frame="circle")
    assert e_auto < e_plain


def test_polish_on_the_command_line(tmp_path):
    from PIL import Image

    img = tmp_path / "blob.png"
    Image.fromarray(horse_like(160).astype(np.uint8)).save(img)
    out = tmp_path / "p.json"
    env = dict(os.environ, STRINGBOT_CACHE=str(tmp_path / "cache"))

    def run(*args):
        p = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", *map(str, args)],
                           capture_output=True, text=True, env=env, timeout=120)
        return p.returncode, p.stderr

    code, err = run("plan", img, "-o", out, "--pins", "60", "--size", "101", "--polish", "50")
    assert code == 0, err
    doc = json.loads(out.read_text())
    assert doc["parameters"]["polish"] == 50 and doc["stats"]["polish"]["tried"] == 50
    assert "woven_cover" not in doc
    # a bad budget: one line, exit 2, the plan already there untouched
    before = out.read_bytes()
    for bad in ("-3", "lots"):
        code, err = run("plan", img, "-o", out, "--pins", "60", "--size", "101", "--polish", bad, "--force")
        assert code == 2 and len(err.strip().splitlines()) == 1 and "--polish" in err, err
        assert "Traceback" not in err
    assert "expected 0..1000000 pins" in run("plan", img, "-o", out, "--polish", "-3", "--force")[1]
    # a knob of the default method given to another: refused, not ignored
    code, err = run("plan", img, "-o", out, "--method", "greedy", "--polish", "5", "--force")
    assert code == 2 and err.strip() == ("stringbot: error: --polish is a knob of --method residual or euler only "
                                         "(not of greedy); leave it out")
    assert out.read_bytes() == before


@pytest.mark.parametrize("m, width", [(256, 0.125), (256, 0.2), (200, 0.15), (128, 0.3)])
def test_each_fine_pixel_falls_in_the_grid_pixel_under_it(m, width):
    canvas = WovenCanvas(np.zeros((m, m)), np.ones((m, m)), np.array([[0.5, 0.0], [0.5, 1.0]]), width)
    F, f = canvas.F, canvas.f
    rows, cols = np.divmod(np.random.default_rng(m).integers(0, F * F, 20000), F)
    cells = canvas._stamp.cells((rows * F + cols).astype(np.int32))
    assert cells.dtype == np.int64
    assert np.array_equal(cells, (rows // f) * m + cols // f)


def test_a_guarded_polish_keeps_a_change_only_where_the_guard_error_does_not_rise():
    """``--face``'s frame polish: the frame's error leads, the face's guards (``Guarded``)."""
    from stringbot.planner.methods.polish import Guarded

    space = chord_space(48)
    g = horse_like()
    mask = frame_mask(M, "circle")
    t = np.where(mask, 1 - g / 255.0, 0.0)
    rng = np.random.default_rng(3)
    seq = [int(p) for p in rng.integers(0, 48, 160)]
    seq = [p for i, p in enumerate(seq) if i == 0 or p != seq[i - 1]]
    chords = list(zip(seq[:-1], seq[1:]))
    face = np.zeros((M, M))
    face[:, : M // 2] = 1.0  # the guard's weight: the left half, which it wants white (so that they disagree)
    white = np.zeros((M, M))

    def guard_error(chords):
        return WovenCanvas(white, face * mask, space.pin_xy, WIDTH).build(chords)

    lead, guard = polished_canvas(t, mask, space, chords), WovenCanvas(white, face * mask, space.pin_xy, WIDTH)
    e_lead, e_guard = lead.error(), guard.build(chords)
    out, stats = polish_plan(Guarded(lead, guard), seq, space, budget=60, passes=1)
    assert lead.error() < e_lead and guard.error() <= e_guard + 1e-9
    assert stats["rerouted"] + stats["inserted"] + stats["deleted"] > 0
    after = list(zip(out[:-1], out[1:]))  # both canvases hold the polished plan
    assert lead.error() == pytest.approx(polished_canvas(t, mask, space, after).error(), rel=1e-9)
    assert guard.error() == pytest.approx(guard_error(after), rel=1e-9)
    # unguarded, the same polish raises the guard's error: the guard is what held it
    free, _ = polish_plan(polished_canvas(t, mask, space, chords), seq, space, budget=60, passes=1)
    assert guard_error(list(zip(free[:-1], free[1:]))) > e_guard
