"""``--method euler``: a chord set made one thread (an Euler trail), then polished."""

import numpy as np
import pytest

from stringbot.planner.build import plan_picture
from stringbot.planner.methods.euler import choose_chords, euler_sequence, make_trail, pair_odd, relaxed_densities
from stringbot.planner.model.chords import chord_space, frame_mask

from test_residual import disc_picture


def _degrees(space, count):
    return np.bincount(space.ends.ravel(), weights=np.repeat(count, 2), minlength=space.pins).astype(int)


def _chords_of(seq):
    return sorted(tuple(sorted(c)) for c in zip(seq[:-1], seq[1:]))


def _multiset(space, count):
    return sorted(tuple(int(p) for p in space.ends[c]) for c in np.repeat(np.arange(space.m), count))


def test_an_odd_chord_set_is_made_one_thread_with_every_chosen_chord_in_it():
    space = chord_space(24)
    rng = np.random.default_rng(3)
    chosen = np.zeros(space.m, dtype=np.int64)
    chosen[rng.choice(space.m, 30, replace=False)] = 1
    harm = rng.normal(size=space.m)
    count = make_trail(space, chosen, harm)
    assert int(np.sum(_degrees(space, chosen) % 2)) > 2  # the set alone is no thread
    assert int(np.sum(_degrees(space, count) % 2)) <= 2
    seq = euler_sequence(space, count)
    assert all(a != b for a, b in zip(seq[:-1], seq[1:]))  # no pin twice in a row
    assert _chords_of(seq) == _multiset(space, count)  # every chord of the trail's set, once each
    left_out = (count == 0) & (chosen > 0)
    # a chord is left out only where that harms less than drawing one (its harm negative)
    assert np.all(harm[left_out] < 0)
    assert int(np.sum(chosen > count)) == int(left_out.sum())


def test_two_parts_are_joined_and_a_start_pin_is_where_the_thread_starts():
    space = chord_space(20)
    count = np.zeros(space.m, dtype=np.int64)
    for a, b in ((0, 5), (5, 9), (9, 0), (12, 15), (15, 17), (17, 12)):  # two triangles
        count[space.index[a, b]] = 1
    harm = np.ones(space.m)
    out = make_trail(space, count, harm, start=3)  # a pin with no chord
    seq = euler_sequence(space, out, start=3)
    assert seq[0] == 3 and seq[-1] == 3
    assert set(_chords_of(seq)) >= {tuple(sorted(p)) for p in ((0, 5), (5, 9), (9, 0), (12, 15), (15, 17), (17, 12))}
    assert len(seq) - 1 == int(out.sum())


def test_odd_pins_are_paired_by_the_least_harmful_chord():
    space = chord_space(12)
    count = np.zeros(space.m, dtype=np.int64)
    count[[space.index[0, 6], space.index[3, 9]]] = 1  # four odd pins: 0, 3, 6, 9
    harm = np.ones(space.m)
    harm[space.index[3, 6]] = -1.0  # the best pair: 3-6; 0 and 9 are the ends
    out = pair_odd(space, count, harm, remove=False)
    assert out[space.index[3, 6]] == 1 and int(out.sum()) == 3
    assert list(np.flatnonzero(_degrees(space, out) % 2)) == [0, 9]


def test_the_densities_darken_where_the_picture_is_dark_and_the_chords_chosen_are_one_thread():
    from stringbot.planner.picture.resample import resize_square

    m = 64
    space = chord_space(60)
    mask = frame_mask(m, "circle")
    t = np.where(mask, 1 - resize_square(disc_picture(), m) / 255.0, 0.0)
    x, f = relaxed_densities(space, t, mask.astype(float), 0.1, sigma=0.25, iterations=30,
                             schedule=((0.02, 10), (0.1, 10)))
    assert np.all((x >= 0) & (x <= 1))
    assert f(x)[0] < 0.5 * f(np.zeros(space.m))[0]
    count, chosen = choose_chords(space, x, f)
    assert int(np.sum(_degrees(space, count) % 2)) <= 2
    top = np.argsort(-x, kind="stable")[:chosen]
    assert np.sum(count[top] > 0) >= 0.8 * chosen  # the set is mostly the densest chords
    assert f(count.astype(float))[0] < 0.7 * f(np.zeros(space.m))[0]


@pytest.mark.parametrize("lines", ["auto", 50])
def test_the_plan_is_one_thread_the_winder_takes(tmp_path, lines):
    from skimage.io import imsave

    imsave(tmp_path / "disc.png", disc_picture().astype(np.uint8))
    p = plan_picture(tmp_path / "disc.png", method="euler", pins=60, size=101, lines=lines, polish=100)
    seq = p.sequence
    assert p.method == "euler"
    assert all(0 <= q < 60 for q in seq) and all(a != b for a, b in zip(seq[:-1], seq[1:]))
    assert 45 <= len(seq) - 1 <= 50 if lines == 50 else len(seq) - 1 > 20
    assert p.stats["chords_chosen"] > 0 and p.stats["polish"]["tried"] > 0



@pytest.mark.parametrize("method", ["euler", "greedy", "fitness"])
def test_refine_is_refused_where_there_is_no_pixel_refinement(tmp_path, method):
    """``--refine`` belongs to the residual method alone; euler and the others refuse it, not ignore it."""
    from stringbot.errors import BadInput

    with pytest.raises(BadInput, match=rf"--refine works with --method residual only; {method} has no"):
        plan_picture(tmp_path / "never-read.png", method=method, pins=60, size=101, refine=10)
    assert list(tmp_path.iterdir()) == []


def test_a_second_thread_for_the_products_leaves_the_densities_as_they_are():
    """Products over many chords run in two halves; a second thread takes one, the sums are the same."""
    from concurrent.futures import ThreadPoolExecutor

    from stringbot.planner.methods.euler import SPLIT
    from stringbot.planner.picture.resample import resize_square

    m = 64
    space = chord_space(80)
    assert space.m >= SPLIT  # the halves are used
    mask = frame_mask(m, "circle")
    t = np.where(mask, 1 - resize_square(disc_picture(), m) / 255.0, 0.0)
    kw = dict(sigma=0.5, iterations=5, rounds=(10,), schedule=((0.1, 5),))
    alone, f = relaxed_densities(space, t, mask.astype(float), 0.1, **kw)
    with ThreadPoolExecutor(1) as threads:
        paired, _ = relaxed_densities(space, t, mask.astype(float), 0.1, threads=threads, **kw)
    assert np.array_equal(alone, paired)
    assert f(alone)[0] < 0.5 * f(np.zeros(space.m))[0]


@pytest.mark.parametrize("processes", ["1", "2"])
def test_the_deletes_after_the_polish_shorten_the_thread_and_are_recorded(tmp_path, monkeypatch, processes):
    from skimage.io import imsave

    import os
    if processes == "2" and not hasattr(os, "fork"):
        pytest.skip("the helper processes are forked")
    monkeypatch.setenv("STRINGBOT_PROCESSES", processes)
    imsave(tmp_path / "disc.png", disc_picture().astype(np.uint8))
    p = plan_picture(tmp_path / "disc.png", method="euler", pins=60, size=101, polish=100)
    ps = p.stats["polish"]
    assert p.parameters["polish_deletes"] == 1 and p.parameters["polish_passes"] == 0
    assert ps["delete_passes"] == 1 and "passes" not in ps
    assert ps["woven_rms"] <= ps["woven_rms_rerouted"]
    lines = p.stats["chords_chosen"] + p.stats["chords_added"] - p.stats["chords_left_out"]
    assert len(p.sequence) - 1 == lines - ps["deleted"]
    assert all(a != b for a, b in zip(p.sequence[:-1], p.sequence[1:]))


def _dark_picture(size=101):
    """A dark portrait-like picture: mostly dark gray with a light disc (a face) and a lighter band."""
    y, x = np.mgrid[:size, :size]
    g = np.full((size, size), 60.0)
    g[(x - 0.5 * size) ** 2 + (y - 0.45 * size) ** 2 < (0.2 * size) ** 2] = 200.0
    g[int(0.75 * size):int(0.85 * size), :] = 120.0
    return g


def test_a_dark_picture_does_not_run_every_chord_to_its_bound():
    """On a dark picture L-BFGS-B's first steps from the uniform start can reach a flat, saturated region
    (every chord near 1, the piece black); the densities are then solved again from the union's log."""
    from stringbot.planner.methods import euler
    from stringbot.planner.picture.resample import resize_square

    m = 64
    space = chord_space(80)
    mask = frame_mask(m, "circle")
    t = np.where(mask, 1 - resize_square(_dark_picture(), m) / 255.0, 0.0)
    w = mask.astype(float)
    AT, cw = euler.coverage(space, m, 0.3)
    f = euler.objective(AT, cw, t, w, 0.5)
    uniform = euler._solve(f, np.full(space.m, 0.02), 10)
    assert euler._saturated(AT, cw, uniform, t, w)  # the trap this guards against, on this picture
    x, f = relaxed_densities(space, t, w, 0.3, sigma=0.5, iterations=10, rounds=(20,), schedule=((0.1, 10),))
    assert not euler._saturated(AT, cw, x, t, w)
    assert f(x)[0] < 0.5 * f(uniform)[0]
    assert x.sum() < 0.5 * space.m  # not every chord drawn
