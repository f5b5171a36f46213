"""Faces: the largest frontal face found, the crop holding it, its features weighed (planner/picture/face.py)."""

import json

import numpy as np
import pytest
from PIL import Image
from skimage import data

from stringbot.errors import BadInput
from stringbot.planner import read_plan
from stringbot.planner.build import plan_picture
from stringbot.planner.model.scoring import face_ssim
from stringbot.planner.picture.face import (Face, _group, crop_on_face, face_box_pixels, face_crop, face_for_plan,
                                            face_weights, largest_face)
from test_cli_plan import SMALL, one_error_line, picture, run  # noqa: F401  (picture: a fixture)

#: the astronaut's face in skimage's 512-px picture, (row, col) of its centre (by eye: between the eyes
#: and the mouth)
ASTRONAUT_FACE = (118.0, 226.0)


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("STRINGBOT_CACHE", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def astronaut():
    return Image.fromarray(data.astronaut())


def small(astronaut, folder, n=128):
    path = folder / f"astronaut{n}.png"
    astronaut.resize((n, n), Image.Resampling.LANCZOS).save(path)
    return path


@pytest.fixture
def no_face(picture):
    """A dark disc on light gray (test_cli_plan's picture): no face."""
    return picture


def test_the_face_is_found_on_a_small_astronaut(tmp_path, astronaut):
    face = largest_face(small(astronaut, tmp_path))
    assert face is not None and face.votes >= 8
    k = 128 / 512
    cy, cx = face.centre
    assert abs(cy - ASTRONAUT_FACE[0] * k) < 0.1 * 128 and abs(cx - ASTRONAUT_FACE[1] * k) < 0.1 * 128
    assert 0.12 * 128 < face.width < 0.35 * 128           # a face, not the whole picture nor a speck
    (ry, lx), (_, rx) = face.eyes
    assert face.row < ry < face.mouth[0] < face.row + face.height and lx < face.mouth[1] < rx


def test_no_face_in_a_disc_nor_in_noise(tmp_path, no_face):
    assert largest_face(no_face) is None
    noise = tmp_path / "noise.png"
    Image.fromarray(np.random.default_rng(1).integers(0, 256, (160, 160), dtype=np.uint8)).save(noise)
    assert largest_face(noise) is None


def test_windows_are_grouped_by_place_and_size():
    windows = [(10, 10, 30), (11, 10, 31), (10, 12, 29), (9, 9, 32),     # one place, about one size
               (10, 10, 60),                                               # same corner, twice the size
               (80, 80, 30), (81, 79, 30)]
    groups = _group(windows)
    assert [g[0] for g in groups] == [4, 2, 1]
    assert groups[0][1:] == pytest.approx((10, 10, 30.5), abs=1)


def test_the_crop_holds_the_face_and_stays_inside(tmp_path, astronaut):
    # the astronaut at the right of a wide white picture: the default crop is its centre, and it is moved
    # towards her face as far as holds the face box, no further
    wide = Image.new("RGB", (300, 160), "white")
    wide.paste(astronaut.resize((160, 160), Image.Resampling.LANCZOS), (140, 0))
    path = tmp_path / "wide.png"
    wide.save(path)
    face = face_for_plan(path, face="on")
    assert face is not None
    crop = crop_on_face(path, face)
    cy, cx = face.centre
    corners = np.array([(face.col + dx, face.row + dy) for dx in (0, face.width) for dy in (0, face.height)])
    reach = np.hypot(*(corners - [crop["cx"], crop["cy"]]).T).max()
    assert crop["r"] == 80 and 150 < crop["cx"] < cx and reach <= 80 < reach + 2  # moved just enough
    assert crop["cy"] == 80  # not shrunk, inside the picture
    inside = Face(row=60, col=140, height=30, width=30, votes=9)  # a face the default crop holds: kept
    assert face_crop(inside, width=300, height=160) == {"cx": 150.0, "cy": 80.0, "r": 80.0}
    p = plan_picture(path, pins=60, size=101, lines=60, face="on")
    assert p.crop == crop and p.parameters["face"]["box"][1] == pytest.approx(face.col, abs=0.1)
    # a crop the user gives is kept (the face still weighed); --face off does not look
    given = {"cx": 150.0, "cy": 80.0, "r": 60.0}
    p = plan_picture(path, pins=60, size=101, lines=60, face="on", crop=given)
    assert p.crop == given and p.parameters["face"] is not None
    assert face_for_plan(path, face="off") is None
    r = face_crop(Face(row=0, col=390, height=20, width=20, votes=9), width=400, height=128)
    assert r == {"cx": 336.0, "cy": 64.0, "r": 64.0}


def test_the_weights_are_raised_on_the_face_and_most_on_its_features():
    size = 101
    crop = {"cx": 50.5, "cy": 50.5, "r": 50.5}  # source pixels = working pixels
    face = Face(row=20, col=30, height=40, width=40, votes=20)
    gray = np.full((size, size), 200.0)
    gray[30:70, 40:60] = 60.0  # an edge inside the face
    w = face_weights(face, crop=crop, size=size, gray=gray)  # the face raised alike
    assert w.shape == (size, size) and w.min() == pytest.approx(1.0)
    r0, c0, r1, c1 = face_box_pixels((20, 30, 40, 40), crop=crop, size=size)
    inside, outside = w[r0:r1, c0:c1], np.concatenate([w[:, :20].ravel(), w[:, 85:].ravel()])
    assert outside.max() < 1.01 and inside.mean() > 2.4 and w[40, 50] == pytest.approx(3.0)
    w = face_weights(face, crop=crop, size=size, gray=gray, eyes=1.5, mouth=1.0, edges=1.0)
    (er, ec), _ = face.eyes
    mr, mc = face.mouth
    cheek = w[int(20 + 0.6 * 40), int(30 + 0.15 * 40)]
    assert w[int(er), int(ec)] > cheek + 1 and w[int(mr), int(mc)] > cheek + 0.5
    assert w[50, 40] > w[50, 35] + 0.3  # the edge at column 40 weighs more than the flat skin beside it


def test_face_ssim_is_one_for_the_picture_and_lower_for_a_blank_face():
    rng = np.random.default_rng(0)
    pic = np.clip(0.5 + 0.2 * rng.standard_normal((64, 64)), 0, 1)
    crop = {"cx": 32.0, "cy": 32.0, "r": 32.0}
    box = (16, 16, 24, 24)
    assert face_ssim(pic, pic, box, crop=crop, frame="square") == pytest.approx({"face": 1.0, "frame": 1.0})
    drawn = pic.copy()
    drawn[16:40, 16:40] = 0.5
    s = face_ssim(drawn, pic, box, crop=crop, frame="square")
    assert s["face"] < 0.2 < s["frame"] < 1.0


def test_plan_face_on_a_small_astronaut_then_score(tmp_path, astronaut):
    img = small(astronaut, tmp_path, 160)
    out = tmp_path / "a.json"
    code, stdout, err = run("plan", img, "-o", out, *SMALL, "--lines", "150", "--face")
    assert code == 0, err
    assert "face: found at rows" in stdout and "the crop holds it" in stdout
    p = read_plan(out)
    r, c, h, w = p.parameters["face"]["box"]
    assert r < ASTRONAUT_FACE[0] * 160 / 512 < r + h and c < ASTRONAUT_FACE[1] * 160 / 512 < c + w
    code, stdout, err = run("score", out)
    assert code == 0, err
    line = next(ln for ln in stdout.splitlines() if ln.startswith("face"))
    assert "inside the face box" in line and "over the frame" in line
    # the face line's frame SSIM and the SSIM line's are told apart: their size, drawing and area said
    ssim = next(ln for ln in stdout.splitlines() if ln.startswith("SSIM"))
    assert "the whole 201 px square" in ssim and "as woven at 512 px" in line and "over the frame only" in line
    assert "blurred sigma 2 px" in line and "the SSIM line: 1-px chords, the whole 201 px square" in line
    code, stdout, err = run("score", out, "--json")
    f = json.loads(stdout)["face"]
    assert 0 < f["ssim_face_blurred"] <= 1 and 0 < f["ssim_frame_blurred"] <= 1 and f["box"] == [r, c, h, w]


def test_score_face_scores_a_plan_made_without_face_inside_the_face_box(tmp_path, astronaut, no_face):
    """`score --face` finds the face as `plan --face` does: the box a --face plan records, for any plan."""
    img = small(astronaut, tmp_path, 160)
    on, off = tmp_path / "on.json", tmp_path / "off.json"
    assert run("plan", img, "-o", on, *SMALL, "--lines", "150", "--face")[0] == 0
    assert run("plan", img, "-o", off, *SMALL, "--lines", "150")[0] == 0
    code, stdout, err = run("score", off)
    assert code == 0, err
    assert not any(ln.startswith("face") for ln in stdout.splitlines())
    code, stdout, err = run("score", off, "--face", "--json")
    assert code == 0, err
    f_off = json.loads(stdout)["face"]
    assert f_off["box"] == read_plan(on).parameters["face"]["box"]
    f_on = json.loads(run("score", on, "--json")[1])["face"]
    assert f_on["box"] == f_off["box"] and f_on["ssim_face_blurred"] != f_off["ssim_face_blurred"]
    code, stdout, err = run("score", off, "--face", "--colour")
    assert code == 0, err
    line = next(ln for ln in stdout.splitlines() if ln.startswith("face"))
    assert "inside the face box" in line and "colour" in line
    # a picture without a face: one line, exit 2
    code, _, err = run("score", off, no_face, "--face")
    one_error_line(code, err, "--face: no face found in")
    assert "score without --face" in err


def test_greedy_with_face_says_it_weighs_nothing(tmp_path, astronaut):
    """Greedy (ThreadTone) weighs no pixel: --face only keeps the face in its crop, and the line says so."""
    img = small(astronaut, tmp_path, 160)
    code, stdout, err = run("plan", img, "-o", tmp_path / "g.json", *SMALL, "--lines", "100", "--face",
                            "--method", "greedy")
    assert code == 0, err
    line = next(ln for ln in stdout.splitlines() if ln.startswith("face: found"))
    assert "greedy weighs every pixel alike" in line and "three times" not in line


def test_face_on_a_picture_without_one_is_refused(tmp_path, no_face):
    out = tmp_path / "d.json"
    code, _, err = run("plan", no_face, "-o", out, *SMALL, "--lines", "50", "--face")
    one_error_line(code, err, "no face found in")
    assert "plan with --face auto or without --face" in err and "--fit" not in err and not out.exists()
    with pytest.raises(BadInput, match="no face found"):
        plan_picture(no_face, pins=60, size=101, lines=50, face="on")


def test_face_auto_on_a_picture_without_one_plans_as_before(tmp_path, no_face):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    code, stdout, err = run("plan", no_face, "-o", a, *SMALL, "--lines", "50", "--face", "auto")
    assert code == 0, err
    assert "face:" not in stdout and not err.strip()
    code, _, err = run("plan", no_face, "-o", b, *SMALL, "--lines", "50")  # off: the default
    assert code == 0, err
    pa, pb = read_plan(a), read_plan(b)
    assert pa.sequence == pb.sequence and pa.crop == pb.crop and pa.parameters["face"] is None


def test_a_colour_plan_with_face_records_it_weighs_it_and_scores_it(tmp_path, astronaut):
    img = small(astronaut, tmp_path, 160)
    on, off = tmp_path / "on.json", tmp_path / "off.json"
    args = ["--pins", "120", "--size", "128", "--lines", "600", "--colors", "black,#ee7623,#eee6cc"]
    code, stdout, err = run("plan", img, "-o", on, *args, "--face")
    assert code == 0, err
    assert "face: found at rows" in stdout
    box = read_plan(on).parameters["face"]["box"]
    r, c, h, w = box
    assert r < ASTRONAUT_FACE[0] * 160 / 512 < r + h and c < ASTRONAUT_FACE[1] * 160 / 512 < c + w
    assert run("plan", img, "-o", off, *args)[0] == 0
    assert read_plan(off).parameters["face"] is None
    code, stdout, err = run("score", on)
    assert code == 0, err
    line = next(ln for ln in stdout.splitlines() if ln.startswith("face"))
    assert "inside the face box" in line and "colour" in line
    ssim = next(ln for ln in stdout.splitlines() if ln.startswith("SSIM"))
    assert "the whole 512 px square" in ssim and "over the frame only (the SSIM line: the whole square)" in line
    f_on = json.loads(run("score", on, "--json")[1])["face"]
    assert f_on["box"] == box
    # the same face box scored on the plan made without --face: the face is nearer the picture with it
    from stringbot.cli.colour import score_colour

    p_off = read_plan(off)
    p_off.parameters["face"] = {"box": box}
    f_off = score_colour(p_off, off, img)["face"]
    assert f_on["delta_e_face"] < f_off["delta_e_face"]
    assert f_on["ssim_face_blurred"] > f_off["ssim_face_blurred"]


def test_a_colour_plan_with_face_drafts_its_schedule_without_the_face_weights(tmp_path, astronaut, monkeypatch):
    # the draft (the colours' order and shares) weighs the frame alone; the plan without the face to compare with
    # too, the plans with it weigh the face more
    from stringbot.planner.colour import runs
    from stringbot.planner.colour.build import plan_colour

    seen, draft, follow = {"laid": []}, runs.draft_schedule, runs.follow

    def spy_draft(d, lines, **kw):
        seen["draft"] = d.piece.weight.copy()
        return draft(d, lines, **kw)

    def spy_follow(r, lines, schedule, **kw):
        seen["laid"].append((r.piece.weight.max(), lines))
        return follow(r, lines, schedule, **kw)

    monkeypatch.setattr(runs, "draft_schedule", spy_draft)
    monkeypatch.setattr(runs, "follow", spy_follow)
    p = plan_colour(small(astronaut, tmp_path, 160), colors=["#000000", "#ee7623"], pins=120, size=128, lines=300,
                    face="on")
    assert seen["draft"].max() == 1.0 and set(np.unique(seen["draft"])) <= {0.0, 1.0}
    (plain, n0), *faced = seen["laid"]
    assert plain == 1.0 and n0 == 300 and faced and all(w > 1.5 and n == 300 for w, n in faced)  # --lines 300: kept
    record = p.parameters["face_plan"]
    assert len(record["tried"]) == len(faced) and record["lines_more"] == 0.0
    assert record["strength"] in [t["strength"] for t in record["tried"]]


def test_lay_with_face_keeps_the_first_plan_whose_frame_is_not_lower(monkeypatch):
    from stringbot.planner.colour import faces

    class Laid:
        def __init__(self, strength, lines):
            self.piece, self.strength, self.lines = (strength, lines), strength, lines

    def lay(strength, lines, schedule):
        assert sum(n for _, n in schedule) == lines or lines == 1000
        return Laid(strength, lines)

    frames = {}
    monkeypatch.setattr(faces, "estimate", lambda piece, box, **kw: (0.7, frames[piece[0]]))
    schedule = [(0, 900), (1, 100)]
    frames.update({None: 0.60, 2.0: 0.59, 1.0: 0.61, 0.5: 0.62})
    got, record = faces.lay_with_face(lay, 1000, schedule, box=None, crop=None, frame="circle",
                                      candidates=((2.0, 0.1), (1.0, 0.1), (0.5, 0.1)))
    assert (got.strength, got.lines) == (1.0, 1100) and len(record["tried"]) == 2    # 0.5 not laid
    assert record["strength"] == 1.0 and record["lines_more"] == 0.1 and record["without"] == [0.7, 0.6]
    frames.update({2.0: 0.58, 1.0: 0.59, 0.5: 0.55})                                  # none: the best frame
    got, record = faces.lay_with_face(lay, 1000, schedule, box=None, crop=None, frame="circle", auto_lines=False,
                                      candidates=((2.0, 0.1), (1.0, 0.1), (0.5, 0.1)))
    assert (got.strength, got.lines) == (1.0, 1000) and len(record["tried"]) == 3


def test_the_estimate_of_a_piece_that_is_the_picture_is_one():
    from stringbot.planner.colour.faces import estimate
    from stringbot.planner.colour.model import Fine, Piece, _gray

    m, rng = 32, np.random.default_rng(1)
    rgb = rng.uniform(0.1, 0.9, (m * m, 3))
    fine = Fine(np.zeros(4 * m * m), np.ones(4 * m * m), 0.2)
    piece = Piece(rgb, np.ones(m * m), np.ones(3), np.zeros((1, 3)), np.zeros((4, 2)), 0.5, fine=fine)
    cells = rng.uniform(0.0, 1.0, (4 * m * m, 3))
    piece.u_fine[:] = cells
    fine.gray[:] = _gray(cells)
    crop = {"cx": 50.0, "cy": 50.0, "r": 50.0}
    face, frame = estimate(piece, (30, 30, 40, 40), crop=crop, frame="square")
    assert np.isclose(face, 1.0) and np.isclose(frame, 1.0)
    fine.gray[:] = 1.0 - fine.gray                                                    # a negative: far from one
    face, frame = estimate(piece, (30, 30, 40, 40), crop=crop, frame="square")
    assert face < 0.5 and frame < 0.5


def test_face_takes_auto_on_or_off(tmp_path, astronaut):
    code, _, err = run("plan", small(astronaut, tmp_path), "-o", tmp_path / "c.json", *SMALL, "--face", "maybe")
    assert code == 2 and "maybe" in err


def test_face_raises_the_face_ssim_as_woven_on_a_small_astronaut(tmp_path, astronaut):
    """What --face is for: the plan as woven matches the picture better inside the face box (blurred SSIM,
    as ``stringbot score`` and benchmarks/bench_face.py measure it); here +0.055 at 600 lines, asked > +0.02."""
    from stringbot.planner.model.scoring import face_scores
    from stringbot.planner.picture.read import read_picture

    img = small(astronaut, tmp_path, 200)
    box = face_for_plan(img, face="on").to_record()["box"]
    s = {}
    for face in ("off", "on"):
        p = plan_picture(img, pins=80, size=101, lines=600, face=face)
        s[face] = face_scores(p, read_picture(img, size=256, crop=p.crop, gray="luminance").gray, box=box)
    assert s["on"]["ssim_face_blurred"] > s["off"]["ssim_face_blurred"] + 0.02


def test_an_auto_plan_with_a_face_polishes_the_frame_after(tmp_path, astronaut):
    """--face, --lines auto: after the face-weighted polish a second one, led by the frame's error."""
    from stringbot.planner.methods import residual

    img = small(astronaut, tmp_path, 160)
    p = plan_picture(img, pins=60, size=101, face="on")
    fp = p.stats["frame_polish"]
    assert fp["passes"] == residual.FACE_PASSES and fp["woven_rms"] < fp["woven_rms_before"]  # the frame's error, lower
    assert "frame_polish" not in plan_picture(img, pins=60, size=101, face="off").stats


def test_the_chooser_sees_half_the_face_weight_the_polish_sees_all(tmp_path, astronaut, monkeypatch):
    """--face, mono: the chooser's (and its stop's) weights carry CHOOSE_FACE of the face's extra weight,
    the polishes' all of it; without --face the chooser's weights are the plan's."""
    from stringbot.planner.methods import residual
    from stringbot.planner.picture.face import FACE_WEIGHT

    seen, canvas = [], residual.Canvas

    def spy(target, w, *a, **kw):
        seen.append(float(np.max(w)))
        return canvas(target, w, *a, **kw)

    monkeypatch.setattr(residual, "Canvas", spy)
    img = small(astronaut, tmp_path, 160)
    plan_picture(img, pins=60, size=101, lines=200, face="on")
    assert seen[-1] == pytest.approx(1.0 + residual.CHOOSE_FACE * FACE_WEIGHT, rel=1e-3)
    assert residual.CHOOSE_FACE < 1.0
    plan_picture(img, pins=60, size=101, lines=200, face="off")
    assert seen[-1] == pytest.approx(1.0)


def _drawn(cls, n=48, m=64, seed=5):
    """A woven canvas of class ``cls`` with random chords drawn on a random target, and its pins' space."""
    from stringbot.planner.model.chords import chord_space, frame_mask

    space = chord_space(n)
    rng = np.random.default_rng(seed)
    mask = frame_mask(m, "circle")
    t = np.where(mask, rng.random((m, m)), 0.0)
    w = np.where(mask, 1.0 + 2.0 * rng.random((m, m)), 0.0)
    canvas = cls(t, w, space.pin_xy, 1.2)
    seq = [int(p) for p in rng.integers(0, n, 120)]
    chords = [(a, b) for a, b in zip(seq[:-1], seq[1:]) if a != b]
    canvas.build(chords)
    return canvas, chords, rng


def test_a_guarded_canvas_does_not_try_a_change_its_guard_would_undo():
    """Guarded.helps: the lead's estimate must fall and the guard's must not rise (a change the guard would
    undo is not made and undone)."""
    from stringbot.planner.methods.eye import EyeError
    from stringbot.planner.methods.polish import Guarded
    from stringbot.planner.methods.woven import WovenCanvas

    lead, chords, rng = _drawn(WovenCanvas)
    guard = EyeError(lead.t.reshape(64, 64) * 0.0, np.ones((64, 64)), sigma=1.0)  # wants it white
    guard.reset(lead.D)
    both = Guarded(lead, guard)
    lead_only = said = 0
    for _ in range(60):
        out = [chords[int(rng.integers(len(chords)))]]
        inn = [tuple(int(p) for p in rng.choice(48, 2, replace=False))]
        cp, dD = lead._fine(out, inn, "none")
        rises = cp is not None and guard.change(cp, dD)[0] > 0.0
        if lead.helps(out, inn):
            lead_only += 1
            assert both.helps(out, inn) == (not rises)
            said += both.helps(out, inn)
        else:
            assert not both.helps(out, inn)
    assert lead_only > said  # the guard said no to some


def test_the_face_led_passes_keep_the_frame_error_from_rising(tmp_path, astronaut, monkeypatch):
    """--face: after the frame's polish, passes the face-weighted error leads and the frame's guards
    (FACE_LED_PASSES): they lower the face-weighted error, the frame's does not rise."""
    from stringbot.planner.methods import residual

    img = small(astronaut, tmp_path, 160)
    captured = {}
    real = residual.frame_polish

    def spy(target, w, frame_w, space, model, seq, **kw):
        captured.update(target=target, w=w, frame_w=frame_w, space=space, model=model, seq=list(seq), kw=kw)
        out = real(target, w, frame_w, space, model, seq, **kw)
        captured["out"] = out
        return out

    monkeypatch.setattr(residual, "frame_polish", spy)
    p = plan_picture(img, pins=60, size=101, face="on")
    assert residual.FACE_LED_PASSES > 0 and p.stats["frame_polish"]["face_led"]["passes"] == residual.FACE_LED_PASSES
    c = captured
    seq, stats = c["out"]
    assert stats["face_led"]["woven_rms"] <= stats["face_led"]["woven_rms_before"]

    def error(weights, s):
        cv = residual.woven_canvas(c["target"], weights, c["space"], c["model"])
        return cv.build(list(zip(s[:-1], s[1:])))

    # the frame's error of the plan after it, against the plan before the face-led passes: not higher
    before, _ = real(c["target"], c["w"], c["frame_w"], c["space"], c["model"], c["seq"],
                     **dict(c["kw"], face_passes=0))
    assert error(c["frame_w"], seq) <= error(c["frame_w"], before) * (1 + 1e-9)
    assert error(c["w"], seq) < error(c["w"], before)
