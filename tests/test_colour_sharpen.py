"""The colour planner's target: the picture sharpened (edges for the threads to lie on), the threads picked as it is."""

import numpy as np
import pytest
from PIL import Image

from stringbot.errors import BadInput
from stringbot.planner.colour.build import plan_colour
from stringbot.planner.colour.model import sharpened
from stringbot.planner.colour.palette import to_linear
from stringbot.planner.model.thread import ThreadModel

THICK = ThreadModel(diameter_mm=100, thread_mm=0.5)


def step(n=32, left=(0.2, 0.1, 0.05), right=(0.9, 0.6, 0.3)):
    img = np.empty((n, n, 3))
    img[:, : n // 2] = left
    img[:, n // 2:] = right
    return img


def test_flat_picture_and_amount_0_are_left_as_they_are():
    flat = np.full((16, 16, 3), 0.4)
    assert np.allclose(sharpened(flat, amount=2.0), flat)
    img = step()
    assert np.array_equal(sharpened(img, amount=0), img)


def test_an_edge_is_steepened_and_far_from_it_nothing_changes():
    img = step()
    out = sharpened(img, amount=2.0, sigma=1.0)
    assert out.min() >= 0 and out.max() <= 1
    y = to_linear(img) @ (0.2126, 0.7152, 0.0722)
    ys = to_linear(out) @ (0.2126, 0.7152, 0.0722)
    assert ys[5, 15] < y[5, 15] - 0.005 and ys[5, 16] > y[5, 16] + 0.005     # each side pushed away from the other
    assert np.allclose(out[:, :8], img[:, :8]) and np.allclose(out[:, 24:], img[:, 24:])


def test_only_lightness_is_sharpened_the_colour_stays():
    img = step()
    out = to_linear(sharpened(img, amount=2.0))
    lin = to_linear(img)
    ok = (out < 0.999).all(axis=-1)             # not clipped
    ratio = out[ok] / lin[ok]
    assert np.allclose(ratio, ratio[:, :1], atol=1e-9)     # every channel scaled alike: the same chromaticity


@pytest.fixture
def line_picture(tmp_path):
    """A light gray picture with a thin dark line across it."""
    n = 96
    img = np.full((n, n, 3), 200, np.uint8)
    img[47:49, 10:86] = 40
    path = tmp_path / "line.png"
    Image.fromarray(img).save(path)
    return path


def test_sharpening_puts_more_of_the_thread_on_a_thin_line(line_picture):
    def on_line(plan):
        xy = plan.pin_xy
        hits = 0
        for a, b in plan.chord_list():
            t = np.linspace(0, 1, 200)[:, None]
            p = xy[a] * (1 - t) + xy[b] * t
            hits += np.count_nonzero(np.abs(p[:, 1] - 0.5) < 0.02) / 200
        return hits / len(plan.chord_list())

    kw = dict(colors=["#141414"], pins=60, size=48, lines=60, model=THICK, cache=False, texture=0)  # sharpening alone
    plain = plan_colour(line_picture, sharpen=0, **kw)
    sharp = plan_colour(line_picture, **kw)
    assert plain.parameters["sharpen"] == 0 and sharp.parameters["sharpen"] == 2.0
    assert on_line(sharp) > on_line(plain)


def test_a_bad_amount_is_refused(line_picture):
    with pytest.raises(BadInput, match="sharpen"):
        plan_colour(line_picture, colors=["#141414"], pins=60, size=48, lines=10, model=THICK, cache=False,
                    sharpen=-1)


def test_an_amount_per_pixel_sharpens_each_pixel_by_its_own():
    img = step()
    amount = np.full(img.shape[:2], 2.0)
    assert np.allclose(sharpened(img, amount=amount, sigma=1.0), sharpened(img, amount=2.0, sigma=1.0))
    amount[:16] = 0.0                                     # the top half as it is, the bottom half sharpened
    out = sharpened(img, amount=amount, sigma=1.0)
    assert np.allclose(out[:16], img[:16])
    assert np.allclose(out[16:], sharpened(img, amount=2.0, sigma=1.0)[16:])
    assert np.array_equal(sharpened(img, amount=np.zeros(img.shape[:2])), img)


def test_face_share_is_the_face_ellipse_over_any_importance():
    from stringbot.planner.colour.faces import face_share as _face_share
    from stringbot.planner.picture.face import FACE_WEIGHT

    face = np.ones((8, 8))
    face[2:6, 2:6] = 1.0 + FACE_WEIGHT
    face[2, 2] = 1.0 + FACE_WEIGHT / 2                    # the soft edge
    assert np.allclose(_face_share(face, None)[3:6, 3:6], 1.0) and _face_share(face, None)[0, 0] == 0.0
    assert np.isclose(_face_share(face, None)[2, 2], 0.5)
    importance = np.full((8, 8), 0.5)
    importance[0] = 0.0                                   # weighs nothing: no share there
    share = _face_share(face * importance, importance)
    assert np.allclose(share[1:], _face_share(face, None)[1:]) and (share[0] == 0).all()
