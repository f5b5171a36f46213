"""Honest messages: one line, the right exit code, the resume hint only when something was wound."""

import socket
import sys

import pytest
import serial

from firmware_protocol.urlhandler import protocol_sim
from stringbot.cli import main
from stringbot.links import sim_url
from stringbot.planner import write_plan

from test_wind_sim import small_plan


def run(argv, capsys, monkeypatch=None, stdin=None):
    if stdin is not None:
        monkeypatch.setattr(sys, "stdin", stdin)
    with pytest.raises(SystemExit) as info:
        main(argv)
    out, err = capsys.readouterr()
    lines = [x for x in err.splitlines() if x.startswith("stringbot:")]
    return info.value.code, lines, err


@pytest.fixture
def plan_path(tmp_path):
    path = tmp_path / "plan.json"
    write_plan(small_plan(n=6, seed=7), path)
    return path


@pytest.mark.parametrize("extra, words", [
    (["--head-side", "in"], "goes with --resume"),
    (["--resume", "--from-step", "2"], "not both"),
])
def test_option_mistakes_are_one_line_exit_2(plan_path, capsys, extra, words):
    code, lines, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes"] + extra, capsys)
    assert code == 2 and len(lines) == 1 and words in lines[0] and "Traceback" not in err


def test_from_step_out_of_range_is_one_line_exit_2(tmp_path, plan_path, capsys):
    url = sim_url("grbl-ring", record=tmp_path / "r.json")
    code, lines, _ = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--port", url], capsys)
    assert code == 0
    code, lines, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--port", url,
                            "--from-step", "99"], capsys)
    assert code == 2 and len(lines) == 1 and "expected a step 1..6" in lines[0]
    protocol_sim.forget(url)


def test_a_question_without_a_terminal_says_so(tmp_path, plan_path, capsys, monkeypatch):
    import io
    url = sim_url("grbl-ring", record=tmp_path / "r.json")
    code, lines, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--port", url], capsys,
                           monkeypatch, stdin=io.StringIO(""))
    assert code == 2, err
    assert len(lines) == 1 and "standard input ended" in lines[0] and "--yes" in lines[0]
    protocol_sim.forget(url)


def test_a_refused_connection_says_what_to_check_and_offers_no_resume(plan_path, capsys):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()                                          # nothing listens there now
    code, lines, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--port",
                            f"socket://127.0.0.1:{port}"], capsys)
    assert code == 2 and len(lines) == 1, err
    assert "connection was refused" in lines[0] and "check" in lines[0]
    assert "--resume" not in lines[0]


def test_grbl_left_in_hold_is_named(tmp_path, plan_path, capsys):
    url = sim_url("grbl-ring", record=tmp_path / "r.json")
    port = serial.serial_for_url(url, timeout=0.05)
    port.write(b"G1 X100 F100\n")
    port.write(b"!")                                   # another program's feed hold, left behind
    port.read(100)
    port.close()
    code, lines, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--port", url], capsys)
    assert code == 1 and len(lines) == 1, err
    assert "in Hold" in lines[0] and "send ~" in lines[0] and "not GRBL" not in lines[0]
    protocol_sim.forget(url)


def test_wrong_baud_rate_says_to_check_it(tmp_path, plan_path, capsys):
    """Garbage on the port before anything was understood: the baud rate is named."""
    from stringbot.errors import MachineFailure
    from stringbot.links import GrblLink

    class Noise:
        baudrate = 9600

        def __init__(self):
            self.buf = bytearray(b"\x1c\xe3\x80\x00\x1f\n" * 4)
            self.in_waiting = len(self.buf)

        def write(self, data):
            return len(data)

        def read(self, n=1):
            out, self.buf = bytes(self.buf[:n]), self.buf[n:]
            self.in_waiting = len(self.buf)
            return out

    with pytest.raises(MachineFailure, match=r"baud rate .*controller\.baud = 9600"):
        GrblLink(Noise()).identify()
