"""The default planner: residual choice under the thread model, refinement, auto lines, masks, --fit."""

import numpy as np
import pytest

from stringbot.errors import BadInput
from stringbot.planner.build import plan_picture
from stringbot.planner.methods.canvas import Canvas
from stringbot.planner.methods.refine import refine_sequence
from stringbot.planner.methods.residual import residual_sequence
from stringbot.planner.model.chords import chord_space, frame_mask
from stringbot.planner.model.lines import PinLines
from stringbot.planner.model.scoring import woven_error
from stringbot.planner.model.thread import DEFAULT_DIAMETER_MM, DEFAULT_THREAD_MM

from planner_helpers import picture, union_brute


def disc_picture(size=101):
    """A dark disc off centre and a mid-gray band on white."""
    y, x = np.mgrid[:size, :size]
    g = np.full((size, size), 255.0)
    g[(x - 0.35 * size) ** 2 + (y - 0.4 * size) ** 2 < (0.18 * size) ** 2] = 20.0
    g[int(0.7 * size):int(0.8 * size), :] = 140.0
    return g


def canvas_of(g, space, width_px=0.2, *, sharp=False):
    """The chooser's canvas of gray ``g``; ``sharp``: against its darkness sharpened, as the planner's."""
    size = g.shape[0]
    mask = frame_mask(size, "circle")
    t = 1 - g / 255.0
    if sharp:
        from stringbot.planner.methods.residual import SHARPEN
        from stringbot.planner.picture.resample import unsharp

        t = unsharp(t, amount=SHARPEN[0], sigma=SHARPEN[1] * size)
    return Canvas(np.where(mask, t, 0.0), mask.astype(float), space.pin_xy, width_px)


def test_residual_draws_where_the_picture_is_dark_and_stops_by_itself():
    g = disc_picture()
    space = chord_space(80)
    canvas = canvas_of(g, space)
    e0 = canvas.error()
    seq = residual_sequence(canvas, space, "auto")
    assert 20 < len(seq) - 1 < 5000
    assert canvas.error() < 0.7 * e0
    assert all(a != b for a, b in zip(seq[:-1], seq[1:]))
    # the kept canvas is the drawing of the kept sequence
    again = canvas_of(g, space)
    again.apply(chords_in=list(zip(seq[:-1], seq[1:])))
    assert again.error() == pytest.approx(canvas.error(), rel=1e-9)
    # darker where the picture is dark
    D = canvas.D.reshape(g.shape)
    assert D[g < 50].mean() > 3 * D[g > 250].mean()
    # the drawing is the union of the threads, sampled f x f a pixel at the samples' offsets
    ref = union_brute(list(zip(seq[:-1], seq[1:])), space.pin_xy, g.shape[0], canvas.f, 0.2)
    np.testing.assert_allclose(D, ref, atol=1e-6)


def test_refinement_never_makes_the_picture_worse_and_keeps_one_thread():
    g = disc_picture()
    space = chord_space(80)
    for lines, remove in ((150, False), ("auto", True)):
        canvas = canvas_of(g, space)
        pl = PinLines(space, g.shape[0], nearest=True)
        seq = residual_sequence(canvas, space, lines, pin_lines=pl)
        before = canvas.error()
        out, st = refine_sequence(canvas, seq, pl, budget=len(seq), remove=remove)
        after = canvas.error()
        assert after <= before + 1e-9 and st["error_drop"] >= 0
        assert after == pytest.approx(before - st["error_drop"], rel=1e-6, abs=1e-9)
        assert st["rerouted"] + st["removed"] > 0  # it found something to do on this picture
        assert all(a != b for a, b in zip(out[:-1], out[1:])) and out[0] == seq[0]
        if not remove:
            assert len(out) == len(seq)
        again = canvas_of(g, space)
        again.apply(chords_in=list(zip(out[:-1], out[1:])))
        assert again.error() == pytest.approx(after, rel=1e-9)


def test_default_method_beats_greedy_and_fitness_as_woven():
    g = disc_picture(121)
    pic = picture(g)
    woven = picture(np.asarray(
        __import__("PIL.Image", fromlist=["Image"]).fromarray(g.astype(np.uint8)).resize((512, 512)), float))
    errs = {}
    for method in ("residual", "greedy", "fitness"):
        p = plan_picture("x", pins=80, size=121, method=method, picture=pic, lines=400)
        errs[method] = woven_error(p.chord_list(), p.pin_xy, woven.gray, frame="circle")
    assert errs["residual"] < min(errs["greedy"], errs["fitness"]), errs


def test_thicker_thread_needs_fewer_lines():
    pic = picture(disc_picture())
    thin = plan_picture("x", pins=80, size=101, picture=pic, thread_mm=0.5)
    thick = plan_picture("x", pins=80, size=101, picture=pic, thread_mm=2.0)
    assert thick.stats["lines"] < 0.6 * thin.stats["lines"]
    assert thick.thread_mm == 2.0 and thick.parameters["thread_px"] == pytest.approx(2.0 / 500 * 101)


def test_importance_mask_weighs_the_error(tmp_path):
    from PIL import Image

    size = 101
    g = np.full((size, size), 255.0)
    g[30:70, 15:45] = 120.0
    g[30:70, 56:86] = 120.0  # two equal gray patches, left and right
    src = tmp_path / "pic.png"
    Image.fromarray(g.astype(np.uint8)).save(src)
    m = np.zeros((size, size), np.uint8)
    m[:, :50] = 255  # the left one is important
    mask = tmp_path / "mask.png"
    Image.fromarray(m).save(mask)
    plain = plan_picture(src, pins=80, size=size, lines=120)
    weighted = plan_picture(src, pins=80, size=size, lines=120, importance=mask)

    def left_share(plan):
        from stringbot.planner.model.thread import coverage
        c = coverage(plan.chord_list(), plan.pin_xy, size=size, width_px=1.0, saturated=False)
        return c[30:70, 15:45].sum() / (c[30:70, 15:45].sum() + c[30:70, 56:86].sum())

    assert left_share(weighted) > left_share(plain) + 0.03


def test_fit_letterboxes_the_whole_picture(tmp_path):
    from PIL import Image

    g = np.full((60, 180), 255, np.uint8)
    g[:, :20] = 0  # a dark bar at the far left: outside the largest centred circle
    g[20:40, 80:100] = 100
    src = tmp_path / "wide.png"
    Image.fromarray(g).save(src)
    centred = plan_picture(src, pins=80, size=101, lines=60)
    fit = plan_picture(src, pins=80, size=101, lines=60, fit=True)
    assert centred.crop["r"] == 30
    assert fit.crop == {"cx": 90.0, "cy": 30.0, "r": pytest.approx(np.hypot(180, 60) / 2)}
    from stringbot.planner.model.thread import coverage
    c = coverage(fit.chord_list(), fit.pin_xy, size=200, width_px=1.0, saturated=False)
    bar = c[72:128, 7:24].mean()  # where the bar lies in the letterboxed crop
    board = c[10:55, 60:140].mean()  # white above the picture
    assert bar > 3 * board
    square = plan_picture(src, pins=80, size=101, lines=60, fit=True, frame="square")
    assert square.crop["r"] == 90
    with pytest.raises(BadInput, match="--fit and --crop"):
        plan_picture(src, pins=80, size=101, fit=True, crop={"cx": 1, "cy": 1, "r": 5})


def test_blank_picture_is_refused():
    with pytest.raises(BadInput, match="nothing to draw"):
        plan_picture("x", pins=40, size=101, picture=picture(np.full((101, 101), 255.0)))


def test_a_chord_drawn_again_adds_nothing_and_is_never_chosen_again():
    g = disc_picture()
    space = chord_space(80)
    canvas = canvas_of(g, space)
    e0 = canvas.error()
    once = canvas.apply(chords_in=[(3, 40)])
    assert once != 0.0 and canvas.error() == pytest.approx(e0 + once, rel=1e-9)
    d1 = canvas.D.copy()
    assert canvas.delta(chords_in=[(40, 3)]) == 0.0  # the same chord, the other way round: on the first
    assert canvas.apply(chords_in=[(40, 3)]) == 0.0
    np.testing.assert_array_equal(canvas.D, d1)
    assert canvas.uses[3, 40] == canvas.uses[40, 3] == 2
    # lifting one copy changes nothing, both: back to the blank board; several at once add up
    assert canvas.delta(chords_out=[(3, 40)]) == 0.0
    both = canvas.delta(chords_out=[(3, 40), (40, 3)])
    assert both == pytest.approx(-once, rel=1e-9)
    assert canvas.apply(chords_out=[(3, 40)] * 2) == pytest.approx(both, rel=1e-9)
    assert canvas.error() == pytest.approx(e0, rel=1e-9) and canvas.D.max() == 0.0 and canvas.uses.max() == 0
    # a long run never draws a chord twice
    seq = residual_sequence(canvas_of(g, space), space, 600)
    chords = {tuple(sorted(c)) for c in zip(seq[:-1], seq[1:])}
    assert len(chords) == 600


def test_residual_starts_at_an_end_of_its_best_chord_unless_told():
    from stringbot.planner.methods.residual import best_start

    g = disc_picture()
    space = chord_space(80)
    pl = PinLines(space, g.shape[0], nearest=True)
    # the default thread, the target sharpened as the planner sees it
    canvas = canvas_of(g, space, width_px=DEFAULT_THREAD_MM / DEFAULT_DIAMETER_MM * g.shape[0], sharp=True)

    def top(a):
        others, pix, starts, counts = pl.get_with_counts(a)
        scores = np.add.reduceat(canvas.slope().take(pix), starts) / counts
        return float(scores.max()), int(others[int(np.argmax(scores))])

    start = best_start(canvas, space, pl)
    best = max(top(a)[0] for a in range(space.pins))
    assert top(start)[0] == best
    pic = picture(g)
    p = plan_picture("x", pins=80, size=101, picture=pic, lines=30, refine=0)
    assert p.sequence[0] == p.parameters["start_pin"]
    first = p.sequence[0]
    assert top(first)[0] == pytest.approx(best, rel=1e-5)  # the same chord, up to the picture's float32
    assert p.sequence[1] == top(first)[1]
    told = plan_picture("x", pins=80, size=101, picture=pic, lines=30, start_pin=7)
    assert told.sequence[0] == told.parameters["start_pin"] == 7


def test_the_error_as_the_eye_sees_it_is_kept_exactly_and_auto_stops_at_its_lowest():
    from stringbot.planner.methods.eye import EyeError

    g = disc_picture()
    space = chord_space(80)
    canvas = Canvas(*_target(g), space.pin_xy, 0.2, eye=True)
    seq = residual_sequence(canvas, space, "auto")
    eye = canvas.eye
    # kept chord by chord, it is the error of the drawing's samples averaged to the eye's grid (each in
    # the cell its centre lies in), from scratch
    me, F = eye.size, canvas.F
    rc = ((np.arange(F) + 0.5) * me / F).astype(int)
    cell = (rc[:, None] * me + rc[None, :]).ravel()
    d_eye = (np.bincount(cell, weights=(canvas.C > 0).astype(float), minlength=me * me)
             / np.bincount(cell, minlength=me * me))
    kept = eye.error()
    assert eye.reset(d_eye) == pytest.approx(kept, rel=1e-9)  # reset: computed from scratch
    assert isinstance(eye, EyeError) and kept < eye.reset(np.zeros(me * me))
    # the run was cut back to where that error was lowest: no shorter prefix is better
    again = Canvas(*_target(g), space.pin_xy, 0.2, eye=True)
    errors = [again.eye.error()]
    for chord in zip(seq[:-1], seq[1:]):
        again.apply(chords_in=[chord])
        errors.append(again.eye.error())
    assert errors[-1] == pytest.approx(min(errors), rel=1e-9) and errors[-1] < 0.8 * errors[0]


def _target(g):
    mask = frame_mask(g.shape[0], "circle")
    return np.where(mask, 1 - g / 255.0, 0.0), mask.astype(float)
