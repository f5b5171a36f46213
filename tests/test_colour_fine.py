"""The colour planner's fine luminance: the picture's gray matched on a grid twice as fine, kept exactly."""

import numpy as np

from stringbot.planner.colour.model import Fine, Piece, _gray, linear_colors
from stringbot.planner.colour.palette import to_linear, to_srgb
from stringbot.planner.model.chords import chord_space

LUMINANCE = np.array([0.2125, 0.7154, 0.0721])


def piece(fine, m=24, pins=40):
    pin_xy = chord_space(pins, "circle").pin_xy
    target = np.full((m * m, 3), to_linear(np.array([0.55, 0.5, 0.45])))
    gray = np.where(np.arange(4 * m * m) % (2 * m) < m, 0.3, 0.8)          # dark left half, light right
    f = None if fine is None else Fine(gray, np.full(4 * m * m, fine), 0.2)
    return Piece(target, np.ones(m * m), np.ones(3), linear_colors(["#000000", "#b22222"]), pin_xy, 0.4,
                 texture=0.0, fine=f)


def lay_some(p):
    for k, a, b in [(0, 0, 17), (1, 3, 25), (0, 5, 30), (1, 0, 17), (0, 12, 33)]:
        p.lay(k, a, b)


def test_the_cells_colours_are_the_means_of_their_samples():
    p = piece(1000.0)
    lay_some(p)
    F, h = p.stamp.F, p.h
    s = np.arange(len(p.top))
    cells = (s // (F * h)) * p.m2 + (s % F) // h
    n = np.bincount(cells, minlength=p.m2 ** 2)
    for c in range(3):
        assert np.allclose(p.u_fine[:, c], np.bincount(cells, p.palette[p.top, c], minlength=p.m2 ** 2) / n)
    assert (np.abs(p.u_fine - 1.0) > 0.05).any()     # some cells are covered


def test_the_error_adds_the_fine_gray_difference_times_its_weight():
    plain, fine = piece(None), piece(1000.0)
    lay_some(plain)
    lay_some(fine)
    gray = to_srgb(fine.u_fine) @ LUMINANCE
    assert np.isclose(fine.error(), plain.error() + 1000.0 * ((gray - fine.fine.gray) ** 2).sum(), rtol=1e-3)
    assert np.allclose(_gray(fine.u_fine), gray, atol=1e-3)        # the table is the sRGB curve


def test_a_black_thread_is_judged_better_where_the_fine_picture_is_dark():
    plain, p = piece(None), piece(5000.0)
    S2 = p.S2[0].reshape(p.m2, p.m2)
    m = p.m
    assert np.allclose(S2[:, :m], S2[0, 0]) and np.allclose(S2[:, m:], S2[0, -1])   # the colour error is uniform
    assert S2[0, 0] < S2[0, -1]             # darker left half: a black thread there lowers the error more


def test_without_its_weight_a_cell_carries_a_quarter_of_its_pixels_gain():
    p = piece(0.0)
    up = np.repeat(np.repeat(p.S.reshape(p.K, p.m, p.m), 2, axis=1), 2, axis=2).reshape(p.K, -1)
    assert np.allclose(p.S2, 0.25 * up)
