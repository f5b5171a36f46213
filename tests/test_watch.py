"""Watching a long job: wind's progress lines without a terminal, plan's progress, animate, the summary."""

import io
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from stringbot.cli.progress import LOG_EVERY_S, PlanProgress, WindProgress
from stringbot.planner.build import plan_picture
from stringbot.planner.plan_file import write_plan
from stringbot.planner.progress import reporting
from stringbot.winding import Progress
from test_cli_plan import one_error_line, run
from test_gcode_replay import make_plan, random_sequence


@pytest.fixture
def plan_file(tmp_path):
    path = tmp_path / "p.json"
    write_plan(make_plan(random_sequence(120, seed=3)), path)
    return path


@pytest.mark.realtime
def test_wind_without_a_terminal_prints_progress_lines(tmp_path):
    path = tmp_path / "three.json"
    write_plan(make_plan([0, 100, 200]), path)
    # the simulated machine at real speed: three pins take a few seconds of machine time
    code, out, err = run("wind", path, "--machine", "grbl-ring", "--yes", "--realtime", "--progress-every", "0.3")
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if ln.startswith("winding: ")]
    assert len(lines) >= 3, err
    assert any("step 1 of 3" in ln and "pin 0" in ln and "elapsed" in ln and "ETA" in ln for ln in lines), lines
    assert "\r" not in err, "a bar's carriage returns in a log"
    assert "wound 3 pins" in out


def test_without_a_terminal_the_default_is_a_line_every_30_s():
    p = WindProgress(stream=io.StringIO())
    assert not p.tty and p.every == LOG_EVERY_S == 30.0
    p(Progress(done=5, total=10, step=5, pin=17, elapsed_s=3.0, eta_s=3.0))
    p.tick()
    text = p.stream.getvalue().splitlines()
    assert text[-1].startswith("winding: step 5 of 10 (50.0 %), pin 17,") and "ETA 0:0" in text[-1]

    class Tty(io.StringIO):
        def isatty(self):
            return True
    assert WindProgress(stream=Tty()).every is None       # a terminal gets the bar


def test_the_planner_reports_its_stages_and_sampling_counts(tmp_path, monkeypatch):
    monkeypatch.setenv("STRINGBOT_CACHE", "off")
    y, x = np.mgrid[:80, :80]
    pic = tmp_path / "pic.png"
    Image.fromarray(np.where((x - 40) ** 2 + (y - 40) ** 2 < 400, 20, 230).astype(np.uint8)).save(pic)
    seen = []
    with reporting(lambda stage, done, total: seen.append((stage, done, total))):
        plan_picture(pic, pins=40, size=64, lines=450, method="fitness")
        plan_picture(pic, pins=40, size=64, lines=450)  # the default method: residual
    assert ("choosing threads", 399, 450) in seen and ("refining", None, None) in seen
    stages = [s for s, _, _ in seen]
    for want in ("reading the picture", "chords", "solving (detail)", "sampling (detail)", "solving (fill)",
                 "scoring (fill)"):
        assert want in stages, stages
    assert ("sampling", 400, 450) in seen
    shown = PlanProgress(after=0.0, every=1.0, stream=io.StringIO())
    shown("sampling (detail)")
    shown("sampling", 200, 450)
    shown.tick()
    assert shown.stream.getvalue().startswith("planning: sampling (detail) 200 of 450 lines, 0:00 elapsed")


def test_animate_writes_a_gif_growing_in_winding_order(tmp_path, plan_file):
    out = tmp_path / "w.gif"
    code, stdout, err = run("animate", plan_file, "-o", out, "--frames", "12", "--size", "120")
    assert code == 0, err
    im = Image.open(out)
    assert im.n_frames == 12 and im.size == (120, 120)
    ink = []
    for k in range(im.n_frames):
        im.seek(k)
        ink.append(float((255 - np.asarray(im.convert("L"), dtype=float)).sum()))
    assert all(b >= a * 0.98 for a, b in zip(ink, ink[1:])) and ink[-1] > 3 * ink[0]
    im.seek(0)
    first = np.asarray(im.convert("RGB"))
    red = (first[..., 0] > 150) & (first[..., 1] < 80)
    assert red.sum() > 20, "the newest thread is not shown in red"


def test_mp4_needs_the_ffmpeg_plugin_and_says_so(tmp_path, plan_file):
    out = tmp_path / "w.mp4"
    p = subprocess.run([sys.executable, "-c", "import sys; sys.modules['imageio_ffmpeg'] = None; "
                        "from stringbot.cli import main; main()", "animate", str(plan_file), "-o", str(out)],
                       capture_output=True, text=True, timeout=120)
    one_error_line(p.returncode, p.stderr, "pip install imageio-ffmpeg")
    assert not out.exists()


def test_mp4_when_the_plugin_is_there(tmp_path, plan_file):
    pytest.importorskip("imageio_ffmpeg")
    import imageio.v3 as iio
    out = tmp_path / "w.mp4"
    code, _, err = run("animate", plan_file, "-o", out, "--frames", "10", "--size", "64")
    assert code == 0, err
    assert iio.imread(out, plugin="FFMPEG", index=None).shape == (10, 64, 64, 3)


@pytest.mark.parametrize("args, words", [
    (["-o", "x.png"], "expected a file name ending in .gif or .mp4"),
    (["-o", "x.mp4", "--size", "101"], "even number"),
])
def test_bad_animate_input(tmp_path, plan_file, args, words):
    code, _, err = run("animate", plan_file, *args, cwd=tmp_path)
    one_error_line(code, err, words)


def test_the_summary_of_a_servo_bus_counts_commands(tmp_path):
    path = tmp_path / "d.json"
    write_plan(make_plan([0, 40, 80, 120]), path)
    code, out, err = run("wind", path, "--machine", "dynamixel-ring", "--yes")
    assert code == 0, err
    assert "wound 4 pins (steps 1-4 of 4)" in out and " commands sent" in out and "lines sent" not in out
    code, out, err = run("wind", path, "--machine", "grbl-ring", "--yes")
    assert code == 0, err
    assert " lines sent" in out


def test_after_a_power_cut_the_resume_summary_counts_the_step_it_finished(tmp_path, plan_file):
    import re

    from test_wind_pty import Simulator
    sim = Simulator(tmp_path, "grbl-ring", faults="power@300")
    try:
        code, _, err = run("wind", plan_file, "--machine", "grbl-ring", "--port", sim.pty, "--yes")
        assert code == 1, err
        stopped = int(re.search(r"step (\d+)\)", err).group(1))
        sim.wait_port()
        code, out, err = run("wind", plan_file, "--machine", "grbl-ring", "--port", sim.pty, "--yes", "--resume",
                             "--head-side", "in")
        assert code == 0, err
        m = re.search(r"wound (\d+) pins \(steps (\d+)-(\d+) of 120\)", out)
        assert m, out
        wound, first, last = (int(g) for g in m.groups())
        assert first == stopped and last == 120 and wound == last - first + 1
        pins, collisions = sim.wraps()
        assert pins == make_plan(random_sequence(120, seed=3)).sequence and not collisions
    finally:
        sim.stop()
