"""The planner's parts: chord space, chord pixels, solve, sampling, greedy, render, score.

Small rings and small pictures only; full-size runs live in benchmarks/.
"""

import numpy as np
import pytest

from stringbot.errors import BadInput
from stringbot.planner.build import plan_picture
from stringbot.planner.knobs import auto_lines
from stringbot.planner.methods.fitness import solve_fitness
from stringbot.planner.methods.greedy import greedy_sequence
from stringbot.planner.methods.sampling import _Diffuser, fitness_table, sample_connected, sample_disconnected
from stringbot.planner.model.chords import (chord_pixels, chord_space, frame_mask, line_pixels, pin_positions,
                                            pixel_chords, thread_length)
from stringbot.planner.model.render import draw
from stringbot.planner.model.scoring import score

from planner_helpers import picture


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("STRINGBOT_CACHE", str(tmp_path / "cache"))


def bar_picture(size=101):
    """White picture with a dark horizontal bar through the middle."""
    g = np.full((size, size), 255.0)
    g[size // 2 - 6:size // 2 + 6, :] = 0.0
    return g


# ---- chord space -----------------------------------------------------------------------------

def test_pins_start_at_the_top_and_go_clockwise():
    xy = pin_positions(8, "circle")
    assert np.allclose(xy[0], [0.5, 0.0])
    assert np.allclose(xy[2], [1.0, 0.5])   # a quarter turn clockwise: right (x right, y down)
    assert np.allclose(xy[4], [0.5, 1.0])
    assert np.allclose(xy[6], [0.0, 0.5])


def test_square_pins_lie_on_the_border_and_side_chords_are_excluded():
    P = 40
    xy = pin_positions(P, "square")
    on_border = (np.isclose(xy, 0) | np.isclose(xy, 1)).any(axis=1)
    assert on_border.all()
    assert np.allclose(xy[0], [0.5, 0.0])
    steps = np.linalg.norm(np.diff(np.vstack([xy, xy[:1]]), axis=0), axis=1)
    assert steps.max() < 4.0 / P + 1e-9  # evenly spaced along the perimeter
    space = chord_space(P, "square")
    for i, j in space.ends:
        same_side = any(np.isclose(xy[i, a], e) and np.isclose(xy[j, a], e) for a in (0, 1) for e in (0, 1))
        assert not same_side
    # each side has P/4 + 1 pins (corners shared): exactly those pairs are gone
    per_side = P // 4 + 1
    assert space.m == P * (P - 1) // 2 - 4 * per_side * (per_side - 1) // 2


def test_chord_index_is_symmetric_and_span_wraps():
    s = chord_space(12)
    assert s.m == 66
    assert (s.index == s.index.T).all() and (np.diag(s.index) == -1).all()
    c = s.index[0, 11]
    assert tuple(s.ends[c]) == (0, 11) and s.span[c] == 1
    assert s.span[s.index[0, 6]] == 6


def test_chord_pixels_are_gapless_paths_between_the_pins():
    size = 61
    s = chord_space(24)
    indptr, indices = chord_pixels(s, size, cache=False)
    rc = np.rint(s.pin_xy[:, ::-1] * (size - 1)).astype(int)
    for c in range(s.m):
        pix = indices[indptr[c]:indptr[c + 1]]
        r, q = pix // size, pix % size
        i, j = s.ends[c]
        assert (r[0], q[0]) == tuple(rc[i]) and (r[-1], q[-1]) == tuple(rc[j])
        assert len(set(pix.tolist())) == len(pix)                          # no pixel twice
        assert np.abs(np.diff(r)).max(initial=0) <= 1 and np.abs(np.diff(q)).max(initial=0) <= 1  # no gap
        assert len(pix) == max(abs(rc[i] - rc[j])) + 1


def test_line_pixels_are_the_nearest_pixels_to_the_segment():
    from skimage.draw import line
    rng = np.random.default_rng(3)
    ends = rng.integers(0, 50, size=(60, 4))
    counts, flat = line_pixels(ends[:, 0], ends[:, 1], ends[:, 2], ends[:, 3], 50)
    start = 0
    for (r0, c0, r1, c1), n in zip(ends, counts):
        pix = flat[start:start + n]
        r, c = pix // 50, pix % 50
        assert n == len(line(r0, c0, r1, c1)[0])  # as many pixels as Bresenham's line
        steps = max(abs(r1 - r0), abs(c1 - c0), 1)
        t = np.arange(n) / steps
        # off the ideal segment by at most half a pixel across its major axis
        assert np.abs(r - (r0 + t * (r1 - r0))).max() <= 0.5 + 1e-6
        assert np.abs(c - (c0 + t * (c1 - c0))).max() <= 0.5 + 1e-6
        start += n


def test_pixel_major_is_the_transpose_of_chord_major():
    space = chord_space(20)
    indptr, indices = chord_pixels(space, 41)
    rowptr, chords = pixel_chords(space, 41)
    pairs_a = {(int(p), c) for c in range(space.m) for p in indices[indptr[c]:indptr[c + 1]]}
    pairs_b = {(p, int(c)) for p in range(41 * 41) for c in chords[rowptr[p]:rowptr[p + 1]]}
    assert pairs_a == pairs_b


def test_chord_cache_is_reused_and_a_damaged_one_rebuilt(tmp_path, monkeypatch):
    monkeypatch.setenv("STRINGBOT_CACHE", str(tmp_path / "c"))
    s = chord_space(30)
    a = chord_pixels(s, 51)
    files = list((tmp_path / "c").glob("*.npz"))
    assert len(files) == 1
    b = chord_pixels(s, 51)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    files[0].write_bytes(b"garbage")
    c = chord_pixels(s, 51)
    assert all(np.array_equal(x, y) for x, y in zip(a, c))
    monkeypatch.setenv("STRINGBOT_CACHE", "off")
    chord_pixels(chord_space(31), 51)
    assert len(list((tmp_path / "c").glob("*.npz"))) == 1


# ---- the chord distance and error diffusion -------------------------------------------------

def paper_distance(c1, c2, P):
    """min over the equivalences of the L-infinity distance, in pins (section 3.1)."""
    def circ(a, b):
        d = abs(a - b) % P
        return min(d, P - d)
    (i1, j1), (i2, j2) = c1, c2
    return min(max(circ(i1, i2), circ(j1, j2)), max(circ(j1, i2), circ(i1, j2)))


@pytest.mark.parametrize("chord", [(0, 1), (0, 19), (3, 10), (5, 15), (1, 18), (9, 11)])
@pytest.mark.parametrize("eps", [1, 2, 3])
def test_neighbourhood_is_the_papers_distance_ball(chord, eps):
    P = 20
    space = chord_space(P)
    lo, hi, size = _Diffuser(space, eps).neighbours(*chord)
    got = set(zip(lo.tolist(), hi.tolist()))
    want = {(a, b) for a, b in space.ends.tolist() if paper_distance(chord, (a, b), P) <= eps} - {chord}
    assert got == want
    assert size == len(want) + 1


def test_error_is_spread_evenly_over_the_neighbours():
    P = 30
    space = chord_space(P)
    table = fitness_table(space, np.zeros(space.m), T=30.0)  # all 0.5
    before = table.copy()
    seq = sample_connected(space, table, 1, epsilon=2, start_pin=4)
    i, j = seq
    lo, hi, size = _Diffuser(space, 2).neighbours(i, j)
    with np.errstate(invalid="ignore"):
        drop = before - table
    assert np.isinf(table[i, j]) and np.isinf(table[j, i])
    assert np.allclose(drop[lo, hi], 0.5 / (size - 1)) and np.allclose(drop[hi, lo], 0.5 / (size - 1))
    others = np.isfinite(table)
    others[lo, hi] = others[hi, lo] = False
    assert np.allclose(drop[others], 0)


def test_tanh_mapping():
    space = chord_space(10)
    f = np.linspace(-100, 100, space.m)
    t = fitness_table(space, f, T=30.0)
    i, j = space.ends.T
    assert np.allclose(t[i, j], (np.tanh(f / 30.0) + 1) / 2)
    assert np.isinf(np.diag(t)).all()


# ---- sampling --------------------------------------------------------------------------------

def test_connected_sampling_takes_the_best_unused_chord_and_never_repeats():
    P = 16
    space = chord_space(P)
    rng = np.random.default_rng(0)
    f = rng.normal(size=space.m)
    table = fitness_table(space, f, T=1.0)
    ref = table.copy()
    seq = sample_connected(space, table, 40, epsilon=0, start_pin=3)  # epsilon 0: no diffusion
    assert seq[0] == 3 and len(seq) == 41
    chords = [tuple(sorted(c)) for c in zip(seq[:-1], seq[1:])]
    assert len(set(chords)) == len(chords)
    assert all(a != b for a, b in zip(seq[:-1], seq[1:]))
    used = set()
    for a, b in zip(seq[:-1], seq[1:]):
        row = ref[a].copy()
        for u, v in used:
            if a in (u, v):
                row[v if a == u else u] = -np.inf
        assert ref[a, b] == row.max()
        used.add(tuple(sorted((a, b))))


def test_connected_sampling_stops_when_a_pin_has_no_unused_chord():
    space = chord_space(4)  # 6 chords; an Euler-like walk runs out
    seq = sample_connected(space, fitness_table(space, np.ones(space.m), T=1.0), 50, epsilon=0)
    assert 2 <= len(seq) - 1 <= 6
    assert len({tuple(sorted(c)) for c in zip(seq[:-1], seq[1:])}) == len(seq) - 1


def test_disconnected_sampling_is_best_first_with_diffusion():
    space = chord_space(20)
    rng = np.random.default_rng(1)
    f = rng.normal(size=space.m)
    table = fitness_table(space, f, T=1.0)
    chosen = sample_disconnected(space, table.copy(), 10, epsilon=0)
    order = np.argsort(-f)[:10]
    assert chosen == [tuple(space.ends[c]) for c in order]
    # diffusion: the error of the first choice pushes its neighbour below a far chord
    t = np.where(np.isfinite(table), 0.1, -np.inf)
    for (a, b), value in (((3, 10), 0.6), ((4, 10), 0.58), ((12, 17), 0.57)):
        t[a, b] = t[b, a] = value
    assert sample_disconnected(space, t.copy(), 3, epsilon=0) == [(3, 10), (4, 10), (12, 17)]
    assert sample_disconnected(space, t.copy(), 2, epsilon=1) == [(3, 10), (12, 17)]


# ---- the solve -------------------------------------------------------------------------------

def test_solve_matches_dense_least_squares():
    size = 41
    space = chord_space(24)
    indptr, indices = chord_pixels(space, size, cache=False)
    A = np.zeros((size * size, space.m))
    for c in range(space.m):
        A[indices[indptr[c]:indptr[c + 1]], c] = 1
    rng = np.random.default_rng(2)
    b = rng.random(size * size) * 255
    w = frame_mask(size, "circle").ravel() * (1 + rng.random(size * size))
    v = 1 + 4 * rng.random(space.m)
    want = np.linalg.lstsq(np.vstack([w[:, None] * A, np.diag(v)]),
                           np.concatenate([w * b, np.zeros(space.m)]), rcond=None)[0]
    rowptr, chords = pixel_chords(space, size, cache=False)
    got, info = solve_fitness(rowptr, chords, b, w, v, iterations=500, tol=1e-10)
    assert np.abs(got - want).max() < 2e-3 * np.abs(want).max()
    assert info["stop"] in (1, 2) and info["iterations"] < 500  # converged, not stopped by the limit
    resid = np.concatenate([w * (A @ got - b), v * got])
    assert abs(info["residual"] - np.linalg.norm(resid)) < 1e-3 * np.linalg.norm(resid)
    # the iteration limit holds, and a cut-short solve is further from the minimiser
    early, info3 = solve_fitness(rowptr, chords, b, w, v, iterations=3, tol=1e-10)
    assert info3["iterations"] == 3 and info3["stop"] == 7
    assert np.abs(early - want).max() > np.abs(got - want).max()


def test_fitness_is_high_on_chords_through_the_dark_bar():
    size = 101
    plan = plan_picture("x", method="fitness", pins=60, size=size, lines=60, picture=picture(bar_picture(size)))
    xy = plan.pin_xy
    # chords that run along the bar (both ends near its height) dominate the sequence
    mids = np.array([(xy[a, 1] + xy[b, 1]) / 2 for a, b in plan.chord_list()])
    assert np.mean(np.abs(mids - 0.5) < 0.15) > 0.6


# ---- methods end to end on synthetic pictures ------------------------------------------------

def test_auto_lines_follows_the_paper():
    g = np.full((51, 51), 200.0)
    assert auto_lines(g, frame_mask(51, "circle")) == 500 + 10 * 55


def test_plan_records_every_knob_and_the_stats():
    size = 101
    pic = picture(bar_picture(size))
    plan = plan_picture("x", method="fitness", pins=60, size=size, lines=50, start_pin=7, alpha=0.25, beta=4.0, gamma=8.0,
                        T=20.0, epsilon=1, iterations=15, picture=pic)
    assert plan.sequence[0] == 7 and len(plan.sequence) == 51 and plan.connected
    p = plan.parameters
    for key, value in dict(pins=60, frame="circle", size=size, lines=50, start_pin=7, method="fitness",
                           alpha=0.25, beta=4.0, gamma=8.0, T=20.0, epsilon=1, iterations=15,
                           disconnected=False).items():
        assert p[key] == value, key
    s = plan.stats
    assert s["lines"] == 50 and s["seconds"] >= 0
    assert s["thread_diameters"] == pytest.approx(thread_length(plan.pin_xy, plan.chord_list()), abs=1e-3)
    assert 0 < s["thread_diameters"] <= 50


def test_fitness_beats_a_random_sequence_on_ssim():
    size = 101
    gray = bar_picture(size)
    pic = picture(gray)
    plan = plan_picture("x", method="fitness", pins=60, size=size, lines=80, picture=pic)
    rng = np.random.default_rng(0)
    rand = plan_picture("x", method="fitness", pins=60, size=size, lines=80, picture=pic)
    seq = [0]
    for _ in range(80):
        seq.append(int((seq[-1] + rng.integers(1, 60)) % 60))
    rand.sequence = seq
    assert score(plan, gray)["ssim"] > score(rand, gray)["ssim"]


def test_greedy_stays_off_white_and_respects_its_loop_rule():
    size = 101
    gray = bar_picture(size)
    space = chord_space(60)
    seq = greedy_sequence(space, size, gray, frame_mask(size, "circle"), 5000)
    for k in range(1, len(seq)):
        assert seq[k] not in seq[max(0, k - 3):k]
    # a thin bar can take only so much: the run stops early once every chord's sum is <= 0
    assert 50 < len(seq) - 1 < 5000
    xy = space.pin_xy
    mids = np.array([(xy[a, 1] + xy[b, 1]) / 2 for a, b in zip(seq[:-1], seq[1:])])
    assert np.mean(np.abs(mids - 0.5) < 0.15) > 0.6


@pytest.mark.parametrize("method", ["greedy", "fitness"])
def test_blank_picture_is_refused(method):
    pic = picture(np.full((101, 101), 255.0))
    with pytest.raises(BadInput, match="nothing to draw"):
        plan_picture("x", pins=40, size=101, method=method, picture=pic)


def test_tiny_ring_runs_out_of_chords_gracefully():
    plan = plan_picture("x", method="fitness", pins=3, size=101, lines=10, picture=picture(bar_picture()))
    assert 1 <= plan.stats["lines"] <= 3 and len(set(map(frozenset, plan.chord_list()))) == plan.stats["lines"]


def test_disconnected_plan_is_a_chord_set():
    size = 101
    plan = plan_picture("x", method="fitness", pins=60, size=size, lines=40, disconnected=True, picture=picture(bar_picture(size)))
    assert not plan.connected and plan.sequence == [] and len(plan.chords) == 40
    assert len(set(plan.chords)) == 40
    assert draw(plan, size=101).min() == 0


def test_square_frame_plan_never_uses_a_side_chord():
    size = 101
    plan = plan_picture("x", method="fitness", pins=48, frame="square", size=size, lines=60, picture=picture(bar_picture(size)))
    xy = plan.pin_xy
    for a, b in plan.chord_list():
        assert not any(np.isclose(xy[a, k], e) and np.isclose(xy[b, k], e) for k in (0, 1) for e in (0, 1))


def test_importance_pulls_chords_to_the_important_half(tmp_path):
    from PIL import Image

    size = 101
    g = np.full((size, size), 128.0)  # flat gray: no preference without a mask
    pic = picture(g)
    mask = np.zeros((size, size), dtype=np.uint8)
    mask[:, : size // 2] = 255  # left half important
    Image.fromarray(mask).save(tmp_path / "m.png")
    with_mask = plan_picture("x", method="fitness", pins=60, size=size, lines=80, picture=pic, importance=tmp_path / "m.png")
    plain = plan_picture("x", method="fitness", pins=60, size=size, lines=80, picture=pic)
    def left_share(plan):
        img = draw(plan, size=101) == 0
        return img[:, :50].sum() / img.sum()
    assert left_share(with_mask) > left_share(plain) + 0.03
    assert with_mask.parameters["importance"].endswith("m.png")


@pytest.mark.parametrize("knob, value, words", [
    ("pins", 2, "--pins 2"), ("pins", 10**6, "--pins"), ("lines", 0, "--lines 0"), ("lines", -3, "--lines"),
    ("size", 5, "--size"), ("T", 0.0, "--sharpness"), ("alpha", 2.0, "--alpha"), ("start_pin", 99, "--start-pin"),
    ("epsilon", -1, "--epsilon"), ("epsilon", 5000, "--epsilon"), ("frame", "hexagon", "--frame"),
    ("method", "magic", "--method"), ("iterations", 0, "--iterations"),
])
def test_bad_knobs_are_named(knob, value, words):
    kw = dict(pins=60, size=101, lines=10, picture=picture(bar_picture()), method="fitness")
    kw[knob] = value
    with pytest.raises(BadInput) as info:
        plan_picture("x", **kw)
    assert words in str(info.value)


def test_render_draws_each_chord_black_on_white():
    size = 101
    plan = plan_picture("x", method="fitness", pins=60, size=size, lines=30, picture=picture(bar_picture(size)))
    img = draw(plan, size=201)
    assert img.dtype == np.uint8 and set(np.unique(img)) <= {0, 255}
    rc = np.rint(plan.pin_xy[plan.sequence][:, ::-1] * 200).astype(int)
    assert (img[rc[:, 0], rc[:, 1]] == 0).all()
    assert (img == 0).mean() < 0.5


def test_edge_term_suppresses_chords_that_cross_edges():
    from stringbot.planner.methods.fitness import edge_consistency, gradients

    size, P = 101, 40
    g = np.full((size, size), 255.0)
    g[:, : size // 2] = 0.0  # one vertical edge through the middle
    space = chord_space(P)
    rowptr, chords = pixel_chords(space, size)
    gy, gx = gradients(g)
    d = edge_consistency(space, rowptr, chords, gy, gx)
    along = space.index[0, P // 2]            # top to bottom: runs along the edge
    across = space.index[P // 4, 3 * P // 4]  # right to left: crosses it
    assert d[across] > 0 and d[along] < 0.1 * d[across]


def test_greedy_weight_is_threadtones_thread_scaled_to_the_working_size():
    size = 101
    pic = picture(bar_picture(size))
    scaled = plan_picture("x", pins=60, size=size, method="greedy", lines=5000, picture=pic)
    literal = plan_picture("x", pins=60, size=size, method="greedy", lines=5000, picture=pic,
                           greedy_reference_radius=None)
    assert scaled.parameters["weight_at_size"] == pytest.approx(15 * 50 / 500)
    assert literal.parameters["weight_at_size"] == 15
    # ten times lighter threads: the bar takes about ten times as many before every sum is <= 0
    assert 5 * literal.stats["lines"] < scaled.stats["lines"]


# ---- greedy: ThreadTone as published ---------------------------------------------------------

def threadtone_literal(gray, pin_rc, lines, weight, half):
    """ThreadTone's loop written out as threadTone.py does it, one chord at a time (a reference)."""
    size = gray.shape[0]
    img = 255.0 - gray
    yy, xx = np.mgrid[:size, :size]
    c = (size - 1) / 2
    img[(yy - c) ** 2 + (xx - c) ** 2 > (c + 0.5) ** 2] = 0.0
    P = len(pin_rc)
    prev, old, seq = [], 0, [0]
    for _ in range(lines):
        best, best_pin = 0.0, old
        for index in range(1, P):
            pin = (old + index) % P
            (r0, c0), (r1, c1) = pin_rc[old], pin_rc[pin]
            n = max(int(np.hypot(r1 - r0, c1 - c0)), 1)
            rr = np.linspace(r0, r1, n).astype(int)   # ThreadTone: linspace, truncated
            cc = np.linspace(c0, c1, n).astype(int)
            s = img[rr, cc].sum()
            if s > best and pin not in prev:
                best, best_pin = s, pin
        if best_pin == old:
            break
        prev = (prev + [best_pin])[-3:]
        # cv2.line(thickness=3) one pixel down-right of the sampled line: within 2 + 1/2 px
        (r0, c0), (r1, c1) = pin_rc[old] + 1, pin_rc[best_pin] + 1
        d = np.array([r1 - r0, c1 - c0], float)
        L = np.hypot(*d)
        u = np.clip(((yy - r0) * d[0] + (xx - c0) * d[1]) / L ** 2, 0, 1)
        dist = np.hypot(yy - r0 - u * d[0], xx - c0 - u * d[1])
        img[dist <= half + 0.5 * abs(d).max() / L + 1e-9] -= weight
        seq.append(best_pin)
        old = best_pin
    return seq


def test_greedy_is_threadtones_loop():
    size, P = 61, 24
    rng = np.random.default_rng(5)
    g = np.full((size, size), 255.0)
    g[20:40, 10:50] = 40.0
    g += rng.uniform(0, 30, g.shape)
    g = np.clip(g, 0, 255)
    space = chord_space(P)
    mask = frame_mask(size, "circle")
    seq = greedy_sequence(space, size, g, mask, 400, weight=15.0, reference_radius=None)
    pin_rc = np.floor(space.pin_xy[:, ::-1] * (size - 1) + 1e-9).astype(int)  # ThreadTone truncates pins too
    ref = threadtone_literal(g, pin_rc, 400, 15.0, 2.0)
    assert len(seq) > 30 and len(seq) < 401  # it stopped by ThreadTone's rule: no positive sum left
    assert seq == ref


def test_threadtone_line_sums_are_isotropic_and_its_band_is_perpendicular():
    from stringbot.planner.methods.greedy import band_pixels, cv_half_width
    from stringbot.planner.model.lines import line_samples
    size = 201
    starts, flat = line_samples(10, 10, np.array([10, 190]), np.array([190, 190]), size)
    n = np.diff(np.append(starts, len(flat)))
    assert list(n) == [180, int(np.hypot(180, 180))]  # int(hypot) points: a diagonal is not under-counted
    assert cv_half_width(3) == 2.0 and cv_half_width(4) == 2.0
    horizontal = band_pixels(100, 20, 100, 180, size, 2.0)
    assert set(np.unique(horizontal // size)) == {98, 99, 100, 101, 102}  # cv2.line(thickness=3): 5 rows
    diagonal = band_pixels(20, 20, 180, 180, size, 2.0)
    r, c = diagonal // size, diagonal % size
    inner = (r > 30) & (r < 170)
    across = np.abs(r - c)[inner] / np.sqrt(2)  # distance from the thread, perpendicular to it
    assert across.max() <= 2.0 + 0.36 and np.sum(inner) / 140 > 6  # as wide across, not squeezed on a row
