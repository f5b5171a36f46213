"""Faults that hit a moving machine: at a virtual time, at a fraction of a move, and a board
that restarts when its port is opened (GRBL, grblHAL, Marlin)."""

import json
import math
import threading
import tomllib

import pytest
import serial

from firmware_protocol import marlin as mc
from firmware_protocol import urlhandler
from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.emulators.grbl import GrblState
from firmware_protocol.emulators.testing import run_exchange
from firmware_protocol.faults import BOOT_SECONDS, Fault, FaultPlan, parse_faults
from firmware_protocol.machine import bundled_dir, machine_from_dict
from firmware_protocol.pty import PtyServer
from firmware_protocol.urlhandler import protocol_sim

pytestmark = pytest.mark.timeout(60)

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
UNLOCK = b"[MSG:'$H'|'$X' to unlock]\r\n"
OK = b"ok\r\n"
ALARM3 = b"ALARM:3\r\n"


def on_step(x, spu=44.4444):
    """``x`` on the nearest whole step of grbl-ring's ring axis (the firmware counts steps)."""
    return round(x * spu) / spu


HALF_STEP = 0.5 / 44.4444


def grbl(faults=None, machine="grbl-ring", record=None):
    emu, world = build_emulator(machine, faults=faults, record=record)
    emu.transmit()
    return emu, world


def status(emu):
    emu.receive(b"?")
    return emu.transmit().decode()


# ---- the grammar ---------------------------------------------------------------------------------
def test_fault_forms_parse_and_print_back():
    faults = parse_faults("reset@12, reset@line=12, reset@t=12.5, power@230+0.4, reboot@line=7+.5, "
                          "ignore@5..9, ignore@30.., ignore@40+, garble@line=3")
    assert faults == [Fault("reset", 12), Fault("reset", 12), Fault("reset", time=12.5),
                      Fault("power", 230, fraction=0.4), Fault("reboot", 7, fraction=0.5),
                      Fault("ignore", 5, last=9), Fault("ignore", 30, last=math.inf),
                      Fault("ignore", 40, last=math.inf), Fault("garble", 3)]
    assert [str(f) for f in faults] == ["reset@12", "reset@12", "reset@t=12.5", "power@line=230+0.4",
                                        "reboot@line=7+0.5", "ignore@5..9", "ignore@30..", "ignore@40..",
                                        "garble@3"]


@pytest.mark.parametrize("bad, why", [
    ("reset@230+1.5", "fraction of the move must be > 0 and < 1"),
    ("reset@230+0", "fraction of the move must be > 0 and < 1"),
    ("reset@3..9", "reset fires once, so it takes no range"),
    ("garble@t=3", "garble hits a line as it arrives"),
    ("drop-ok@3+0.5", "drop-ok hits a line as it arrives"),
    ("ignore@9..3", "the range ends before it starts"),
    ("reset@t=", "expected a comma list"),
    ("reset@t=-1", "expected a comma list"),
    ("melt@t=3", "expected a comma list"),
])
def test_bad_fault_forms_name_the_expected_form(bad, why):
    with pytest.raises(ValueError, match=why):
        parse_faults(bad)


def test_ranges_fire_on_every_line_they_cover():
    plan = FaultPlan("ignore@2..3,drop-ok@4..")
    assert [plan.next_line() for _ in range(6)] == [set(), {"ignore"}, {"ignore"}, {"drop-ok"},
                                                   {"drop-ok"}, {"drop-ok"}]


# ---- a soft reset while moving: GRBL's own sequence -----------------------------------------------
def test_reset_at_a_time_stops_the_ring_mid_move_and_keeps_the_position(tmp_path):
    emu, world = grbl("reset@t=0.3", record=tmp_path / "rec.json")
    run_exchange(emu, [(b"G0 X90\n", OK), (b"", ALARM3)])
    assert emu.now == pytest.approx(0.3)
    moved = world.ring_deg
    assert 0 < moved < 90
    run_exchange(emu, [(b"", BANNER + UNLOCK)])
    assert emu.now == pytest.approx(0.8)                   # GRBL's 0.5 s pause after an alarm
    assert status(emu) == f"<Alarm|MPos:{moved:.3f},0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n"
    rec = json.loads((tmp_path / "rec.json").read_text())  # written when the reset hit
    assert rec["events"] == [{"event": "reset", "move": rec["moves"], "t": 0.3, "at": "t=0.3",
                              "moving": True}]
    assert (rec["ring_deg"], rec["head_side"]) == (moved, "in")


def test_reset_at_a_fraction_of_a_move_answers_the_waiting_line_then_the_banner():
    """The sync line (G4 P0) waits in GRBL's main loop when the reset comes: after ALARM:3 and the
    pause it is answered ok -- a stray ok a host counting answers must not take for a move done."""
    emu, world = grbl("reset@1+0.4")
    run_exchange(emu, [(b"G0 X90\nG4 P0\n", OK + ALARM3 + OK + BANNER + UNLOCK)])
    assert world.ring_deg == pytest.approx(36.0, abs=HALF_STEP)
    assert status(emu).startswith("<Alarm|MPos:36.000,0.000,0.000|")


def test_a_fraction_counts_the_whole_path_of_the_line():
    emu, world = grbl("power@2+0.25")
    run_exchange(emu, [(b"G0 X10\n", OK), (b"G0 X20 Y8\n", OK)])
    while emu.port_up:
        emu.advance(None)
    assert world.ring_deg == pytest.approx(12.5, abs=HALF_STEP) and world.head_mm == 2.0
    emu.reconnect()
    run_exchange(emu, [(b"", BANNER), (b"G0 X0 Y0\nG4 P0\n", OK + OK)])
    assert (world.ring_deg, world.head_mm) == pytest.approx((12.5, 2.0), abs=HALF_STEP)   # belief wiped
    emu, world = grbl("power@2+0.5")
    run_exchange(emu, [(b"G0 X10\n", OK), (b"G28 X20\n", OK)])          # via X20 to G28's X0
    while emu.port_up:
        emu.advance(None)
    assert world.ring_deg == pytest.approx(15.0, abs=HALF_STEP)   # half of 10 + 20, on the way back


def test_a_fraction_of_a_line_that_does_not_move_fires_as_it_starts():
    emu, world = grbl("reset@2+0.5")
    run_exchange(emu, [(b"G0 X10\n", OK)])
    emu.advance(0.05)
    run_exchange(emu, [(b"G4 P1\n", ALARM3 + OK + BANNER + UNLOCK)])
    assert 0 < world.ring_deg < 10


def test_ctrl_x_while_moving_is_the_same_sequence():
    emu, world = grbl()
    run_exchange(emu, [(b"G0 X90\nG4 P0\n", OK)])
    emu.advance(0.3)
    emu.receive(b"\x18?G0 X1\n")                           # the rest is lost in the pause
    assert emu.transmit() == ALARM3
    run_exchange(emu, [(b"", OK + BANNER + UNLOCK)])
    assert emu.state is GrblState.ALARM and 0 < world.ring_deg < 90


def test_ctrl_x_in_a_dwell_at_rest_answers_the_dwell_without_alarm():
    emu, world = grbl()
    run_exchange(emu, [(b"G4 P5\n", b"")])
    emu.advance(1.0)
    run_exchange(emu, [(b"\x18", OK + BANNER)])
    assert emu.state is GrblState.IDLE and emu.now == pytest.approx(1.0)


def test_grblhal_alarm_sequence():
    emu, world = grbl("reset@t=0.2", machine="grblhal-ring")
    run_exchange(emu, [(b"$X\n", b"[MSG:Caution: Unlocked]\r\nok\r\n"), (b"G0 A90\nG4 P0\n", OK)])
    out = b""
    while emu.busy:
        emu.advance(None)
        out += emu.transmit()
    assert out == (ALARM3 + OK + b"\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n" + UNLOCK)
    assert 0 < world.ring_deg < 90


# ---- reboot and power: the position is wiped, the world is not -----------------------------------
def test_reboot_mid_move_is_silent_a_moment_then_forgets_the_position(tmp_path):
    emu, world = grbl("reboot@1+0.5", record=tmp_path / "rec.json")
    run_exchange(emu, [(b"G0 X90\nG4 P0\n", b"ok\r\n")])
    emu.advance(emu.next_event_in())                        # the reboot
    assert world.ring_deg == pytest.approx(45.0, abs=HALF_STEP)
    emu.receive(b"?G0 X1\n")                                # the bootloader eats it
    assert emu.transmit() == b"" and emu.next_event_in() == pytest.approx(BOOT_SECONDS)
    run_exchange(emu, [(b"", BANNER),
                       (b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n")])
    assert world.ring_deg == pytest.approx(45.0, abs=HALF_STEP)
    events = json.loads((tmp_path / "rec.json").read_text())["events"]
    assert [(e["event"], e["at"]) for e in events] == [("reboot", "line=1+0.5")]


def test_power_loss_mid_head_move_then_position_reads_zero():
    emu, world = grbl("power@t=0.05")
    run_exchange(emu, [(b"G0 Y12\n", OK)])
    emu.advance(0.05)
    assert not emu.port_up and 0 < world.head_mm < 12
    stopped = world.head_mm
    emu.reconnect()
    run_exchange(emu, [(b"", BANNER),
                       (b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n")])
    assert world.head_mm == stopped


def test_marlin_reset_mid_move_is_a_restart():
    emu, world = build_emulator("marlin-ring", faults="reset@2+0.5")
    emu.transmit()
    n = lambda i, c: mc.numbered(i, c).encode() + b"\n"  # noqa: E731
    run_exchange(emu, [(n(0, "M110 N0"), b"ok\n"), (n(1, "G0 A90"), b"ok\n")])
    emu.advance(None)                                       # half way: the board restarts
    assert world.ring_deg == pytest.approx(45.0, abs=HALF_STEP) and emu.transmit() == b""
    emu.advance(None)
    assert emu.transmit().startswith(b"start\n")
    run_exchange(emu, [(n(1, "M114"), b"X:0.00 Y:0.00 Z:0.00 A:0.00 Count X:0 Y:0 Z:0 A:0\nok\n")])


def test_a_timed_fault_while_the_power_is_off_hits_nothing(tmp_path):
    emu, world = grbl("power@t=0.1,reset@t=0.5", record=tmp_path / "rec.json")
    emu.advance(2.0)
    events = json.loads((tmp_path / "rec.json").read_text())["events"]
    assert [e["event"] for e in events] == ["power off", "reset", "power on"]
    assert events[1]["skipped"] == "the firmware is off"


# ---- a board that restarts when its port is opened -----------------------------------------------
@pytest.fixture
def uno(tmp_path):
    """grbl-ring with controller.reset_on_open = true (the Arduino Uno the file describes)."""
    doc = tomllib.loads((bundled_dir() / "grbl-ring.toml").read_text())
    doc["controller"]["reset_on_open"] = True
    path = tmp_path / "uno.toml"
    path.write_text(machine_from_dict(doc).to_toml())
    return path


def test_reset_on_open_through_sim_url(uno, tmp_path):
    urlhandler.register()
    rec = tmp_path / "rec.json"
    url = f"sim://?machine={uno}&record={rec}"
    port = serial.serial_for_url(url, timeout=0.3)
    assert port.read(len(BANNER)) == BANNER                 # the banner of the restart on open
    for line in (b"G0 X5\n", b"G4 P0\n"):
        port.write(line)
        assert port.readline() == OK
    port.close()
    port = serial.serial_for_url(url, timeout=0.3)
    assert port.read(len(BANNER)) == BANNER                 # restarted again: position lost
    port.write(b"?")
    assert port.readline().startswith(b"<Idle|MPos:0.000,0.000,0.000|")
    port.close()
    r = json.loads(rec.read_text())
    assert [(e["event"], e["at"]) for e in r["events"]] == [("reboot", "port opened")] * 2
    assert r["ring_deg"] == on_step(5.0)
    protocol_sim.forget(url)


def test_reset_on_open_through_a_pty(uno, tmp_path):
    emu, world = build_emulator(uno)
    server = PtyServer(emu, tmp_path / "tty", reopen_delay=0.1).start()
    stop = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stop,), kwargs={"poll": 0.005}, daemon=True)
    thread.start()
    try:
        port = serial.Serial(str(tmp_path / "tty"), timeout=2)
        assert port.read(len(BANNER)) == BANNER            # one banner: the one from before the open is gone
        port.write(b"G0 X5\nG4 P0\n")
        assert port.read(2 * len(OK)) == OK + OK
        port.close()
        for _ in range(500):                               # the server sees the port closed ...
            if server._client_since is None:
                break
            stop.wait(0.01)
        port = serial.Serial(str(tmp_path / "tty"), timeout=2)   # ... and opened again
        assert port.read(len(BANNER)) == BANNER
        port.write(b"?")
        assert port.readline().startswith(b"<Idle|MPos:0.000,0.000,0.000|")
        port.close()
        assert world.ring_deg == on_step(5.0)
    finally:
        stop.set()
        thread.join(5)
        server.close()


def test_reset_on_open_is_off_by_default():
    emu, world = grbl()
    assert emu.port_opened() is False and emu.transmit() == b""


# ---- ignore: ok without execution ----------------------------------------------------------------
def test_grbl_ignore_answers_ok_and_does_nothing():
    emu, world = grbl("ignore@2,ignore@4..")
    run_exchange(emu, [
        (b"G0 X10\nG0 X20\nG4 P0\n", OK + OK + OK),        # line 2 acknowledged, not run
        (b"?", b"<Idle|MPos:9.990,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n"),
        (b"G10 L20 P1 X0\nG0 X30\n$X\n", OK + OK + OK),     # from line 4 on: nothing happens
    ])
    emu.advance(5.0)
    assert world.ring_deg == on_step(10.0)
    assert status(emu).startswith("<Idle|MPos:9.990,0.000,0.000|")
    assert emu.parser.coord_systems[0] == [0.0, 0.0, 0.0]              # G10 L20 did nothing either


def test_marlin_ignore_answers_ok_and_does_nothing():
    emu, world = build_emulator("marlin-ring", faults="ignore@3")
    emu.transmit()
    n = lambda i, c: mc.numbered(i, c).encode() + b"\n"  # noqa: E731
    run_exchange(emu, [(n(0, "M110 N0"), b"ok\n"), (n(1, "G0 A10"), b"ok\n"), (n(2, "G0 A20"), b"ok\n"),
                       (n(3, "M400"), b"ok\n"),
                       (n(4, "M114"), b"X:0.00 Y:0.00 Z:0.00 A:10.00 Count X:0 Y:0 Z:0 A:444\nok\n")])
    assert world.ring_deg == on_step(10.0)


def test_a_plus_in_a_sim_url_is_a_plus():
    from firmware_protocol.urlhandler.protocol_sim import parse_url
    assert parse_url("sim://?faults=reset@230+0.4,ignore@9+")["faults"] == "reset@230+0.4,ignore@9+"
    assert parse_url("sim://?faults=reset@230%2B0.4")["faults"] == "reset@230+0.4"
    assert parse_url("sim://?record=my%20rec+1.json")["record"] == "my rec+1.json"
