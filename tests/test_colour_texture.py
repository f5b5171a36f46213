"""The colour planner's texture term: each pixel's variance of luminance over its samples, kept exactly."""

import numpy as np

from stringbot.planner.colour.model import Piece, linear_colors
from stringbot.planner.colour.palette import to_linear
from stringbot.planner.model.chords import chord_space

Y = np.array([0.2126, 0.7152, 0.0722])


def piece(texture, m=24, pins=40):
    pin_xy = chord_space(pins, "circle").pin_xy
    target = np.full((m * m, 3), to_linear(np.array([0.55, 0.5, 0.45])))
    return Piece(target, np.ones(m * m), np.ones(3), linear_colors(["#000000", "#b22222"]), pin_xy, 0.4,
                 texture=texture)


def lay_some(p):
    for k, a, b in [(0, 0, 17), (1, 3, 25), (0, 5, 30), (1, 0, 17), (0, 12, 33)]:
        p.lay(k, a, b)


def test_the_pixels_luminance_moments_are_those_of_their_samples():
    p = piece(100.0)
    lay_some(p)
    cells = p.stamp.cells(np.arange(len(p.top)))
    lum = p.lum[p.top]
    n = np.bincount(cells, minlength=p.n)
    assert np.allclose(p.y1, np.bincount(cells, lum, minlength=p.n) / n)
    assert np.allclose(p.y2, np.bincount(cells, lum * lum, minlength=p.n) / n)
    assert (p.y2 - p.y1 ** 2 > 1e-3).any()          # some pixels are part covered: a texture


def test_the_error_adds_the_texture_times_its_weight():
    plain, textured = piece(0.0), piece(500.0)
    lay_some(plain)
    lay_some(textured)
    var = textured.y2 - textured.y1 ** 2
    assert np.isclose(textured.error(), plain.error() + 500.0 * var.sum(), rtol=1e-9)
    assert textured.error() > plain.error()


def test_with_texture_a_black_thread_on_the_bare_board_is_judged_worse():
    plain, textured = piece(0.0), piece(5000.0)
    assert (textured.S[0] > plain.S[0]).all()       # it adds a stripe to every pixel's texture


def test_a_bad_texture_weight_is_refused(tmp_path):
    import pytest
    from PIL import Image

    from stringbot.errors import BadInput
    from stringbot.planner.colour.build import plan_colour
    from stringbot.planner.model.thread import ThreadModel

    path = tmp_path / "gray.png"
    Image.fromarray(np.full((32, 32, 3), 120, np.uint8)).save(path)
    with pytest.raises(BadInput, match="texture"):
        plan_colour(path, colors=["#141414"], pins=40, size=32, lines=10, cache=False, texture=-1,
                    model=ThreadModel(diameter_mm=100, thread_mm=0.5))
