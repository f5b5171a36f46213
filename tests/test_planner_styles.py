"""Fitness styles: detail (the paper's beta, gamma, T), fill (strong regularisation, sharp T), auto (keep the better).

Small rings and small synthetic pictures; the full-size quality table is
benchmarks/quality_table.py.
"""

import numpy as np
import pytest

from stringbot.errors import BadInput
from stringbot.planner.build import plan_picture
from stringbot.planner.methods import DEFAULTS
from stringbot.planner.methods.fitness import FILL, style_candidates
from stringbot.planner.model.render import draw
from stringbot.planner.model.scoring import score

from planner_helpers import picture

SIZE, PINS, LINES = 101, 100, 300


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("STRINGBOT_CACHE", str(tmp_path / "cache"))


def silhouette(n=SIZE):
    """A black 'animal': a wide body band and two legs, on white (like the horse test picture)."""
    yy, xx = np.mgrid[:n, :n]
    g = np.full((n, n), 255.0)
    g[(yy > 30) & (yy < 65)] = 0.0
    g[(yy >= 65) & (yy < 90) & ((abs(xx - 30) < 5) | (abs(xx - 70) < 5))] = 0.0
    return g


def plan(gray, **kw):
    kw.setdefault("method", "fitness")
    return plan_picture("x", pins=PINS, size=SIZE, lines=LINES, picture=picture(gray), **kw)


def white_share(p, gray):
    """Share of the drawing's thread pixels (at the working size) that lie on white picture pixels."""
    thread = draw(p, size=gray.shape[0]) == 0
    return float(np.mean(gray[thread] > 230))


def test_candidates_follow_the_style_and_the_given_knobs():
    detail = {k: DEFAULTS[k] for k in ("beta", "gamma", "T")}
    assert style_candidates("auto") == [("detail", detail), ("fill", FILL)]
    assert style_candidates("detail") == [("detail", detail)]
    assert style_candidates("fill") == [("fill", FILL)]
    # any knob given: that knob, the paper's defaults for the rest, and no comparison
    assert style_candidates("auto", T=12.0) == [("detail", dict(detail, T=12.0))]
    assert style_candidates("detail", beta=1.0, gamma=0.0) == [("detail", dict(detail, beta=1.0, gamma=0.0))]
    assert FILL["beta"] == 30 * DEFAULTS["beta"] and FILL["gamma"] == 30 * DEFAULTS["gamma"]


def test_auto_keeps_the_style_whose_drawing_scores_higher_and_records_both():
    gray = silhouette()
    auto = plan(gray)
    styles = auto.stats["styles"]
    assert set(styles) == {"detail", "fill"}
    # no one SSIM variant decides: both windows, plain and blurred, are summed
    keys = ("ssim", "ssim_blurred", "ssim_uniform", "ssim_uniform_blurred")
    assert all(set(keys) <= set(v) for v in styles.values())
    rank = {k: sum(v[key] for key in keys) for k, v in styles.items()}
    chosen = auto.parameters["style"]
    assert rank[chosen] == max(rank.values())
    assert auto.parameters["style_requested"] == "auto"
    # the kept drawing is exactly that style's own plan, and its recorded score is the drawing's
    alone = plan(gray, style=chosen)
    assert alone.sequence == auto.sequence
    assert alone.parameters["style"] == chosen and "styles" not in alone.stats
    for key in ("beta", "gamma", "T"):
        assert auto.parameters[key] == (FILL if chosen == "fill" else DEFAULTS)[key]
    s = score(auto, gray)
    assert s["ssim"] == pytest.approx(styles[chosen]["ssim"], abs=1e-3)
    assert s["ssim_blurred"] == pytest.approx(styles[chosen]["ssim_blurred"], abs=1e-3)


def test_fill_keeps_the_white_of_a_silhouette_cleaner_and_wins_it():
    gray = silhouette()
    detail, fill = plan(gray, style="detail"), plan(gray, style="fill")
    assert white_share(fill, gray) < white_share(detail, gray) - 0.05
    assert score(fill, gray)["ssim"] > score(detail, gray)["ssim"]
    assert plan(gray).parameters["style"] == "fill"


def test_explicit_knobs_mean_detail_without_a_comparison():
    p = plan(silhouette(), T=12.0)
    assert p.parameters["style"] == "detail" and p.parameters["T"] == 12.0
    assert p.parameters["beta"] == DEFAULTS["beta"] and "styles" not in p.stats


@pytest.mark.parametrize("kw, words", [
    (dict(style="fill", T=5.0), "--style fill sets beta, gamma and T itself"),
    (dict(style="fill", beta=1.0, gamma=2.0), "--beta, --gamma"),
    (dict(style="sharp"), "--style 'sharp'"),
    (dict(method="greedy", style="fill"), "knobs of --method fitness"),
    (dict(method="greedy", T=3.0), "knobs of --method fitness"),
    (dict(beta=-1.0), "--beta -1.0"),
])
def test_conflicting_or_bad_style_knobs_are_refused(kw, words):
    with pytest.raises(BadInput) as info:
        plan(silhouette(), **kw)
    assert words in str(info.value)


def test_disconnected_compares_the_styles_too():
    p = plan(silhouette(), disconnected=True)
    assert not p.connected and len(p.chords) == LINES
    assert set(p.stats["styles"]) == {"detail", "fill"}
