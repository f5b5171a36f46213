"""`stringbot plan`, `render` and `score` through the real entry point (a subprocess).

Bad input must give exit 2, one line on stderr naming the problem, no
traceback, and leave every file already on disk as it was.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from stringbot.planner import read_plan

SMALL = ["--pins", "60", "--size", "101"]
#: A plan file stringbot wrote, as far as `plan -o` can tell (only such a file is replaced)
OLD_PLAN = '{"format": "stringbot-plan", "note": "an old plan"}'


def run(*args, cwd=None, env=None):
    e = dict(os.environ)
    e.update(env or {})
    p = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", *map(str, args)],
                       capture_output=True, text=True, cwd=cwd, env=e, timeout=120)
    return p.returncode, p.stdout, p.stderr


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("STRINGBOT_CACHE", str(tmp_path / "cache"))


@pytest.fixture
def picture(tmp_path):
    y, x = np.mgrid[:120, :120]
    g = np.where((x - 60) ** 2 + (y - 50) ** 2 < 30 ** 2, 30, 220).astype(np.uint8)
    path = tmp_path / "pic.png"
    Image.fromarray(g).save(path)
    return path


def one_error_line(code, err, words):
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("stringbot: error:") and "Traceback" not in err
    assert words in lines[0], lines[0]


def test_plan_writes_plan_and_preview_and_prints_a_summary(tmp_path, picture):
    out = tmp_path / "p.json"
    code, stdout, err = run("plan", picture, "-o", out, *SMALL, "--lines", "80", "--start-pin", "5", "--method",
                            "fitness")
    assert code == 0, err
    plan = read_plan(out)
    assert plan.pins == 60 and plan.sequence[0] == 5 and len(plan.sequence) == 81
    assert plan.method == "fitness" and plan.connected
    assert plan.source["path"] == str(picture) and plan.source["width"] == 120
    for key in ("pins", "frame", "crop", "start_pin", "size", "lines", "alpha", "beta", "gamma", "T",
                "epsilon", "iterations", "gray", "importance", "disconnected", "style", "style_requested"):
        assert key in plan.parameters, key
    assert {"lines", "thread_diameters", "seconds", "styles"} <= set(plan.stats)
    preview = Image.open(tmp_path / "p.png")
    assert preview.size == (1001, 1001)
    line = stdout.strip()
    assert "\n" not in line
    metres = plan.stats["thread_diameters"] * plan.diameter_mm / 1000   # the issue: metres, not diameters
    for part in (f"fitness ({plan.parameters['style']}):", "60 pins", "80 lines", f"thread {metres:.1f} m", " s "):
        assert part in line, line


@pytest.mark.parametrize("size", ["101", "251"])
def test_auto_records_the_scores_that_score_gives(tmp_path, picture, size):
    out = tmp_path / "p.json"
    code, _, err = run("plan", picture, "-o", out, "--pins", "60", "--size", size, "--lines", "120", "--method",
                       "fitness")
    assert code == 0, err
    plan = read_plan(out)
    kept = plan.stats["styles"][plan.parameters["style"]]
    code, stdout, err = run("score", out, "--json")
    assert code == 0, err
    got = json.loads(stdout)
    assert got["ssim"] == pytest.approx(kept["ssim"], abs=2e-4)
    assert got["ssim_blurred"] == pytest.approx(kept["ssim_blurred"], abs=2e-4)


def test_greedy_square_crop_and_preview_path(tmp_path, picture):
    out, prev = tmp_path / "g.json", tmp_path / "view.png"
    code, stdout, err = run("plan", picture, "-o", out, "--preview", prev, "--method", "greedy", "--frame",
                            "square", "--crop", "60,50,40", "--lines", "50", *SMALL)
    assert code == 0, err
    plan = read_plan(out)
    assert plan.method == "greedy" and plan.frame == "square"
    assert plan.crop == {"cx": 60.0, "cy": 50.0, "r": 40.0}
    assert prev.is_file() and not (tmp_path / "g.png").exists()
    assert stdout.startswith("greedy: 60 pins")


def test_disconnected_plan_renders_and_scores(tmp_path, picture):
    out = tmp_path / "d.json"
    code, _, err = run("plan", picture, "-o", out, "--disconnected", "--lines", "60", *SMALL, "--method", "fitness")
    assert code == 0, err
    doc = json.loads(out.read_text())
    assert doc["connected"] is False and len(doc["chords"]) == 60 and doc["sequence"] == []
    code, stdout, err = run("render", out, "-o", tmp_path / "r.png", "--size", "301")
    assert code == 0, err
    assert Image.open(tmp_path / "r.png").size == (301, 301)
    code, stdout, err = run("score", out, "--json")
    assert code == 0, err
    s = json.loads(stdout)
    assert s["connected"] is False and 0 < s["ssim"] < 1 and 0 < s["ssim_blurred"] < 1


def test_score_table_and_json_agree(tmp_path, picture):
    out = tmp_path / "p.json"
    assert run("plan", picture, "-o", out, "--lines", "60", *SMALL)[0] == 0
    code, table, _ = run("score", out, picture)
    assert code == 0
    code, js, _ = run("score", out, "--json")
    s = json.loads(js)
    for key in ("ssim", "ssim_blurred", "ssim_uniform", "ssim_uniform_blurred", "woven_error"):
        assert f"{s[key]:.4f}" in table, key
    assert 0 < s["woven_error"] < 1
    # a drawing of the picture scores better than the same drawing against its negative
    neg = tmp_path / "neg.png"
    Image.fromarray(255 - np.asarray(Image.open(picture))).save(neg)
    worse = json.loads(run("score", out, neg, "--json")[1])
    assert worse["ssim_blurred"] < s["ssim_blurred"]
    assert worse["woven_error"] > s["woven_error"]


def test_score_is_against_luminance_and_the_plans_own_gray_on_a_second_line(tmp_path):
    # a blue disc on yellow: luminance sees a dark disc on light (0.07 B against 0.93 R + G); a decolorization
    # that weighs blue most sees it the other way round
    y, x = np.mgrid[:120, :120]
    disc = (x - 60) ** 2 + (y - 50) ** 2 < 30 ** 2
    rgb = np.where(disc[..., None], [20, 20, 230], [240, 230, 40]).astype(np.uint8)
    img = tmp_path / "blue.png"
    Image.fromarray(rgb).save(img)
    out = tmp_path / "p.json"
    assert run("plan", img, "-o", out, *SMALL, "--lines", "80", "--gray", "luminance")[0] == 0
    doc = json.loads(out.read_text())
    doc["parameters"]["gray_requested"], doc["parameters"]["gray_weights"] = "decolor", [0.1, 0.1, 0.8]
    out.write_text(json.dumps(doc))  # as if planned against a blue-heavy decolorization
    code, js, err = run("score", out, "--json")
    assert code == 0, err
    s = json.loads(js)
    assert s["target"] == "luminance" and s["own_gray"]["weights"] == [0.1, 0.1, 0.8]
    # threads on the disc: right against luminance, wrong against the blue-heavy gray (the disc light there)
    assert s["woven_error"] < s["own_gray"]["woven_error"]
    assert s["ssim_blurred"] > s["own_gray"]["ssim_blurred"]
    code, table, _ = run("score", out)
    own = [ln for ln in table.splitlines() if ln.startswith("own gray")]
    assert len(own) == 1 and f"woven {s['own_gray']['woven_error']:.4f}" in own[0] and "0.100, 0.100, 0.800" in own[0]
    assert f"{s['woven_error']:.4f}" in table.splitlines()[6] and "luminance" in table


def test_machine_gives_the_pin_count(tmp_path, picture):
    from firmware_protocol.machine import load_machine

    ring = load_machine("grbl-ring").pins
    out = tmp_path / "m.json"
    code, _, err = run("plan", picture, "-o", out, "--machine", "grbl-ring", "--size", "201", "--lines", "30")
    assert code == 0, err
    assert read_plan(out).pins == ring
    code, _, err = run("plan", picture, "-o", out, "--machine", "grbl-ring", "--pins", str(ring + 1))
    one_error_line(code, err, "differs from machine")


def test_machine_summary_has_the_machine_time_estimate(tmp_path, picture):
    from firmware_protocol.machine import load_machine

    from stringbot.motion import estimate, format_duration

    out = tmp_path / "m.json"
    code, stdout, err = run("plan", picture, "-o", out, "--machine", "grbl-ring", "--size", "151", "--lines", "40")
    assert code == 0, err
    est = estimate(read_plan(out), load_machine("grbl-ring"))
    assert est.seconds > 0 and est.thread_m > 0
    lines = stdout.strip().splitlines()
    assert len(lines) == 2, stdout
    assert "grbl-ring" in lines[1] and format_duration(est.seconds) in lines[1], stdout
    assert f"{est.thread_m:.1f} m of thread" in lines[1], stdout
    # without --machine: the one summary line, no estimate
    code, stdout, err = run("plan", picture, "-o", out, "--pins", "60", "--size", "101", "--lines", "40")
    assert code == 0 and len(stdout.strip().splitlines()) == 1 and "winding" not in stdout, stdout
    # a chord set cannot be wound: said so, no estimate
    code, stdout, err = run("plan", picture, "-o", out, "--machine", "grbl-ring", "--size", "151", "--lines", "40",
                            "--disconnected", "--method", "fitness")
    assert code == 0, err
    assert "cannot be wound" in stdout and "of winding" not in stdout, stdout


# ---- bad input: one line, exit 2, nothing overwritten ------------------------------------------

def bad_pictures(tmp_path):
    """name -> path of a picture that cannot be planned."""
    out = {}
    (tmp_path / "empty.png").write_bytes(b"")
    out["empty file"] = tmp_path / "empty.png"
    (tmp_path / "text.png").write_text("not an image")
    out["not a picture"] = tmp_path / "text.png"
    Image.new("L", (1, 1)).save(tmp_path / "one.png")
    out["1 x 1"] = tmp_path / "one.png"
    Image.new("RGB", (200, 200), (10, 200, 30)).save(tmp_path / "full.jpg", quality=90)
    data = (tmp_path / "full.jpg").read_bytes()
    (tmp_path / "cut.jpg").write_bytes(data[: len(data) // 3])
    out["truncated"] = tmp_path / "cut.jpg"
    out["is a folder"] = tmp_path
    out["does not exist"] = tmp_path / "missing.png"
    return out


@pytest.mark.parametrize("which", ["empty file", "not a picture", "1 x 1", "truncated", "is a folder",
                                   "does not exist"])
def test_bad_pictures(tmp_path, which):
    path = bad_pictures(tmp_path)[which]
    out = tmp_path / "old.json"
    out.write_text(OLD_PLAN)
    code, _, err = run("plan", path, "-o", out, *SMALL)
    one_error_line(code, err, {"truncated": "runcated"}.get(which, which))
    assert out.read_text() == OLD_PLAN


@pytest.mark.parametrize("args, words", [
    (["--pins", "2", "--size", "101"], "--pins 2"),
    (["--pins", "100000"], "--pins 100000"),
    (["--lines", "0"], "--lines 0"),
    (["--lines", "-4"], "--lines -4"),
    (["--lines", "many"], "'many'"),
    (["--size", "3"], "--size 3"),
    (["--crop", "1,2"], "--crop"),
    (["--crop", "900,900,10"], "outside"),
    (["--start-pin", "400"], "--start-pin"),
    (["-T", "0"], "-T/--sharpness 0"),
    (["--method", "greedy", "--disconnected"], "--disconnected"),
    (["--style", "fill", "-T", "5"], "--style fill sets beta, gamma and T itself"),
    (["--style", "crisp"], "--style"),
    (["--method", "greedy", "--beta", "2"], "knobs of --method fitness"),
    (["--method", "greedy", "--style", "auto"], "knobs of --method fitness"),
    (["--thread-mm", "0"], "--thread-mm 0; expected millimetres"),
    (["--diameter-mm", "-1"], "--diameter-mm -1; expected millimetres"),
    (["--diameter-mm", "nan"], "--diameter-mm nan"),
    (["--diameter-mm", "10", "--thread-mm", "1"], "more than a 20th"),
    (["--machine", "grbl-ring", "--thread-mm", "0.4"], "differs from machine 'grbl-ring'"),
])
def test_bad_options(tmp_path, picture, args, words):
    out = tmp_path / "p.json"
    out.write_text(OLD_PLAN)
    code, _, err = run("plan", picture, "-o", out, *args)
    one_error_line(code, err, words)
    assert out.read_text() == OLD_PLAN


def test_bad_outputs(tmp_path, picture):
    code, _, err = run("plan", picture, "-o", tmp_path / "nope" / "p.json", *SMALL)
    one_error_line(code, err, "does not exist")
    code, _, err = run("plan", picture, "-o", tmp_path, *SMALL)
    one_error_line(code, err, "is a folder")
    (tmp_path / "keep.json").write_text(OLD_PLAN)
    code, _, err = run("plan", picture, "-o", tmp_path / "keep.json", "--preview", tmp_path / "no" / "x.png", *SMALL)
    one_error_line(code, err, "does not exist")
    assert (tmp_path / "keep.json").read_text() == OLD_PLAN
    before = picture.read_bytes()
    code, _, err = run("plan", picture, "-o", tmp_path / "p.json", "--preview", picture, *SMALL)
    one_error_line(code, err, "is the picture itself")
    assert picture.read_bytes() == before


def test_no_output_may_be_an_input(tmp_path, picture):
    plan = tmp_path / "p.json"
    code, _, err = run("plan", picture, "-o", plan, *SMALL, "--lines", "20")
    assert code == 0, err
    kept = plan.read_bytes()
    (tmp_path / "alias.json").symlink_to(plan)
    for out in (plan, tmp_path / "alias.json", tmp_path / "." / "p.json"):
        code, _, err = run("render", plan, "-o", out)
        one_error_line(code, err, "is the plan itself")
        assert plan.read_bytes() == kept and read_plan(plan).pins == 60
    code, _, err = run("gcode", plan, "--machine", "grbl-ring", "-o", tmp_path / "alias.json")
    one_error_line(code, err, "is the plan itself")
    assert plan.read_bytes() == kept
    before = picture.read_bytes()
    code, _, err = run("plan", picture, "-o", picture, "--preview", tmp_path / "x.png", *SMALL)
    one_error_line(code, err, "is the picture itself")
    assert picture.read_bytes() == before
    code, _, err = run("plan", picture, "-o", plan, "--preview", tmp_path / "." / "p.json", *SMALL)
    one_error_line(code, err, "is the plan itself")
    assert plan.read_bytes() == kept
    new = tmp_path / "new.json"                     # neither exists yet: compared by resolved path
    code, _, err = run("plan", picture, "-o", new, "--preview", tmp_path / "." / "new.json", *SMALL)
    one_error_line(code, err, "is the plan itself")
    assert not new.exists()


def test_mask_of_another_size(tmp_path, picture):
    Image.new("L", (50, 50), 255).save(tmp_path / "mask.png")
    code, _, err = run("plan", picture, "-o", tmp_path / "p.json", "--importance", tmp_path / "mask.png", *SMALL)
    one_error_line(code, err, "expected the picture's size 120 x 120")
    assert not (tmp_path / "p.json").exists()


@pytest.mark.parametrize("content, words", [
    ("{not json", "is not JSON"),
    ('{"format": "stringbot-plan", "version": 1}', "missing field"),
    ("[1, 2]", "expected a JSON object"),
])
def test_render_and_score_refuse_broken_plans(tmp_path, content, words):
    plan = tmp_path / "bad.json"
    plan.write_text(content)
    (tmp_path / "out.png").write_bytes(b"old")
    code, _, err = run("render", plan, "-o", tmp_path / "out.png")
    one_error_line(code, err, words)
    assert (tmp_path / "out.png").read_bytes() == b"old"
    code, _, err = run("score", plan)
    one_error_line(code, err, words)


def test_lazy_imports_keep_startup_light():
    code = ("import sys; import stringbot.cli; heavy = [m for m in ('numpy', 'scipy', 'PIL', 'skimage') "
            "if m in sys.modules]; print(','.join(heavy))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and p.stdout.strip() == "", p.stdout + p.stderr


def test_score_finds_a_relative_source_and_warns_when_it_changed(tmp_path, picture):
    work = tmp_path / "work"
    work.mkdir()
    Image.open(picture).save(work / "art.png")
    code, _, err = run("plan", "art.png", "-o", "p.json", "--lines", "40", *SMALL, cwd=work)
    assert code == 0, err
    assert sorted(p.name for p in work.iterdir()) == ["art.png", "p.json", "p.png"]  # no temp files left
    code, out, err = run("score", work / "p.json", "--json", cwd=tmp_path)  # source found beside the plan
    assert code == 0, err
    first = json.loads(out)
    assert err.strip() == ""
    Image.fromarray(255 - np.asarray(Image.open(work / "art.png"))).save(work / "art.png")
    code, out, err = run("score", work / "p.json", "--json", cwd=tmp_path)
    assert code == 0 and "sha256 differs" in err, (out, err)
    assert json.loads(out)["ssim"] != first["ssim"]


def test_plan_records_the_thread_and_renders_as_woven_by_default(tmp_path, picture):
    out = tmp_path / "p.json"
    code, _, err = run("plan", picture, "-o", out, *SMALL, "--lines", "60", "--diameter-mm", "300",
                       "--thread-mm", "0.6")
    assert code == 0, err
    doc = json.loads(out.read_text())
    assert doc["version"] == 1 and doc["diameter_mm"] == 300.0 and doc["thread_mm"] == 0.6
    code, stdout, err = run("render", out, "-o", tmp_path / "w.png", "--size", "301")
    assert code == 0 and "as woven (0.6 mm thread on 300 mm)" in stdout, err
    code, stdout, err = run("render", out, "-o", tmp_path / "b.png", "--size", "301", "--binary")
    assert code == 0 and "1-pixel lines" in stdout, err
    woven = np.asarray(Image.open(tmp_path / "w.png"), dtype=float)
    binary = np.asarray(Image.open(tmp_path / "b.png"), dtype=float)
    # the binary drawing is only black and white; as woven, a 0.6 mm thread on 300 mm is 0.6 px
    # at 301 px: gray, anti-aliased, and lighter overall than 1-pixel lines
    assert set(np.unique(binary)) <= {0.0, 255.0}
    assert len(np.unique(woven)) > 20 and woven.mean() > binary.mean()
    # the preview is the woven drawing at 1001 px (2 px wide threads there, 4 x 4 samples a pixel at least)
    preview = np.asarray(Image.open(tmp_path / "p.png"))
    assert preview.shape == (1001, 1001) and len(np.unique(preview)) > 10


def test_old_plans_without_thread_fields_still_read(tmp_path, picture):
    out = tmp_path / "p.json"
    assert run("plan", picture, "-o", out, *SMALL, "--lines", "30")[0] == 0
    doc = json.loads(out.read_text())
    del doc["diameter_mm"], doc["thread_mm"]
    out.write_text(json.dumps(doc))
    plan = read_plan(out)
    assert (plan.diameter_mm, plan.thread_mm) == (None, None)  # not recorded: drawn with 500 / 0.25
    assert (plan.thread_model().diameter_mm, plan.thread_model().thread_mm) == (500.0, 0.25)
    code, _, err = run("render", out, "-o", tmp_path / "r.png", "--size", "101")
    assert code == 0, err
    doc["thread_mm"] = 0
    out.write_text(json.dumps(doc))
    code, _, err = run("render", out, "-o", tmp_path / "r.png")
    one_error_line(code, err, "field 'thread_mm' is 0")


def test_machine_gives_the_ring_and_the_thread(tmp_path, picture):
    out = tmp_path / "p.json"
    code, _, err = run("plan", picture, "-o", out, "--machine", "grbl-ring", "--size", "151", "--lines", "40")
    assert code == 0, err
    plan = read_plan(out)
    assert (plan.pins, plan.diameter_mm, plan.thread_mm) == (300, 500.0, 0.25)


def test_the_recorded_frame_size_reaches_the_makers_commands(tmp_path, picture):
    out = tmp_path / "p.json"
    assert run("plan", picture, "-o", out, *SMALL, "--lines", "30", "--diameter-mm", "400")[0] == 0
    code, stdout, err = run("pins", out, "-o", tmp_path / "pins.txt")
    assert code == 0, err
    assert "400 mm ring diameter, from the plan" in stdout, stdout


def test_score_help_names_the_sizes_it_scores_at():
    from stringbot.planner.colour.render import SCORE_SIZE
    code, out, _ = run("score", "--help")
    text = " ".join(out.split())
    assert code == 0
    assert f"CIEDE2000 between the picture and the plan as woven (both at {SCORE_SIZE} px," in text
