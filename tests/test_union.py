"""The planners' thread model: the union of sharp threads on a fine canvas whose samples are offset at random."""

import numpy as np
import pytest

from stringbot.planner.model.chords import pin_positions
from stringbot.planner.model.union import UnionStamp, offsets

from planner_helpers import union_brute


def _drawn(stamp, chords, xy):
    C = np.zeros(stamp.F * stamp.F, dtype=bool)
    for a, b in chords:
        flat = stamp(xy[a], xy[b])
        assert len(np.unique(flat)) == len(flat)  # each sample once
        C[flat] = True
    m, f = stamp.m, stamp.f
    return C.reshape(m, f, m, f).mean(axis=(1, 3))


@pytest.mark.parametrize("m, f, width", [(40, 5, 0.2), (32, 8, 0.125), (50, 3, 0.6)])
def test_a_stamp_is_the_union_tested_sample_by_sample(m, f, width):
    rng = np.random.default_rng(m)
    xy = pin_positions(41, "circle")
    chords = [(int(a), int(b)) for a, b in rng.integers(0, 41, (60, 2)) if a != b]
    want = union_brute(chords, xy, m, f, width)
    np.testing.assert_allclose(_drawn(UnionStamp(m, f, width), chords, xy), want, atol=1e-9)


def test_the_offsets_are_the_same_in_every_process_and_stay_in_their_cells():
    a, b = offsets(2005)
    a2, b2 = offsets(2005)
    assert np.array_equal(a, a2) and np.array_equal(b, b2)
    assert a.min() >= -0.5 and a.max() < 0.5 and abs(a.mean()) < 0.03 and not np.array_equal(a, b)


def test_two_threads_side_by_side_half_a_thread_apart_cover_one_and_a_half_threads():
    # nearly horizontal threads one sample wide, half a sample apart: on a regular lattice both meet the
    # samples in the same phase along their whole length and their union counts as one thread or two
    m, f, width = 100, 10, 0.1
    F = m * f
    y0, s = 0.4003, 2e-5
    xy = np.array([[0.02, y0], [0.98, y0 + s], [0.02, y0 + 0.5 / F], [0.98, y0 + s + 0.5 / F]])
    for jitter, close in ((True, True), (False, False)):
        stamp = UnionStamp(m, f, width, jitter=jitter)
        one = _drawn(stamp, [(0, 1)], xy).sum()
        both = _drawn(stamp, [(0, 1), (2, 3)], xy).sum()
        assert (abs(both / one - 1.5) < 0.05) == close


@pytest.mark.parametrize("m, f", [(32, 8), (20, 5), (16, 3)])
def test_the_tiled_canvas_is_the_same_samples_each_pixels_together(m, f):
    stamp = UnionStamp(m, f, 0.3)
    F = m * f
    every = np.arange(F * F)
    tiled = stamp.tile(every)
    assert np.array_equal(np.sort(tiled), every)  # a reordering of the samples
    assert np.array_equal(stamp.tiled_cells(tiled), stamp.cells(every))  # each in its pixel
    assert np.array_equal(np.sort(tiled.reshape(F, F)[:f, f:2 * f].ravel()), np.arange(f * f, 2 * f * f))  # pixel (0, 1)
    values = np.zeros(F * F, dtype=np.int64)
    values[tiled] = every  # a canvas of row-major numbers, kept tiled
    assert np.array_equal(stamp.untile(values), every.reshape(F, F))
