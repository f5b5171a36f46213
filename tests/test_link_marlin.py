"""The Marlin link as exact exchange tables over a scripted port."""

import re

import pytest

from stringbot.errors import MachineFailure
from stringbot.links import MarlinLink
from stringbot.links.marlin import numbered

from planner_helpers import for_machine
from test_link_scripted import ScriptedPort

M115 = (b"FIRMWARE_NAME:Marlin 2.1.2 (Nov 1 2026) SOURCE_CODE_URL:github.com/MarlinFirmware/Marlin "
        b"PROTOCOL_VERSION:1.0 MACHINE_TYPE:stringbot\r\nCap:EMERGENCY_PARSER:1\r\nok\r\n")


def w(n, text):
    return numbered(n, text).encode() + b"\n"


def test_checksum_is_the_xor_of_the_bytes_before_the_star():
    # a line as hosts send it: XOR of "N0 M110 N0"
    assert numbered(0, "M110 N0") == "N0 M110 N0*125"


def link(extra, **kw):
    table = [(None, b"start\r\necho:Marlin 2.1.2\r\n"), (b"M115\n", M115),
             (w(0, "M110 N0"), b"ok\r\n")] + extra
    kw.setdefault("response_timeout", 0.3)
    lk = MarlinLink(ScriptedPort(table), **kw)
    lk.identify()
    return lk, lk.port


class FakeStep:
    def __init__(self, index, pin, lines):
        self.index, self.pin, self.lines = index, pin, lines


def test_identify_and_stream_with_line_numbers_and_m400():
    table = [(w(1, "G0 X1"), b"ok\r\n"), (w(2, "M400"), b"echo:busy: processing\r\n"),
             (None, b"ok\r\n")]
    lk, port = link(table)
    assert lk.info.dialect == "marlin" and lk.info.version == "2.1.2"
    done = []
    lk.execute([FakeStep(0, 3, ["G0 X1 ; move"])], lambda s: s.lines, done.append)
    assert [s.index for s in done] == [0]
    port.assert_done()


def test_resend_after_a_checksum_error():
    table = [(w(1, "G0 X1"), b"Error:checksum mismatch, Last Line: 0\r\nResend: 1\r\nok\r\n"),
             (w(1, "G0 X1"), b"ok\r\n"), (w(2, "M400"), b"ok\r\n")]
    lk, port = link(table)
    lk.execute([FakeStep(0, 3, ["G0 X1"])], lambda s: s.lines)
    assert lk.resends == 1
    port.assert_done()


def test_lost_ok_is_found_by_sending_the_line_again():
    # a line answered at once (not a wait on motion): silence means a lost ok
    table = [(w(1, "G92 A0"), b""),    # its ok is lost
             (w(1, "G92 A0"), b"Error:Line Number is not Last Line Number+1, Last Line: 1\r\n"
                              b"Resend: 2\r\nok\r\n"),
             (w(2, "M400"), b"ok\r\n")]
    lk, port = link(table)
    lk.execute([FakeStep(0, 3, ["G92 A0"])], lambda s: s.lines)
    port.assert_done()


POS = b"X:0.00 Y:19.00 Z:0.00 A:30.00 Count X:0 Y:0 Z:0 A:0\r\n"


def test_a_long_silent_m400_is_waited_for_not_sent_again():
    # busy keepalive off (M113 S0): M400 says nothing for many response timeouts, then ok.
    # The link never sends it twice; M114 goes behind it once, and is answered after it.
    table = [(w(1, "G0 X1"), b"ok\r\n"), (w(2, "M400"), b""),
             (w(3, "M114"), b""),                               # no answer while moving
             (None, b""), (None, b""), (None, b""), (None, b""),  # reads that find nothing
             (None, b"ok\r\n" + POS + b"ok\r\n"),                # M400 done, then M114
             (w(4, "G0 X2"), b"ok\r\n"), (w(5, "M400"), b"ok\r\n")]
    lk, port = link(table, response_timeout=0.1, motion_timeout=30.0)
    done = []
    lk.execute([FakeStep(0, 3, ["G0 X1"]), FakeStep(1, 4, ["G0 X2"])], lambda s: s.lines,
               lambda s: done.append((s.index, len(port.table))))
    # step 1 only after M400's ok; step 2 after its own M400's, not the M114's
    assert done == [(0, 2), (1, 0)]
    assert lk.resends == 0 and port.written.count(w(2, "M400")) == 1
    port.assert_done()


def test_a_lost_m400_ok_is_found_by_the_m114_behind_it():
    table = [(w(1, "G0 X1"), b"ok\r\n"), (w(2, "M400"), b""),   # its ok is lost
             (w(3, "M114"), POS + b"ok\r\n"),
             (w(4, "G0 X2"), b"ok\r\n"), (w(5, "M400"), b"ok\r\n")]
    lk, port = link(table)
    done = []
    lk.execute([FakeStep(0, 3, ["G0 X1"]), FakeStep(1, 4, ["G0 X2"])], lambda s: s.lines,
               lambda s: done.append(s.index))
    assert done == [0, 1] and lk.last_position["A"] == 30.0
    port.assert_done()


def test_a_silent_m400_fails_only_at_the_motion_timeout():
    table = [(w(1, "G0 X1"), b"ok\r\n"), (w(2, "M400"), b""), (w(3, "M114"), b"")]
    lk, port = link(table, response_timeout=0.05, motion_timeout=0.5)
    with pytest.raises(MachineFailure, match=r"did not answer within 0 s.*pin 7, step 5"):
        lk.execute([FakeStep(4, 7, ["G0 X1"])], lambda s: s.lines)
    port.assert_done()


def test_other_firmware_refused():
    table = [(None, b"Grbl 1.1h ['$' for help]\r\n"), (b"M115\n", b"error:20\r\n")]
    lk = MarlinLink(ScriptedPort(table), response_timeout=0.3)
    with pytest.raises(MachineFailure, match="runs GRBL"):
        lk.identify()
    lk.port.assert_done()


@pytest.mark.parametrize("reply, words", [
    (b"Error:Printer halted. kill() called!\r\n", "Printer halted"),
    (b"start\r\n", "reset itself"),
    (b"\x01\x02zz\r\n", "garbage"),
])
def test_failures_name_pin_and_step(reply, words):
    table = [(w(1, "G0 X1"), reply)]
    lk, port = link(table)
    with pytest.raises(MachineFailure, match=words) as info:
        lk.execute([FakeStep(4, 7, ["G0 X1"])], lambda s: s.lines)
    assert "pin 7, step 5" in str(info.value)
    port.assert_done()


def test_silence_is_a_clear_failure():
    table = [(w(1, "G92 A0"), b""), (w(1, "G92 A0"), b""), (w(1, "G92 A0"), b"")]
    lk, port = link(table)
    with pytest.raises(MachineFailure, match="stopped answering.*pin 7, step 5"):
        lk.execute([FakeStep(4, 7, ["G92 A0"])], lambda s: s.lines)
    port.assert_done()


@pytest.mark.realtime
def test_a_marlin_that_stops_sending_keepalives_is_declared_unresponsive(tmp_path):
    """``stringbot simulate --realtime`` (its own process, a pty) with the ring slowed to 30 deg/s:
    step 2's half-turn jump waits 6 s on M400, with a busy: keepalive every 2 s; ``freeze@40`` (the
    M400 of step 3) then hangs the firmware.  ``wind`` stops after three keepalive periods (not
    motion_timeout's 600 s): exit 1, one line, a stop record, the resume hint.  (Realtime: in fast
    mode the simulator may finish a move before its M400 arrives, and then sends no keepalive.)"""
    import os
    import signal
    import subprocess
    import sys
    import time

    from stringbot.planner import write_plan
    from stringbot.winding import read_journal
    from test_gcode_replay import make_plan

    write_plan(for_machine(make_plan([0, 150, 1, 151]), "marlin-ring"), tmp_path / "plan.json")
    pty = tmp_path / "pty"
    cli = [sys.executable, "-c", "from stringbot.cli import main; main()"]
    sim = subprocess.Popen(cli + ["simulate", "--machine", "marlin-ring", "--pty", str(pty), "--set", "M203 A30",
                                  "--realtime", "--faults", "freeze@40"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for _ in range(200):
            if os.path.islink(pty):
                break
            time.sleep(0.05)
        wind = subprocess.run(cli + ["wind", str(tmp_path / "plan.json"), "--machine", "marlin-ring", "--port",
                                     str(pty), "--yes", "--no-check", "--head-side", "in"],   # it homes
                              capture_output=True, text=True, timeout=300)
    finally:
        sim.send_signal(signal.SIGINT)
        sim.communicate(timeout=10)
    assert wind.returncode == 1 and "Traceback" not in wind.stderr, wind.stderr
    [line] = [x for x in wind.stderr.splitlines() if x.startswith("stringbot: error:")]
    # the period it names is what it measured (2 s on an idle computer, more on a loaded one): not asserted
    assert "stopped answering" in line and re.search(r"keepalives every \d+(\.\d+)? s", line) and "--resume" in line
    assert "(at pin 1, step 3)" in line
    stop = read_journal(tmp_path / "plan.json.journal").last_stop
    assert stop["reason"] == "failed" and "stopped answering" in stop["error"]


def test_hang_after_is_a_few_periods_within_bounds():
    from stringbot.links.marlin import HANG_CAP_S, HANG_FLOOR_S, hang_after
    assert hang_after(2.0) == 6.0                      # three of Marlin's default periods
    assert hang_after(0.01) == HANG_FLOOR_S            # a fast simulator: never sooner than the floor
    assert hang_after(60.0) == HANG_CAP_S == 180.0     # M113's longest period
    assert hang_after(None) == HANG_CAP_S              # keepalives heard, period not yet measured


def test_ctrl_c_right_after_a_line_is_written_never_reuses_its_number_nor_reports_a_stale_position():
    """Ctrl-C landing just after ``N2 M400`` left the port: the position read for the stop record
    goes as N3 (an N2 would be taken by Marlin for a resend and answered by nothing), and a reply
    that does not carry its report gives no position rather than the one read before the move
    (which, trusted after a reboot, put the whole rest of the winding one pin off)."""
    stale = b"X:0.00 Y:8.00 Z:0.00 A:-81.00 Count X:0 Y:0 Z:0 A:0\r\nok\r\n"
    table = [(w(1, "M114"), stale), (w(2, "M400"), KeyboardInterrupt()),
             (w(3, "M114"), b"ok\r\nX:0.00 Y:8.00 Z:0.00 A:-82.20 Count X:0 Y:0 Z:0 A:-48\r\nok\r\n")]
    lk, port = link(table)
    assert lk.status().fields["axes"]["A"] == -81.0
    with pytest.raises(KeyboardInterrupt):
        lk.command("M400")
    axes = lk.status().fields["axes"]            # the first ok is the M400's: no report yet
    assert axes.get("A") != -81.0
    port.assert_done()
