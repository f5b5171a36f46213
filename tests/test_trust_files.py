"""Trust every file: outputs never replace what is not theirs, and a disk that refuses is one line.

Full and read-only disks are real: a tiny tmpfs mounted for the test (skipped where
mounting is not permitted).  A refused permission cannot be made for root, so that
case runs the command in a subprocess whose ``tempfile.mkstemp`` raises EACCES.
"""

import json
import os
import socket
import stat
import subprocess
import sys

import pytest

from stringbot.planner.model.chords import pin_positions
from stringbot.planner.plan_file import Plan, write_plan
from test_cli_plan import SMALL, one_error_line, picture, private_cache, run  # noqa: F401  (fixtures)
from test_gcode_replay import make_plan, random_sequence


@pytest.fixture
def plan_file(tmp_path):
    path = tmp_path / "p.json"
    write_plan(make_plan(random_sequence(30, seed=5)), path)
    return path


def mount_tmpfs(where, size, ro=False):
    where.mkdir(exist_ok=True)
    opts = f"size={size}" + (",ro" if ro else "")
    p = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(where)], capture_output=True, text=True)
    if p.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {p.stderr.strip()}")


@pytest.fixture
def tiny_fs(tmp_path):
    mounted = []

    def make(size="32k", ro=False, name="fs"):
        where = tmp_path / name
        mount_tmpfs(where, size, ro)
        mounted.append(where)
        return where
    yield make
    for where in mounted:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


def fill(folder):
    """Fill a file system to the last byte."""
    with open(folder / "filler", "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"\0" * 1024)
        except OSError:
            pass


# ---- symlinks, devices, FIFOs, sockets -----------------------------------------------------


def test_outputs_are_written_through_a_symlink_to_a_regular_file(tmp_path, picture, plan_file):  # noqa: F811
    real = tmp_path / "real"
    real.mkdir()
    links = {}
    for name in ("plan.json", "plan.png", "big.png", "job.gcode", "pins.txt", "rec.json", "j.journal"):
        (real / name).write_bytes(b"")
        (tmp_path / name).symlink_to(real / name)
        links[name] = tmp_path / name
    assert run("plan", picture, "-o", links["plan.json"], "--preview", links["plan.png"], *SMALL)[0] == 0
    assert run("render", plan_file, "-o", links["big.png"], "--size", "64")[0] == 0
    assert run("gcode", plan_file, "--machine", "grbl-ring", "-o", links["job.gcode"])[0] == 0
    assert run("pins", plan_file, "-o", links["pins.txt"])[0] == 0
    code, _, err = run("wind", plan_file, "--machine", "grbl-ring", "--yes", "--record", links["rec.json"],
                       "--journal", links["j.journal"])
    assert code == 0, err
    for name, link in links.items():
        assert link.is_symlink() and os.readlink(link) == str(real / name), name
        assert (real / name).stat().st_size > 0, name
    assert json.loads((real / "rec.json").read_text())["wraps"]


def special_files(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    sock_path = tmp_path / "sock"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    to_null = tmp_path / "to-null"
    to_null.symlink_to("/dev/null")
    return {"/dev/null": "a character device", str(fifo): "a FIFO", str(sock_path): "a socket",
            str(to_null): "a character device"}, sock


@pytest.mark.parametrize("command", ["plan", "preview", "render", "gcode", "pins", "template", "animate",
                                     "record", "journal", "simulate-record"])
def test_devices_fifos_sockets_and_links_to_them_are_refused(tmp_path, picture, plan_file, command):  # noqa: F811
    specials, sock = special_files(tmp_path)
    try:
        for path, kind in specials.items():
            args = {
                "plan": ["plan", picture, "-o", path, *SMALL],
                "preview": ["plan", picture, "-o", tmp_path / "x.json", "--preview", path, *SMALL],
                "render": ["render", plan_file, "-o", path],
                "gcode": ["gcode", plan_file, "--machine", "grbl-ring", "-o", path],
                "pins": ["pins", plan_file, "-o", path + ".txt" if False else path],
                "template": ["template", "--pins", "24", "--diameter-mm", "100", "-o", path],
                "animate": ["animate", plan_file, "-o", path],
                "record": ["wind", plan_file, "--machine", "grbl-ring", "--yes", "--record", path],
                "journal": ["wind", plan_file, "--machine", "grbl-ring", "--yes", "--journal", path],
                "simulate-record": ["simulate", "--pty", tmp_path / "pty", "--record", path],
            }[command]
            code, out, err = run(*args)
            if command in ("pins", "template", "animate") and not path.endswith((".txt", ".svg", ".gif")):
                # refused for its name before its kind: still one line, still untouched
                assert code == 2 and "Traceback" not in err, err
            else:
                one_error_line(code, err, kind)
            assert not os.path.exists(tmp_path / "x.json")
        assert stat.S_ISFIFO(os.stat(tmp_path / "fifo").st_mode)
        assert stat.S_ISSOCK(os.stat(tmp_path / "sock").st_mode)
        assert os.readlink(tmp_path / "to-null") == "/dev/null"
    finally:
        sock.close()


def test_a_fifo_named_like_an_output_is_refused_not_opened(tmp_path, plan_file):
    for name, args in (("pins.txt", ["pins", plan_file, "-o"]), ("t.svg", ["template", "--pins", "24",
                                                                          "--diameter-mm", "100", "-o"]),
                       ("w.gif", ["animate", plan_file, "-o"])):
        os.mkfifo(tmp_path / name)
        one_error_line(*run(*args, tmp_path / name)[::2], "a FIFO")


# ---- standard output -------------------------------------------------------------------------


def test_dash_is_standard_output_for_gcode_and_pins_and_refused_elsewhere(tmp_path, picture, plan_file):  # noqa: F811
    code, out, err = run("gcode", plan_file, "--machine", "grbl-ring", "-o", "-", cwd=tmp_path)
    assert code == 0, err
    assert out.startswith("; stringbot winding job") and "G4 P0" in out and "-> -" in err
    for args in (["plan", picture, "-o", "-", *SMALL], ["plan", picture, "-o", "x.json", "--preview", "-", *SMALL],
                 ["render", plan_file, "-o", "-"], ["wind", plan_file, "--machine", "grbl-ring", "--yes",
                                                    "--record", "-"],
                 ["wind", plan_file, "--machine", "grbl-ring", "--yes", "--journal", "-"]):
        code, _, err = run(*args, cwd=tmp_path)
        one_error_line(code, err, "'-'")
    assert not list(tmp_path.glob("-*")) and not (tmp_path / "x.json").exists()


# ---- full, read-only, refused ----------------------------------------------------------------


def test_a_full_disk_is_one_line_and_leaves_the_plan_and_preview_as_they_were(tmp_path, tiny_fs, picture):  # noqa: F811
    fs = tiny_fs("256k")
    plan, preview = fs / "p.json", fs / "p.png"
    assert run("plan", picture, "-o", plan, *SMALL, "--lines", "40")[0] == 0
    before = plan.read_bytes(), preview.read_bytes()
    fill(fs)
    code, _, err = run("plan", picture, "-o", plan, *SMALL, "--lines", "60")
    one_error_line(code, err, "the disk is full")
    assert str(fs) in err
    assert (plan.read_bytes(), preview.read_bytes()) == before
    assert sorted(p.name for p in fs.iterdir()) == ["filler", "p.json", "p.png"], "a temp file was left"


def test_both_or_neither_when_only_the_preview_does_not_fit(tmp_path, tiny_fs, picture):  # noqa: F811
    fs = tiny_fs("32k")          # the plan (a few kB) fits, the 1001 px preview does not
    code, _, err = run("plan", picture, "-o", fs / "p.json", *SMALL, "--lines", "200")
    one_error_line(code, err, "the disk is full")
    assert list(fs.iterdir()) == []


def test_a_read_only_folder_is_one_line(tmp_path, tiny_fs, picture, plan_file):  # noqa: F811
    fs = tiny_fs("1m", ro=True)
    for args in (["plan", picture, "-o", fs / "p.json", *SMALL], ["render", plan_file, "-o", fs / "r.png"],
                 ["gcode", plan_file, "--machine", "grbl-ring", "-o", fs / "j.gcode"],
                 ["pins", plan_file, "-o", fs / "p.txt"],
                 ["template", "--pins", "24", "--diameter-mm", "100", "-o", fs / "t.pdf"],
                 ["wind", plan_file, "--machine", "grbl-ring", "--yes", "--journal", fs / "j.journal"],
                 ["wind", plan_file, "--machine", "grbl-ring", "--yes", "--record", fs / "r.json"]):
        code, _, err = run(*args)
        one_error_line(code, err, "read-only")
        assert str(fs) in err


def test_a_refused_permission_is_one_line(tmp_path, plan_file):
    out = tmp_path / "job.gcode"
    patch = ("import errno, tempfile\n"
             "def refuse(*a, **k): raise PermissionError(errno.EACCES, 'Permission denied')\n"
             "tempfile.mkstemp = refuse\n"
             "from stringbot.cli import main; main()\n")
    p = subprocess.run([sys.executable, "-c", patch, "gcode", str(plan_file), "--machine", "grbl-ring",
                        "-o", str(out)], capture_output=True, text=True, timeout=120)
    one_error_line(p.returncode, p.stderr, "permission denied")
    assert str(out) in p.stderr and not out.exists()


def test_a_journal_that_fills_the_disk_mid_winding_stops_with_exit_1_and_resumes(tmp_path, tiny_fs):
    from test_wind_pty import Simulator
    fs = tiny_fs("8k")
    plan = tmp_path / "p.json"
    seq = random_sequence(150, seed=9)
    write_plan(make_plan(seq), plan)
    journal = fs / "p.journal"
    sim = Simulator(tmp_path, "grbl-ring")
    try:
        code, _, err = run("wind", plan, "--machine", "grbl-ring", "--port", sim.pty, "--yes", "--journal", journal)
        assert code == 1, err
        lines = [ln for ln in err.splitlines() if ln.startswith("stringbot:")]
        assert len(lines) == 1 and "Traceback" not in err
        assert str(journal) in lines[0] and "the disk is full" in lines[0] and "resume with:" in lines[0]
        subprocess.run(["mount", "-o", "remount,size=1m", str(fs)], check=True)
        code, out, err = run("wind", plan, "--machine", "grbl-ring", "--port", sim.pty, "--yes", "--resume",
                             "--journal", journal)
        assert code == 0, err
        pins, collisions = sim.wraps()
        assert pins == seq and not collisions
    finally:
        sim.stop()


# ---- files that are not ours -----------------------------------------------------------------


def test_gcode_replaces_only_gcode_that_stringbot_wrote(tmp_path, plan_file):
    mine = tmp_path / "mine.gcode"
    mine.write_text("G1 X10 ; my own program\n")
    one_error_line(*run("gcode", plan_file, "--machine", "grbl-ring", "-o", mine)[::2],
                   "not G-code stringbot wrote")
    assert mine.read_text() == "G1 X10 ; my own program\n"
    ours = tmp_path / "job.gcode"
    assert run("gcode", plan_file, "--machine", "grbl-ring", "-o", ours)[0] == 0
    assert run("gcode", plan_file, "--machine", "grbl-ring", "-o", ours)[0] == 0


def test_plan_over_a_plan_with_a_wound_journal_needs_force(tmp_path, picture):  # noqa: F811
    plan = tmp_path / "p.json"
    assert run("plan", picture, "-o", plan, "--machine", "grbl-ring", "--size", "151", "--lines", "20")[0] == 0
    from test_wind_pty import Simulator
    sim = Simulator(tmp_path, "grbl-ring")
    try:
        assert run("wind", plan, "--machine", "grbl-ring", "--port", sim.pty, "--yes")[0] == 0
    finally:
        sim.stop()
    before = plan.read_bytes()
    code, _, err = run("plan", picture, "-o", plan, "--machine", "grbl-ring", "--size", "151", "--lines", "30")
    one_error_line(code, err, "--force")
    assert "p.json.journal" in err and plan.read_bytes() == before
    code, _, err = run("plan", picture, "-o", plan, "--machine", "grbl-ring", "--size", "151", "--lines", "30",
                       "--force")
    assert code == 0, err
    assert plan.read_bytes() != before and (tmp_path / "p.json.journal").exists()


def test_square_frames_and_ring_machines_do_not_mix(tmp_path, picture):  # noqa: F811
    one_error_line(*run("plan", picture, "-o", tmp_path / "s.json", "--machine", "grbl-ring", "--frame", "square",
                        "--size", "101")[::2], "--frame square")
    sq = tmp_path / "sq.json"
    write_plan(Plan(pins=300, frame="square", pin_xy=pin_positions(300, "square"), crop={"cx": 1, "cy": 1, "r": 1},
                    sequence=[0, 50, 120], method="hand", source={}), sq)
    for args in (["wind", sq, "--machine", "grbl-ring", "--yes"], ["gcode", sq, "--machine", "grbl-ring", "-o",
                                                                  tmp_path / "s.gcode"],
                 ["estimate", sq, "--machine", "marlin-ring"]):
        one_error_line(*run(*args)[::2], "winds a ring")
    assert not (tmp_path / "s.gcode").exists()


def test_a_head_stroke_that_does_not_clear_the_pins_is_refused(tmp_path):
    text = subprocess.run([sys.executable, "-m", "stringbot.cli", "machines", "show", "grbl-ring"],
                          capture_output=True, text=True, check=True).stdout
    short = tmp_path / "short.toml"
    short.write_text(text.replace("out_mm = 12.0", "out_mm = 1.5"))
    code, _, err = run("machines", "show", short)
    one_error_line(code, err, "does not clear the pins")
    assert "1.75 mm" in err


def test_the_record_has_the_permissions_of_every_other_output(tmp_path, plan_file):
    rec, gcode = tmp_path / "rec.json", tmp_path / "job.gcode"
    old = os.umask(0o022)
    try:
        assert run("wind", plan_file, "--machine", "grbl-ring", "--yes", "--record", rec)[0] == 0
        assert run("gcode", plan_file, "--machine", "grbl-ring", "-o", gcode)[0] == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(rec.stat().st_mode) == stat.S_IMODE(gcode.stat().st_mode) == 0o644
    journal = plan_file.with_name(plan_file.name + ".dry-run.journal")
    assert stat.S_IMODE(journal.stat().st_mode) == 0o644


def test_gitignore_covers_the_venv_and_the_quick_starts_outputs():
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    if not (root / ".git").exists():
        pytest.skip("not a git checkout")
    names = [".venv/x", "camera.json", "camera.png", "camera-record.json", "camera.json.journal",
             "camera.json.dry-run.journal"]
    p = subprocess.run(["git", "check-ignore", *names], cwd=root, capture_output=True, text=True)
    assert sorted(p.stdout.split()) == sorted(names)
    p = subprocess.run(["git", "check-ignore", "examples/camera.png"], cwd=root, capture_output=True, text=True)
    assert p.stdout == ""
