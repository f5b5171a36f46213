"""Outputs replace only what stringbot wrote; pictures it cannot plan well are refused or warned about.

Issue 24, items 5 and 6, through the real entry point (a subprocess) in a scratch folder: each refusal
is exit 2, one line on stderr, no traceback, and every file already on disk byte-for-byte unchanged.
"""

import hashlib
import json
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from stringbot.planner import read_plan
from test_cli_plan import SMALL, one_error_line, picture, private_cache, run  # noqa: F401  (fixtures)

QUICK = [*SMALL, "--lines", "40"]


def snapshot(folder):
    """Every file under ``folder`` (not following symlinks): name -> sha256."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


def refused(folder, args, words):
    """Run ``stringbot ARGS`` in ``folder``: exit 2, one line naming ``words``, nothing on disk changed."""
    before = snapshot(folder)
    code, _, err = run(*args, cwd=folder)
    one_error_line(code, err, words)
    assert snapshot(folder) == before
    return err


def software(path):
    im = Image.open(path)
    im.load()
    return im.text.get("Software", "")


@pytest.fixture
def folder(tmp_path, picture):  # noqa: F811
    """A scratch folder with the test picture (pic.png), a plan of it (p.json, preview p.png) and a photo."""
    assert run("plan", "pic.png", "-o", "p.json", *QUICK, cwd=tmp_path)[0] == 0
    Image.fromarray(np.random.default_rng(1).integers(0, 255, (60, 80, 3), dtype=np.uint8)).save(
        tmp_path / "photo.jpg")
    return tmp_path


# ---- item 5: what plan -o, --preview and render -o may replace ------------------------------


def test_the_default_preview_path_holding_a_picture_is_refused_with_the_preview_hint(folder):
    Image.new("RGB", (50, 40), (200, 10, 10)).save(folder / "rk.png")     # the user's own picture
    err = refused(folder, ["plan", "photo.jpg", "-o", "rk.json", *QUICK], "--preview OTHER.png")
    assert "'rk.png'" in err and "a PNG picture" in err
    assert not (folder / "rk.json").exists()
    code, _, err = run("plan", "photo.jpg", "-o", "rk.json", "--preview", "rk-preview.png", *QUICK, cwd=folder)
    assert code == 0, err                                          # the hint works


def test_render_never_draws_over_the_plans_source_picture(folder):
    refused(folder, ["render", "p.json", "-o", "pic.png"], "is the plan's source picture")
    (folder / "sub").mkdir()
    (folder / "sub" / "copy.png").write_bytes((folder / "pic.png").read_bytes())   # moved, same content
    refused(folder, ["render", "p.json", "-o", "sub/copy.png"], "is the plan's source picture")


@pytest.mark.parametrize("args, option", [
    (["render", "p.json", "-o", "photo.jpg"], "-o 'photo.jpg'"),
    (["render", "p.json", "-o", "new.jpg"], "-o 'new.jpg'"),
    (["plan", "pic.png", "-o", "q.json", "--preview", "photo.jpg", *QUICK], "--preview 'photo.jpg'"),
    (["plan", "pic.png", "-o", "q.json", "--preview", "q.webp", *QUICK], "--preview 'q.webp'"),
])
def test_png_outputs_need_a_png_name(folder, args, option):
    err = refused(folder, args, option)
    assert "expected a file name ending in .png" in err
    assert not (folder / "q.json").exists() and not (folder / "new.jpg").exists()


def test_plan_never_replaces_a_journal_with_steps_done(folder):
    assert run("plan", "pic.png", "-o", "ring.json", "--machine", "grbl-ring", "--size", "151", "--lines", "20",
               cwd=folder)[0] == 0
    code, _, err = run("wind", "ring.json", "--machine", "grbl-ring", "--yes", cwd=folder)   # a dry run
    assert code == 0, err
    journal = "ring.json.dry-run.journal"
    lines = (folder / journal).read_text().splitlines()
    assert sum(json.loads(x)["kind"] == "done" for x in lines) == 21                    # steps done
    refused(folder, ["plan", "pic.png", "-o", journal, *QUICK], "is a winding journal, not a plan stringbot wrote")
    refused(folder, ["render", "ring.json", "-o", journal], "expected a file name ending in .png")


def test_plan_never_replaces_gcode_not_even_its_own(folder):
    assert run("plan", "pic.png", "-o", "ring.json", "--machine", "grbl-ring", "--size", "151", "--lines", "20",
               cwd=folder)[0] == 0
    assert run("gcode", "ring.json", "--machine", "grbl-ring", "-o", "keep.gcode", cwd=folder)[0] == 0
    refused(folder, ["plan", "pic.png", "-o", "keep.gcode", *QUICK], "is G-code stringbot wrote, not a plan")
    (folder / "mine.gcode").write_text("G1 X10 ; my own\n")
    refused(folder, ["plan", "pic.png", "-o", "mine.gcode", *QUICK], "is not a plan stringbot wrote")
    refused(folder, ["gcode", "ring.json", "--machine", "grbl-ring", "-o", "mine.gcode"],
            "not G-code stringbot wrote")


@pytest.mark.parametrize("name, what", [("photo.jpg", "a JPEG picture"), ("pic.png", "is the picture itself"),
                                        ("notes.json", "a JSON file stringbot did not write")])
def test_plan_o_never_replaces_a_picture_or_a_foreign_file(folder, name, what):
    (folder / "notes.json").write_text('{"my": "notes"}')
    refused(folder, ["plan", "pic.png", "-o", name, "--preview", "x.png", *QUICK], what)


def test_render_never_replaces_a_picture_it_did_not_draw(folder):
    Image.new("L", (64, 64), 128).save(folder / "art.png")                  # square, but no plan named art
    refused(folder, ["render", "p.json", "-o", "art.png"], "a PNG picture, not a picture stringbot drew")


def test_previews_and_drawings_are_marked_and_replaced_again(folder):
    assert software(folder / "p.png").startswith("stringbot")
    assert run("render", "p.json", "-o", "big.png", "--size", "64", cwd=folder)[0] == 0
    assert software(folder / "big.png").startswith("stringbot")
    first = (folder / "big.png").read_bytes()
    code, _, err = run("render", "p.json", "-o", "big.png", "--size", "80", cwd=folder)
    assert code == 0, err
    assert (folder / "big.png").read_bytes() != first and Image.open(folder / "big.png").size == (80, 80)
    code, _, err = run("plan", "pic.png", "-o", "p.json", *SMALL, "--lines", "30", cwd=folder)   # re-plan
    assert code == 0, err
    assert len(read_plan(folder / "p.json").sequence) == 31
    code, _, err = run("render", "p.json", "-o", "p.png", "--size", "64", cwd=folder)   # over its own preview
    assert code == 0, err


def test_a_colour_preview_and_drawing_are_marked(folder):
    code, _, err = run("plan", "pic.png", "-o", "c.json", "--colors", "black,crimson", *QUICK, cwd=folder)
    assert code == 0, err
    assert software(folder / "c.png").startswith("stringbot")
    assert run("render", "c.json", "-o", "c-big.png", "--size", "64", cwd=folder)[0] == 0
    assert software(folder / "c-big.png").startswith("stringbot")
    refused(folder, ["render", "c.json", "-o", "photo.jpg"], "expected a file name ending in .png")


def test_an_old_unmarked_preview_beside_its_plan_is_replaced_but_not_a_look_alike(folder):
    Image.open(folder / "p.png").save(folder / "p.png")        # as stringbot wrote it before the marker
    assert software(folder / "p.png") == ""
    code, _, err = run("plan", "pic.png", "-o", "p.json", *QUICK, cwd=folder)
    assert code == 0, err                                       # re-planning over an old preview works
    Image.open(folder / "p.png").save(folder / "p.png")
    code, _, err = run("render", "p.json", "-o", "p.png", "--size", "64", cwd=folder)
    assert code == 0, err                                       # so does re-rendering over it
    # a square picture beside a plan made from it is that plan's source, not its preview: kept
    Image.fromarray(np.full((90, 90), 40, np.uint8)).save(folder / "sq.png")
    (folder / "sq.json").write_text(json.dumps({"format": "stringbot-plan", "source": {
        "sha256": hashlib.sha256((folder / "sq.png").read_bytes()).hexdigest()}}))
    refused(folder, ["plan", "pic.png", "-o", "sq.json", *QUICK], "--preview OTHER.png")
    # a picture that is not square is never a preview
    Image.new("L", (90, 60), 200).save(folder / "wide.png")
    (folder / "wide.json").write_text('{"format": "stringbot-plan"}')
    refused(folder, ["plan", "pic.png", "-o", "wide.json", *QUICK], "--preview OTHER.png")


def test_an_empty_file_holds_nothing_to_lose(folder):
    for name in ("e.json", "e.png", "r.png"):
        (folder / name).write_bytes(b"")
    assert run("plan", "pic.png", "-o", "e.json", *QUICK, cwd=folder)[0] == 0
    assert run("render", "p.json", "-o", "r.png", "--size", "32", cwd=folder)[0] == 0
    assert software(folder / "e.png").startswith("stringbot") and software(folder / "r.png").startswith("stringbot")


# ---- item 6: pictures the planner cannot paint in black on white ------------------------------


@pytest.mark.parametrize("gray, moon", [(0, 18), (12, 12)])   # mean gray in the frame 23, 22
def test_a_too_dark_picture_is_refused_like_a_blank_one_and_the_advice_plans_it(tmp_path, gray, moon):
    y, x = np.mgrid[:120, :120]
    g = np.where((x - 60) ** 2 + (y - 60) ** 2 < moon ** 2, 255, gray).astype(np.uint8)   # a moon at night
    Image.fromarray(g).save(tmp_path / "night.png")
    err = refused(tmp_path, ["plan", "night.png", "-o", "n.json"], "too dark to plan in black thread on white")
    assert "--colors white --background black" in err
    assert not (tmp_path / "n.json").exists() and not (tmp_path / "n.png").exists()
    for method in ("fitness", "greedy"):
        refused(tmp_path, ["plan", "night.png", "-o", "n.json", *SMALL, "--method", method], "too dark")
    code, _, err = run("plan", "night.png", "-o", "n.json", *SMALL, "--colors", "white", "--background", "black",
                       cwd=tmp_path)
    assert code == 0, err                                       # the advice: light thread on a dark board
    plan = read_plan(tmp_path / "n.json")
    assert plan.background == "#000000" and len(plan.sequence) > 10


def test_a_dark_but_plannable_picture_is_planned(tmp_path):
    g = np.full((120, 120), 40, np.uint8)
    Image.fromarray(g).save(tmp_path / "dusk.png")
    code, _, err = run("plan", "dusk.png", "-o", "d.json", *SMALL, "--lines", "50", cwd=tmp_path)
    assert code == 0, err
    assert "warning" not in err


def test_the_line_cap_is_reported(tmp_path, picture):  # noqa: F811
    """The cap is 60000 lines (a minute's planning): this process lowers it to 60."""
    code = "import stringbot.planner.methods.residual as r; r.MAX_AUTO = 60; from stringbot.cli import main; main()"
    p = subprocess.run([sys.executable, "-c", code, "plan", str(picture), "-o", "cap.json", *SMALL,
                        "--polish", "0"], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert p.returncode == 0, p.stderr
    lines = [x for x in p.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    assert lines[0].startswith("stringbot: warning: planning stopped at the cap of 60 lines"), lines[0]
    plan = read_plan(tmp_path / "cap.json")
    assert plan.stats["line_cap"] == 60 and len(plan.sequence) == 61
    p = subprocess.run([sys.executable, "-c", code.replace("60", "100000"), "plan", str(picture), "-o", "free.json",
                        *SMALL, "--polish", "0"], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert p.returncode == 0 and "warning" not in p.stderr, p.stderr        # the same run, uncapped
    assert "line_cap" not in read_plan(tmp_path / "free.json").stats


def test_a_crop_keeping_less_than_half_the_picture_names_fit(tmp_path):
    rng = np.random.default_rng(3)
    Image.fromarray(rng.integers(0, 255, (20, 2000), dtype=np.uint8)).save(tmp_path / "strip.png")
    Image.fromarray(rng.integers(0, 255, (60, 100), dtype=np.uint8)).save(tmp_path / "photo.png")  # 60 %
    code, _, err = run("plan", "strip.png", "-o", "s.json", *QUICK, "--polish", "0", cwd=tmp_path)
    assert code == 0, err
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("stringbot: warning:"), err
    assert "20 x 20 of its 2000 x 20 pixels (1 %)" in lines[0] and "--fit" in lines[0]
    for args in (["--fit"], ["--crop", "1000,10,10"]):                       # the user chose: no word
        code, _, err = run("plan", "strip.png", "-o", "s.json", *QUICK, *args, cwd=tmp_path)
        assert code == 0 and "warning" not in err, err
    code, _, err = run("plan", "photo.png", "-o", "p.json", *QUICK, cwd=tmp_path)
    assert code == 0 and "warning" not in err, err
    code, _, err = run("plan", "strip.png", "-o", "c.json", *QUICK, "--colors", "black", cwd=tmp_path)
    assert code == 0, err
    assert "(1 %)" in err and "--crop" in err and "--fit" not in err            # a colour plan has no --fit


def test_a_library_warning_reads_as_one_line_of_the_command(tmp_path, picture):
    """A planner's log warning is one plain line (``warning: ...``); with -v it says where it came from."""
    args = ("plan", picture, "-o", "g.json", "--method", "greedy", "--pins", "24", "--lines", "3000",
            "--size", "101")
    code, _, err = run(*args, cwd=tmp_path)
    assert code == 0, err
    warn = [x for x in err.splitlines() if "greedy stopped after" in x]
    assert len(warn) == 1 and warn[0].startswith("warning: greedy stopped after") and "stringbot.planner" not in err
    assert "darkens what is left" in warn[0] and "fewer --lines" in warn[0]     # why, without -v
    code, _, err = run("-v", *args, cwd=tmp_path)
    assert code == 0 and "WARNING stringbot.planner" in err, err
