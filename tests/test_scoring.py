"""The scorer: the paper's SSIM with both windows, and the as-woven error."""

import numpy as np
import pytest

from stringbot.planner.model.chords import pin_positions
from stringbot.planner.model.scoring import SSIM_KEYS, score_chords, ssim_pair, woven_drawing, woven_error


def test_ssim_pair_gives_both_windows_plain_and_blurred():
    rng = np.random.default_rng(3)
    a = rng.random((64, 64))
    same = ssim_pair(a, a)
    assert set(same) == set(SSIM_KEYS) and all(v == pytest.approx(1.0) for v in same.values())
    b = np.clip(a + 0.3 * rng.standard_normal(a.shape), 0, 1)
    r = ssim_pair(a, b)
    assert r["ssim"] != pytest.approx(r["ssim_uniform"], abs=1e-3)  # the windows differ
    assert r["ssim_blurred"] > r["ssim"]  # blurring removes the noise first


def test_woven_error_of_a_blank_board():
    xy = pin_positions(40, "square")
    white = np.full((512, 512), 255.0)
    assert woven_error([], xy, white, frame="square") == pytest.approx(0.0, abs=1e-9)
    gray = np.full((512, 512), 102.0)
    assert woven_error([], xy, gray, frame="square") == pytest.approx(1 - 102 / 255, abs=1e-6)


def test_woven_drawing_draws_threads_at_their_width():
    xy = np.array([[0.0, 0.5013], [1.0, 0.5017]])
    # 0.25 mm on 500 mm (the default) on a 512 px picture: 0.256 of a pixel's width, darkness per column
    darkness = (1.0 - woven_drawing([(0, 1)], xy)).sum(axis=0)
    assert np.allclose(darkness[8:-8].mean(), 0.256, atol=0.01)
    wide = (1.0 - woven_drawing([(0, 1)], xy, thread_fraction=1.0 / 500)).sum(axis=0)
    assert np.allclose(wide[8:-8].mean(), 1.024, atol=0.02)


def test_woven_error_rewards_thread_where_the_picture_is_dark():
    P = 120
    xy = pin_positions(P, "circle")
    g = np.full((512, 512), 255.0)
    g[236:276, :] = 0.0  # a dark horizontal bar
    on_bar = [(P // 4 + k % 3, 3 * P // 4 - k % 3) for k in range(40)]  # chords across the middle, left-right
    off_bar = [(P - P // 8 - k % 3, P // 8 + k % 3) for k in range(40)]  # chords near the top, on white
    blank = woven_error([], xy, g, frame="circle")
    assert woven_error(on_bar, xy, g, frame="circle") < blank < woven_error(off_bar, xy, g, frame="circle")


def test_score_chords_reports_every_figure():
    xy = pin_positions(60, "circle")
    g = np.full((201, 201), 255.0)
    g[:, 90:110] = 30.0
    chords = [(0, 30), (1, 31), (29, 59)]
    s = score_chords(chords, xy, g, frame="circle", woven_gray=np.full((512, 512), 255.0))
    assert set(SSIM_KEYS) <= set(s) and s["lines"] == 3 and s["woven_error"] > 0
    assert "woven_error" not in score_chords(chords, xy, g, frame="circle")
