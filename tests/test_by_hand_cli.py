"""`stringbot by-hand` through the real entry point: at a pseudo-terminal (keys), from a pipe (lines),
stopped and resumed; --speak with a stand-in espeak-ng and with the real one."""

import json
import os
import re
import shutil
import subprocess
import sys

import pytest

from stringbot.planner.plan_file import read_plan, write_plan
from pty_session import PtySession
from test_cli_plan import one_error_line, run
from test_colour_plan import colour_plan
from test_gcode_replay import make_plan, random_sequence

STEP = re.compile(r"step (\d+) of (\d+) \([\d.]+ %\): pin (\d+), wrap (cw|ccw|either)")


@pytest.fixture
def plan_path(tmp_path):
    path = tmp_path / "p.json"
    plan = make_plan(random_sequence(30, seed=11))
    plan.diameter_mm, plan.thread_mm = 500.0, 0.25
    write_plan(plan, path)
    return path


def feed(plan_path, text, *args, env=None):
    """`by-hand` with ``text`` on standard input (line mode)."""
    e = dict(os.environ, **(env or {}))
    p = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", "by-hand", str(plan_path),
                        *map(str, args)], input=text, capture_output=True, text=True, env=e, timeout=120)
    return p.returncode, p.stdout, p.stderr


def shown(text):
    """``[(step, pin), ...]`` of every step line shown."""
    return [(int(m[1]), int(m[3])) for m in STEP.finditer(text)]


def saved(plan_path):
    return json.loads((plan_path.parent / (plan_path.name + ".by-hand")).read_text())


def expect_step(s, plan, number):
    m = s.expect(STEP.pattern)
    assert int(m[1]) == number and int(m[2]) == len(plan.sequence), s.out
    assert int(m[3]) == plan.sequence[number - 1], s.out
    return m


def test_keys_at_a_terminal_step_back_repeat_quit_and_resume(plan_path):
    plan = read_plan(plan_path)
    s = PtySession("by-hand", plan_path)
    try:
        s.expect("keys: Space/Enter/n next")
        expect_step(s, plan, 1)
        for key, number in [("n", 2), (" ", 3), ("\r", 4), ("\x1b[C", 5), ("b", 4), ("\x7f", 3), ("r", 3),
                            ("n", 4)]:
            s.send(key)
            expect_step(s, plan, number)
        s.send("x")
        s.expect(r"key 'x' does nothing; \? shows the keys")
        s.send("g")
        s.expect(r"go to step \(1-30")
        s.send("17\r")
        expect_step(s, plan, 17)
        s.send("q")
        assert s.wait() == 0
    finally:
        s.close()
    assert "stopped at step 17 of 30" in s.out and f"stringbot by-hand {plan_path} resumes there" in s.out
    assert saved(plan_path)["done"] == 16 and saved(plan_path)["plan_sha256"] == plan.sha256()
    again = PtySession("by-hand", plan_path)
    try:
        again.expect(r"resumed at step 17 \(16 done\)")
        expect_step(again, plan, 17)
        again.send("n")
        expect_step(again, plan, 18)
        again.send("q")
        assert again.wait() == 0
    finally:
        again.close()
    assert saved(plan_path)["done"] == 17


def test_ctrl_c_keeps_the_position_and_says_how_to_resume(plan_path):
    plan = read_plan(plan_path)
    s = PtySession("by-hand", plan_path, "--from-step", 5)
    try:
        expect_step(s, plan, 5)
        s.send("n")
        expect_step(s, plan, 6)
        s.send("\x03")                                  # Ctrl-C typed at the terminal: SIGINT
        assert s.wait() == 130
    finally:
        s.close()
    assert "Traceback" not in s.out
    assert f"interrupted at step 6 of 30; the position is saved in {plan_path}.by-hand: resume with: " \
           f"stringbot by-hand {plan_path}" in s.out
    assert saved(plan_path)["done"] == 5


def test_the_last_step_finishes_and_a_finished_plan_says_so(plan_path):
    plan = read_plan(plan_path)
    s = PtySession("by-hand", plan_path, "--from-step", 29)
    try:
        expect_step(s, plan, 29)
        s.send("n")
        expect_step(s, plan, 30)
        s.send("n")
        assert s.wait() == 0
    finally:
        s.close()
    assert f"done: all 30 steps; tie the thread off at pin {plan.sequence[-1]}" in s.out
    assert saved(plan_path)["done"] == 30
    code, out, err = feed(plan_path, "")
    assert code == 0 and "all 30 steps of" in out and "--restart" in out and not shown(out)


def test_lines_from_a_pipe_and_the_end_of_input_keeps_the_position(plan_path):
    plan = read_plan(plan_path)
    code, out, err = feed(plan_path, "next\n\nn\nback\nrepeat\ngo 10\nnonsense\nnext\n")
    assert code == 0, err
    want = [1, 2, 3, 4, 3, 3, 10, 11]
    assert shown(out) == [(k, plan.sequence[k - 1]) for k in want]
    assert "'nonsense' is no command" in err and len(err.strip().splitlines()) == 1
    assert "stopped at step 11 of 30" in out and saved(plan_path)["done"] == 10
    code, out, err = feed(plan_path, "next\nquit\nnext\n")            # nothing read after quit
    assert code == 0 and shown(out) == [(11, plan.sequence[10]), (12, plan.sequence[11])]
    assert saved(plan_path)["done"] == 11
    code, out, _ = feed(plan_path, "", "--restart")
    assert shown(out) == [(1, plan.sequence[0])] and saved(plan_path)["done"] == 0


def test_a_position_for_another_plan_is_refused_in_one_line(plan_path):
    assert feed(plan_path, "go 12\n")[0] == 0
    write_plan(make_plan(random_sequence(30, seed=12)), plan_path)       # planned again, same name
    before = (plan_path.parent / "p.json.by-hand").read_text()
    code, out, err = feed(plan_path, "next\n")
    one_error_line(code, err, "is for another plan")
    assert "step 12 of 30" in err and "--restart" in err and not shown(out)
    assert (plan_path.parent / "p.json.by-hand").read_text() == before
    code, out, err = feed(plan_path, "", "--restart")
    assert code == 0 and saved(plan_path)["done"] == 0


@pytest.mark.parametrize("args, words", [(["--from-step", "0"], "--from-step 0; expected a step 1..30"),
                                         (["--from-step", "31"], "--from-step 31; expected a step 1..30"),
                                         (["--from-step", "x"], "--from-step"),
                                         (["--restart", "--from-step", "3"], "give one of them"),
                                         (["--voice", "en"], "--voice and --speed are for --speak"),
                                         (["--speak", "--speed", "5"], "--speed 5; expected 80..450")])
def test_bad_options_are_one_line_and_exit_2(plan_path, args, words):
    code, out, err = feed(plan_path, "next\n", *args)
    one_error_line(code, err, words)
    assert not (plan_path.parent / "p.json.by-hand").exists()


def test_the_position_never_replaces_a_journal_or_the_plan(plan_path, tmp_path):
    journal = tmp_path / "p.json.journal"
    journal.write_text('{"kind": "start", "format": "stringbot-journal", "version": 1}\n')
    before = plan_path.read_text()
    for target, words in [(journal, "is a winding journal"), (plan_path, "is the plan itself")]:
        code, _, err = feed(plan_path, "next\n", "--position", target)
        one_error_line(code, err, words)
    assert plan_path.read_text() == before and journal.read_text().startswith('{"kind": "start"')
    code, out, err = feed(plan_path, "next\n", "--position", tmp_path / "mine.pos")
    assert code == 0 and f"--position {tmp_path / 'mine.pos'} resumes there" in out
    assert json.loads((tmp_path / "mine.pos").read_text())["done"] == 1


def test_a_colour_plan_says_when_to_change_thread(tmp_path):
    plan = colour_plan(pins=300, n=(5, 4, 3))
    path = tmp_path / "c.json"
    write_plan(plan, path)
    a = plan.layer_starts[1]
    code, out, err = feed(path, "next\n" * 6, "--from-step", a - 1)
    assert code == 0, err
    lines = out.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith(">> cut the blue"))
    assert lines[k] == (f">> cut the blue (#1f5bb5) thread and tie it off at pin {plan.sequence[a - 1]}; tie the "
                        f"red (#c8102e) thread on at pin {plan.sequence[a]} (thread 2 of 3)")
    assert shown(lines[k + 1]) == [(a + 1, plan.sequence[a])] and "red: 4 step(s)" in lines[k + 1]
    assert ">> on thread 1 of 3: blue (#1f5bb5)" in out        # resumed inside a thread: which one is on
    assert "last of this thread" in lines[k - 1]


@pytest.fixture
def fake_espeak(tmp_path):
    """A folder holding an `espeak-ng` that notes its arguments (one line a call), then "speaks" for ten
    minutes unless cut short, noting that too."""
    folder = tmp_path / "bin"
    folder.mkdir()
    log = tmp_path / "said.txt"
    exe = folder / "espeak-ng"
    exe.write_text("#!/bin/sh\n"
                   f"trap 'echo cut >> {log}; exit 0' TERM\n"
                   f"printf '%s|' \"$@\" >> {log}\necho >> {log}\n"
                   "sleep 600 &\nwait\n")
    exe.chmod(0o755)
    return folder, log


def calls_in(log, n):
    """The first ``n`` lines of the stand-in's log, once there are that many (it runs on its own)."""
    import time
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        lines = log.read_text().splitlines() if log.exists() else []
        if len(lines) >= n:
            return lines[:n]
        time.sleep(0.05)
    raise AssertionError(f"espeak-ng was called {len(lines)} times, not {n}: {lines}")


def test_speak_says_each_pin_and_a_newer_step_cuts_the_last_short(plan_path, fake_espeak):
    folder, log = fake_espeak
    plan = read_plan(plan_path)
    s = PtySession("by-hand", plan_path, "--speak", "--speed", "150",
                   env={"PATH": f"{folder}{os.pathsep}{os.environ['PATH']}"})
    try:
        wrap = {"cw": "clockwise", "ccw": "counter-clockwise"}[expect_step(s, plan, 1)[4]]
        assert calls_in(log, 1)[0] == f"-s|150|Tie the thread on at pin {plan.sequence[0]}, {wrap}.|"
        n = 1
        for key, number in [("n", 2), ("n", 3), ("r", 3), ("b", 2)]:
            s.send(key)                       # shown while the last utterance still "speaks"
            expect_step(s, plan, number)
            n += 2                            # the one before cut short, then this one
            last = calls_in(log, n)[-2:]     # the two run side by side: either may write first
            assert "cut" in last
            said = [x for x in last if x != "cut"][0].rstrip("|").split("|")
            assert said[:2] == ["-s", "150"]
            assert said[2].startswith(("Back. " if key == "b" else "") + f"pin {plan.sequence[number - 1]}")
        s.send("q")
        assert s.wait() == 0
    finally:
        s.close()
    assert calls_in(log, n + 1)[-1] == "cut"  # quitting stops the voice too


def test_speak_without_espeak_says_so_once_and_goes_on(plan_path, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    env = {"PATH": str(empty)}
    code, out, err = feed(plan_path, "next\n", "--speak", env=env)
    assert code == 0
    assert err.strip() == ("--speak: espeak-ng is not installed (apt-get install espeak-ng, brew install "
                           "espeak-ng, or espeak-ng.org); continuing silently")
    assert [k for k, _ in shown(out)] == [1, 2]


@pytest.mark.skipif(shutil.which("espeak-ng") is None, reason="espeak-ng is not installed")
def test_the_real_espeak_takes_our_arguments(tmp_path, plan_path):
    from stringbot.cli.speech import speech_argv
    from stringbot.winding.by_hand import HandWinding
    hw = HandWinding(read_plan(plan_path), plan_path=str(plan_path), position_path=str(tmp_path / "x"))
    wav = tmp_path / "pin.wav"
    argv = speech_argv(shutil.which("espeak-ng"), hw.utterance(hw.steps[1]), voice="en-us", speed=160)
    subprocess.run(argv[:1] + ["-w", str(wav)] + argv[1:], check=True, timeout=60, capture_output=True)
    data = wav.read_bytes()
    assert data[:4] == b"RIFF" and data[8:12] == b"WAVE" and len(data) > 8000     # some speech, not a header
    code, _, err = feed(plan_path, "next\n", "--speak", "--voice", "zz")
    one_error_line(code, err, "--voice 'zz': espeak-ng has no such voice")


def test_help_names_the_keys():
    code, out, err = run("by-hand", "--help")
    assert code == 0 and "Backspace" in out and "--speak" in out and "--from-step" in out


def test_plan_does_not_orphan_a_position_with_steps_done(tmp_path):
    import numpy as np
    from PIL import Image
    y, x = np.mgrid[:120, :120]
    pic = tmp_path / "pic.png"
    Image.fromarray(np.where((x - 60) ** 2 + (y - 50) ** 2 < 900, 30, 220).astype(np.uint8)).save(pic)
    out = tmp_path / "p.json"
    small = ["--pins", "60", "--size", "101", "--lines", "30"]
    assert run("plan", pic, "-o", out, *small)[0] == 0
    assert feed(out, "quit\n")[0] == 0                  # a position at step 1: nothing done, no refusal
    assert run("plan", pic, "-o", out, *small)[0] == 0
    assert feed(out, "next\nnext\n", "--restart")[0] == 0
    before = out.read_text()
    code, _, err = run("plan", pic, "-o", out, *small)
    one_error_line(code, err, f"plan {str(out)!r} has a by-hand position {str(out) + '.by-hand'!r} (2 of 31 steps "
                              "done); overwriting the plan would orphan it: give another -o, or --force")
    assert out.read_text() == before
    assert run("plan", pic, "-o", out, *small, "--force")[0] == 0


def test_a_second_session_of_the_same_plan_is_refused_while_the_first_winds(plan_path):
    plan = read_plan(plan_path)
    s = PtySession("by-hand", plan_path)
    try:
        s.expect("keys: Space/Enter/n next")
        expect_step(s, plan, 1)
        s.send("n")
        expect_step(s, plan, 2)
        code, out, err = feed(plan_path, "next\nnext\nquit\n")
        one_error_line(code, err, f"another `stringbot by-hand` is winding {plan_path} now")
        assert saved(plan_path)["done"] == 1          # the first session's position, untouched
        s.send("q")
        assert s.wait() == 0
    finally:
        s.close()
    code, out, err = feed(plan_path, "next\nquit\n")   # once the first has quit, the plan is free again
    assert code == 0 and saved(plan_path)["done"] == 2
