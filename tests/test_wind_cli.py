"""``stringbot wind``: exit codes 0/1/2/130, one line on stderr, the record of a dry run."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from stringbot.cli import main
from stringbot.planner import write_plan

from test_wind_sim import small_plan


def run(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    out, err = capsys.readouterr()
    return info.value.code, out, err


@pytest.fixture
def plan_path(tmp_path):
    path = tmp_path / "plan.json"
    write_plan(small_plan(n=10, seed=7), path)
    return path


def error_lines(err):
    return [x for x in err.splitlines() if x.startswith("stringbot:")]


def test_dry_run_winds_the_plan_and_exits_0(tmp_path, plan_path, capsys):
    record = tmp_path / "rec.json"
    code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes",
                          "--record", str(record)], capsys)
    assert code == 0, err
    assert "wound 10 pins" in out and "pins/s" in out
    rec = json.loads(record.read_text())
    assert [w["pin"] for w in rec["wraps"]] == small_plan(n=10, seed=7).sequence
    assert rec["collisions"] == []


def test_status_shows_the_journal(tmp_path, plan_path, capsys):
    run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes"], capsys)
    code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--status"], capsys)
    assert code == 0
    assert "finished: all 10 steps done" in out


def test_machine_failure_exits_1_with_one_line_naming_pin_step_and_resume(tmp_path, plan_path, capsys):
    code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes",
                          "--faults", "error@20"], capsys)
    assert code == 1
    lines = error_lines(err)
    assert len(lines) == 1 and "Traceback" not in err
    assert "error:20" in lines[0] and "pin " in lines[0] and "step " in lines[0]
    # a dry run's simulated machine ends with the command: no resume hint that --resume refuses,
    # but the line still says what to do
    assert "--resume" not in lines[0] and "a dry run cannot be resumed: run it again" in lines[0]


def test_machine_failure_on_a_port_names_the_resume_command(tmp_path, plan_path, capsys):
    url = f"sim://?machine=grbl-ring&faults=error@20&record={tmp_path / 'rec.json'}"
    code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--port", url,
                          "--journal", str(tmp_path / "j")], capsys)
    assert code == 1
    lines = error_lines(err)
    assert len(lines) == 1 and "error:20" in lines[0]
    assert "resume with: stringbot wind" in lines[0] and "--resume" in lines[0]


@pytest.mark.parametrize("args, words", [
    (["--machine", "grbl-ring", "--port", "/dev/ttyNOPE_stringbot"], "does not exist"),
    (["--machine", "no-such-machine"], "no-such-machine"),
    (["--machine", "grbl-ring", "--faults", "boom@3"], "boom@3"),
    (["--machine", "grbl-ring", "--port", "/dev/ttyNOPE", "--record", "r.json"], "simulated machine"),
    (["--machine", "grbl-ring", "--resume"], "nothing to resume"),
    (["--machine", "grbl-ring", "--port", "sim://?machine=grbl-ring", "--resume"], "does not exist"),
    (["--machine", "grbl-ring", "--from-step", "0"], "--from-step"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, plan_path, capsys, args, words):
    code, out, err = run(["wind", str(plan_path), "--yes", "--journal", str(tmp_path / "j")] + args, capsys)
    assert code == 2, err
    lines = error_lines(err)
    assert len(lines) == 1 and "Traceback" not in err
    assert words in lines[0]


def test_missing_plan_exits_2(tmp_path, capsys):
    code, out, err = run(["wind", str(tmp_path / "nope.json"), "--machine", "grbl-ring", "--yes"], capsys)
    assert code == 2 and "does not exist" in err


@pytest.mark.realtime
def test_ctrl_c_on_a_dry_run_exits_130_without_a_resume_hint(tmp_path, plan_path):
    """A real SIGINT to a realtime dry run: feed hold, one line, exit 130; no resume hint (a dry
    run cannot be resumed: --resume would refuse it)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-c", "import sys; from stringbot.cli import main; main(sys.argv[1:])",
           "wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--realtime"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    journal = plan_path.with_name(plan_path.name + ".dry-run.journal")
    deadline = time.monotonic() + 120            # Ctrl-C once a pin is wound, however loaded the computer
    while proc.poll() is None and time.monotonic() < deadline and b'"kind":"done"' not in (
            journal.read_bytes() if journal.exists() else b""):
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    lines = error_lines(err)
    assert len(lines) == 1 and "Traceback" not in err
    assert "interrupted at pin" in lines[0] and "--resume" not in lines[0] and "run it again" in lines[0]


class FakeDevice:
    """A pty whose far end answers every write with ``reply`` (None: never answers)."""

    def __init__(self, reply):
        import threading
        import tty
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        os.close(slave)
        self.reply = reply
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        import select
        while not self.stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if ready:
                try:
                    os.read(self.master, 1024)
                except OSError:
                    continue
                if self.reply:
                    os.write(self.master, self.reply)

    def close(self):
        self.stop.set()
        self.thread.join()
        os.close(self.master)


@pytest.mark.parametrize("reply, words", [
    (b"\x00\xff\xfe#$%\r\n", "unreadable bytes"),
    (None, "no answer"),
    (b"FIRMWARE_NAME:Marlin 2.1.2\r\nok\r\n", "runs Marlin"),
])
def test_a_device_that_is_not_the_machine_exits_1(tmp_path, plan_path, capsys, reply, words):
    dev = FakeDevice(reply)
    try:
        code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes",
                              "--port", dev.path, "--journal", str(tmp_path / "j")], capsys)
    finally:
        dev.close()
    assert code == 1, err
    lines = error_lines(err)
    assert len(lines) == 1 and "Traceback" not in err and words in lines[0]


def test_a_busy_port_exits_2(tmp_path, plan_path, capsys):
    import serial
    dev = FakeDevice(None)
    holder = serial.Serial(dev.path, exclusive=True)
    try:
        code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes",
                              "--port", dev.path, "--journal", str(tmp_path / "j")], capsys)
    finally:
        holder.close()
        dev.close()
    assert code == 2, err
    assert "busy" in error_lines(err)[0]


@pytest.mark.parametrize("port, expected", [
    ("rfc2217://127.0.0.1:1", 2),                               # nothing listens there
    ("sim://?machine=grbl-ring&set=$100=40", 1),                # a firmware that disagrees
])
def test_a_start_that_cannot_begin_leaves_the_last_journal_as_it_was(tmp_path, plan_path, capsys, port, expected):
    """The journal of a finished winding is what keeps `plan -o` from replacing a wound plan: a
    start whose port does not open, or whose machine disagrees with its file, must not replace it."""
    journal = tmp_path / "plan.journal"
    code, _, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--journal", str(journal)],
                       capsys)
    assert code == 0, err
    before = journal.read_bytes()
    assert b'"finished"' in before
    code, _, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--journal", str(journal),
                        "--port", port], capsys)
    assert code == expected, err
    assert "Traceback" not in err
    assert journal.read_bytes() == before


def test_a_port_that_does_not_open_writes_no_journal(tmp_path, plan_path, capsys):
    """Nothing began, so nothing is recorded: no bare start left behind for `--status` or `plan -o`
    to read as a winding (a refused settings check, which did talk to the machine, is recorded)."""
    journal = tmp_path / "plan.journal"
    code, _, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--journal", str(journal),
                        "--port", "rfc2217://127.0.0.1:1"], capsys)
    assert code == 2 and "Traceback" not in err, err
    assert not journal.exists()
