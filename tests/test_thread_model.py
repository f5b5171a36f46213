"""The thread model: anti-aliased, direction-independent, saturating coverage in real units."""

import numpy as np
import pytest

from stringbot.planner.model.thread import ThreadModel, composite, coverage, footprints, saturate


def segment(angle_deg, length=0.8, centre=(0.5, 0.5)):
    a = np.radians(angle_deg)
    half = 0.5 * length * np.array([np.cos(a), np.sin(a)])
    c = np.asarray(centre)
    return np.array([c - half, c + half])


@pytest.mark.parametrize("width", [0.2, 1.0, 2.5])
def test_a_thread_darkens_its_width_per_unit_length_in_every_direction(width):
    size, length = 120, 0.8
    totals = []
    for angle in (0, 7, 22.5, 30, 45, 60, 77, 90, 135):
        cov = coverage([(0, 1)], segment(angle, length), size=size, width_px=width, saturated=False)
        totals.append(cov.sum() / (length * size * width))
    totals = np.array(totals)
    # a Bresenham count would give 0.71 at 45 degrees; this is within 2 % everywhere
    assert np.all(np.abs(totals - 1.0) < 0.02), totals.round(4)


def test_coverage_depends_on_the_distance_to_the_line_not_its_direction():
    size = 64
    across = coverage([(0, 1)], segment(0.0), size=size, width_px=1.0)
    down = coverage([(0, 1)], segment(90.0), size=size, width_px=1.0)
    assert np.allclose(down, across.T, atol=1e-6)
    # the profile across a diagonal thread equals the one across a horizontal one at the same distances
    _, flat, cov = footprints([[0.1, 0.1]], [[0.9, 0.9]], size, 1.0)
    r, c = flat // size, flat % size
    d = np.abs(r - c) / np.sqrt(2.0)  # distance of each pixel centre from the diagonal
    for dist in np.unique(d.round(6)):
        got = cov[np.isclose(d, dist)]
        assert np.ptp(got) < 1e-3  # one coverage per distance


def test_coverage_is_anti_aliased_and_thin_threads_stay_light():
    size = 100
    cov = coverage([(0, 1)], segment(17.0), size=size, width_px=0.25)
    touched = cov[cov > 0]
    assert touched.max() < 0.25  # a quarter-pixel thread never blackens a pixel
    assert len(touched) > 2 * 0.8 * size  # spread over more than one pixel across


def test_coverage_saturates_at_one():
    size = 50
    xy = segment(0.0)
    one = coverage([(0, 1)], xy, size=size, width_px=3.0)
    many = coverage([(0, 1)] * 5, xy, size=size, width_px=3.0)
    raw = coverage([(0, 1)] * 5, xy, size=size, width_px=3.0, saturated=False)
    assert raw.max() == pytest.approx(5 * one.max(), rel=1e-5)
    assert many.max() == pytest.approx(1.0) and np.all(many <= 1.0)
    assert np.array_equal(many, saturate(raw))
    assert (many >= one - 1e-6).all()


def test_composite_shows_the_board_through_the_uncovered_part():
    cov = np.array([[0.0, 0.25], [1.0, 0.5]])
    gray = composite(cov)
    assert np.allclose(gray, [[1.0, 0.75], [0.0, 0.5]])
    rgb = composite(cov, board=(1.0, 0.9, 0.8), thread=(0.5, 0.0, 0.0))
    assert rgb.shape == (2, 2, 3)
    assert np.allclose(rgb[0, 0], [1.0, 0.9, 0.8]) and np.allclose(rgb[1, 0], [0.5, 0.0, 0.0])
    assert np.allclose(rgb[1, 1], [0.75, 0.45, 0.4])


def test_thread_model_units():
    m = ThreadModel(diameter_mm=500.0, thread_mm=0.25)
    assert m.width_px(2000) == pytest.approx(1.0) and m.width_px(401) == pytest.approx(0.2005)
    for bad in (dict(thread_mm=0.0), dict(diameter_mm=-1.0), dict(thread_mm=float("nan")),
                dict(diameter_mm=10.0, thread_mm=10.0)):
        with pytest.raises(ValueError):
            ThreadModel(**bad)


@pytest.mark.parametrize("size, width", [(2048, 1.0), (401, 0.2), (300, 3.0)])
def test_a_single_thread_stamp_is_the_footprint_of_that_thread_in_either_form(size, width):
    from stringbot.planner.model.thread import SegmentStamp

    stamp = SegmentStamp(size, width)
    rng = np.random.default_rng(size)
    ends = [((0.0, 0.0), (1.0, 1.0)), ((0.5, 0.0), (0.5, 1.0)), ((0.0, 0.5), (1.0, 0.5))]
    ends += [tuple(map(tuple, rng.uniform(0.0, 1.0, (2, 2)))) for _ in range(30)]
    for xy0, xy1 in ends:
        xy0, xy1 = np.array(xy0), np.array(xy1)
        flat, cov = stamp(xy0, xy1)
        small_flat, small_cov = stamp(xy0, xy1, compact=True)
        assert (flat.dtype, cov.dtype, small_flat.dtype, small_cov.dtype) == (np.int64, np.float64, np.int32, np.float32)
        assert np.array_equal(flat, small_flat) and np.array_equal(cov, small_cov)
        _, ref_flat, ref_cov = footprints(xy0[None], xy1[None], size, width)
        order = np.argsort(flat, kind="stable")
        ref_order = np.argsort(ref_flat, kind="stable")
        assert np.array_equal(flat[order], ref_flat[ref_order])
        assert np.allclose(cov[order], ref_cov[ref_order], atol=2e-3)  # the batch works in float32
        assert flat.min(initial=0) >= 0 and flat.max(initial=0) < size * size
