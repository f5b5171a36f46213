"""The reference rendering: the union of sharp threads at their real width, converged, box-filtered."""

import numpy as np
import pytest

from stringbot.planner.model import reference
from stringbot.planner.model.chords import pin_positions
from stringbot.planner.model.reference import fine_factor, reference_coverage, reference_gray


def _brute(chords, xy, size, fraction, k):
    """Every sample of the fine canvas tested against every thread: covered when its centre is within half
    the width of the thread's line and between its ends (along the major axis)."""
    F = size * k
    yy, xx = np.mgrid[0:F, 0:F] + 0.5
    cov = np.zeros((F, F), dtype=bool)
    for a, b in chords:
        p, q = xy[a] * F, xy[b] * F
        d = q - p
        n = np.array([-d[1], d[0]]) / np.hypot(*d)
        near = np.abs((xx - p[0]) * n[0] + (yy - p[1]) * n[1]) <= fraction * F / 2
        lo, hi = sorted((p[0], q[0])) if abs(d[0]) >= abs(d[1]) else sorted((p[1], q[1]))
        along = xx if abs(d[0]) >= abs(d[1]) else yy
        cov |= near & (along >= lo) & (along <= hi)
    return cov.reshape(size, k, size, k).mean(axis=(1, 3))


def _random_plan(pins, lines, seed):
    rng = np.random.default_rng(seed)
    xy = pin_positions(pins, "circle")
    seq = [0]
    while len(seq) <= lines:
        nxt = int(rng.integers(0, pins))
        if nxt != seq[-1]:
            seq.append(nxt)
    return list(zip(seq[:-1], seq[1:])), xy


@pytest.mark.parametrize("size,k,fraction", [(48, 4, 1 / 40), (40, 6, 1 / 90), (32, 8, 1 / 25)])
def test_every_sample_is_tested_exactly_in_strips_of_any_height(monkeypatch, size, k, fraction):
    chords, xy = _random_plan(37, 50, seed=size)
    want = _brute(chords, xy, size, fraction, k)
    for strip in (1 << 21, 3000, 1):  # the whole canvas at once, a few rows, one output row at a time
        monkeypatch.setattr(reference, "STRIP_SAMPLES", strip)
        got = reference_coverage(chords, xy, size=size, thread_fraction=fraction, factor=k)
        np.testing.assert_allclose(got, want, atol=1e-6)
    # a band of rows is those rows of the whole
    part = reference_coverage(chords, xy, size=size, thread_fraction=fraction, factor=k, rows=(5, 17))
    np.testing.assert_allclose(part, want[5:17], atol=1e-6)


def test_a_thread_covers_its_width_along_its_length_in_any_direction():
    # (a thread exactly along a row, a column or a diagonal of the samples is drawn as it meets them:
    # a 45-degree one through their centres is 5 samples wide where it should be 5.7; such threads are rare)
    xy = pin_positions(64, "circle") + np.random.default_rng(2).uniform(-1e-3, 1e-3, (64, 2))
    fraction = 1 / 300
    for a, b in ((0, 32), (8, 40), (3, 29), (16, 47), (5, 41)):
        cov = reference_coverage([(a, b)], xy, size=200, thread_fraction=fraction)
        length = np.hypot(*(xy[a] - xy[b]))
        assert cov.sum() / 200 ** 2 == pytest.approx(length * fraction, rel=0.03)
        assert cov.max() <= 1.0


def test_threads_on_one_spot_are_as_dark_as_one_and_side_by_side_add_up():
    xy = np.array([[0.05, 0.4003], [0.95, 0.4011], [0.05, 0.6007], [0.95, 0.6001]])
    one = reference_coverage([(0, 1)], xy, size=100, thread_fraction=0.01)
    np.testing.assert_array_equal(reference_coverage([(0, 1), (1, 0), (0, 1)], xy, size=100, thread_fraction=0.01),
                                  one)
    two = reference_coverage([(0, 1), (2, 3)], xy, size=100, thread_fraction=0.01)
    assert two.sum() == pytest.approx(2 * one.sum(), rel=0.02)
    # crossing threads: the union, less than the sum by their overlap
    cross = reference_coverage([(0, 3), (2, 1)], xy, size=100, thread_fraction=0.01)
    apart = sum(reference_coverage([c], xy, size=100, thread_fraction=0.01).sum() for c in ((0, 3), (2, 1)))
    assert 0.9 * apart < cross.sum() < apart


def test_doubling_the_fine_canvas_changes_the_mean_lightness_by_less_than_0_002():
    # a small plan, with the thread as wide on its 160 px output as a 0.25 mm thread on 500 mm is at 512 px
    chords, xy = _random_plan(120, 500, seed=7)
    fraction = 0.256 / 160
    k = fine_factor(160, fraction)
    assert k * 160 * fraction >= reference.SAMPLES_PER_WIDTH  # the thread 4 samples wide at least
    light = [float(reference_gray(chords, xy, size=160, thread_fraction=fraction, factor=f).mean())
             for f in (k, 2 * k)]
    assert 0.3 < light[0] < 0.9  # a real drawing: not blank, not black
    assert abs(light[1] - light[0]) < 0.002
    # the coarsest canvases are not converged in the pixels' values (the test can fail)
    coarse = reference_coverage(chords, xy, size=160, thread_fraction=fraction, factor=1)
    fine = reference_coverage(chords, xy, size=160, thread_fraction=fraction, factor=2 * k)
    assert np.abs(coarse - fine).mean() > 0.01


def test_the_gray_is_the_board_showing_through():
    chords, xy = _random_plan(40, 30, seed=1)
    cov = reference_coverage(chords, xy, size=64, thread_fraction=0.01)
    np.testing.assert_allclose(reference_gray(chords, xy, size=64, thread_fraction=0.01, board=200, thread=20),
                               200 * (1 - cov) + 20 * cov, rtol=1e-6)
    assert reference_coverage([], xy, size=64, thread_fraction=0.01).max() == 0.0


def test_the_preview_is_the_reference_with_fewer_samples_and_the_same_mean():
    from stringbot.planner import Plan
    from stringbot.planner.model.render import PREVIEW_SAMPLES, draw_woven, preview_drawing

    chords, xy = _random_plan(120, 400, seed=3)
    seq = [chords[0][0]] + [b for _, b in chords]
    plan = Plan(pins=120, frame="circle", pin_xy=xy, crop={"cx": 1, "cy": 1, "r": 1}, sequence=seq, method="x")
    full = draw_woven(plan, size=301).astype(float)
    preview = preview_drawing(plan, 301).astype(float)
    assert PREVIEW_SAMPLES < reference.SAMPLES_PER_WIDTH and not np.array_equal(full, preview)
    assert abs(full.mean() - preview.mean()) / 255 < 0.002 and full.mean() < 250
