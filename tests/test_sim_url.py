"""``sim://``: the simulated machine through pyserial's own serial_for_url."""

import json
import time

import pytest
import serial

from firmware_protocol import urlhandler
from firmware_protocol.urlhandler import protocol_sim

pytestmark = pytest.mark.timeout(30)

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"


@pytest.fixture(autouse=True)
def registered():
    urlhandler.register()
    urlhandler.register()                       # idempotent
    assert serial.protocol_handler_packages.count("firmware_protocol.urlhandler") == 1
    yield
    protocol_sim.forget()


def url(tmp_path, **opts):
    query = "&".join(f"{k}={v}" for k, v in {"machine": "grbl-ring", "record": tmp_path / "rec.json",
                                               **opts}.items())
    return f"sim://?{query}"


def lines(port, n):
    return [port.readline() for _ in range(n)]


def test_banner_and_a_hand_written_hook_of_one_pin_is_exactly_one_wrap(tmp_path):
    port = serial.serial_for_url(url(tmp_path), timeout=1)
    assert port.read(len(BANNER)) == BANNER
    # pin 10 faces the station at X = 12 deg (pitch 1.2): gap 9|10 at 11.4, gap 10|11 at 12.6
    for line in (b"G0 X11.4\n", b"G0 Y12\n", b"G0 X12.6\n", b"G0 Y0\n", b"G4 P0\n"):
        port.write(line)
        assert port.readline() == b"ok\r\n"
    record = json.loads((tmp_path / "rec.json").read_text())
    assert record["wraps"] == [{"pin": 10, "direction": 1}]
    assert record["collisions"] == []
    port.write(b"?")
    assert port.readline().startswith(b"<Idle|MPos:12.600,0.000,0.000|")
    port.close()


def test_read_on_an_idle_machine_returns_after_the_timeout(tmp_path):
    port = serial.serial_for_url(url(tmp_path), timeout=0.2)
    port.read(len(BANNER))
    emu = protocol_sim.session(url(tmp_path)).emulator
    idle_since = emu.now
    t0 = time.monotonic()
    assert port.read(10) == b""                      # the timeout ends the read, with nothing
    assert time.monotonic() - t0 < 30                # it does end (no timing figure: benchmarks/)
    assert emu.now == idle_since                     # fast mode: nothing pending, no virtual time passed
    assert port.in_waiting == 0
    port.write(b"G0 X1\n")
    assert port.in_waiting == 4
    port.reset_input_buffer()
    assert port.in_waiting == 0
    port.close()
    with pytest.raises(serial.PortNotOpenError):
        port.read(1)


@pytest.mark.parametrize("query, named", [
    ("color=red", "unknown option 'color'"),
    ("realtime=2", "realtime='2'; expected 0 or 1"),
    ("machine=no-such-machine", "unknown machine 'no-such-machine'"),
    ("faults=reset@x", "bad fault 'reset@x'"),
    ("faults=melt@3", "bad fault 'melt@3'"),
])
def test_a_wrong_option_is_named_with_the_expected_form(query, named):
    with pytest.raises(serial.SerialException) as info:
        serial.serial_for_url(f"sim://?{query}")
    assert named in str(info.value)
    assert 'expected a string in the form "sim://[?machine=NAME]' in str(info.value)


def test_default_machine_is_grbl_ring_and_the_machine_survives_reopen(tmp_path):
    u = url(tmp_path)
    port = serial.serial_for_url(u, timeout=1)
    port.read(len(BANNER))
    port.write(b"G0 X7\nG4 P0\n")
    assert lines(port, 2) == [b"ok\r\n", b"ok\r\n"]
    port.close()
    again = serial.serial_for_url(u, timeout=0.1)
    assert again.read(100) == b""                 # same machine: no new banner
    again.write(b"?")
    assert again.readline().startswith(b"<Idle|MPos:6.998,")
    again.close()
    fresh = serial.serial_for_url("sim://", timeout=1)
    assert fresh.read(len(BANNER)) == BANNER
    fresh.close()


def test_faults_fire_at_line_n(tmp_path):
    port = serial.serial_for_url(url(tmp_path, faults="error@2,drop-ok@3,garble@4"), timeout=0.3)
    port.read(len(BANNER))
    port.write(b"G0 X1\n")
    assert port.readline() == b"ok\r\n"
    port.write(b"G0 X2\n")
    assert port.readline() == b"error:20\r\n"       # rejected, not executed
    port.write(b"G0 X3\n")
    assert port.readline() == b""                   # executed, its ok lost
    port.write(b"G0 X44\n")                         # "G0 X44" -> "G0 \x7f44": error:1
    assert port.readline() == b"error:1\r\n"
    port.write(b"G4 P0\n?")
    assert port.readline() == b"ok\r\n"
    assert port.readline().startswith(b"<Idle|MPos:2.993,")
    port.close()


def test_disconnect_drops_the_port_until_it_is_reopened(tmp_path):
    u = url(tmp_path, faults="disconnect@2")
    port = serial.serial_for_url(u, timeout=0.3)
    port.read(len(BANNER))
    port.write(b"G0 X5\n")
    assert port.readline() == b"ok\r\n"
    with pytest.raises(serial.SerialException, match="disconnected"):
        port.write(b"G0 X6\n")                      # line 2 is lost with the cable
        port.read(1)
    with pytest.raises(serial.SerialException):
        port.read(1)
    port.close()
    port = serial.serial_for_url(u, timeout=0.3)
    port.write(b"G4 P0\n?")
    assert port.readline() == b"ok\r\n"
    assert port.readline().startswith(b"<Idle|MPos:4.995,")   # the firmware kept running
    port.close()


def test_power_loss_wipes_the_belief_not_the_world(tmp_path):
    u = url(tmp_path, faults="power@3")
    port = serial.serial_for_url(u, timeout=0.3)
    port.read(len(BANNER))
    port.write(b"G0 X30\n")
    assert port.readline() == b"ok\r\n"
    port.write(b"G0 Y1\n")
    assert port.readline() == b"ok\r\n"
    with pytest.raises(serial.SerialException):
        port.write(b"G0 X0\n")
        port.read(1)
    port.close()
    world = protocol_sim.session(u).world
    stopped = world.ring_deg
    assert stopped < 30.0                            # the power went while the ring was turning
    port = serial.serial_for_url(u, timeout=0.3)
    assert port.read(len(BANNER)) == BANNER          # the firmware restarted
    port.write(b"?")
    assert port.readline().startswith(b"<Idle|MPos:0.000,0.000,0.000|")
    assert world.ring_deg == stopped
    port.close()


def test_realtime_mode_takes_wall_clock_time(tmp_path):
    """No timed assert (figures: benchmarks/bench_realtime.py): the move takes its virtual time,
    and in realtime mode the virtual clock never runs ahead of the wall clock."""
    wall0 = time.monotonic()                         # before the emulator exists (its clock starts at 0)
    port = serial.serial_for_url(url(tmp_path, realtime=1), timeout=2)
    s = protocol_sim.session(url(tmp_path, realtime=1))
    port.read(len(BANNER))
    port.write(b"G0 Y3\nG4 P0\n")                    # 3 mm at 500 mm/s^2: about 0.155 s
    assert lines(port, 2) == [b"ok\r\n", b"ok\r\n"]
    assert s.world.head_mm == 3.0
    assert s.emulator.now >= 0.15                    # the sync waited for the whole move
    assert s.emulator.now <= time.monotonic() - wall0  # fast mode would jump ahead of the wall
    port.close()


def test_machine_by_path_and_marlin_through_the_url(tmp_path):
    from pathlib import Path

    from firmware_protocol.machine import load_machine
    path = Path(load_machine("marlin-ring").path)
    port = serial.serial_for_url(f"sim://?machine={path}&record={tmp_path / 'm.json'}", timeout=0.5)
    assert port.readline() == b"start\n"
    port.reset_input_buffer()
    from firmware_protocol.marlin import numbered
    port.write("".join(numbered(n, c) + "\n" for n, c in enumerate(["M110 N0", "G0 Y19", "M400"])).encode())
    assert [port.readline() for _ in range(3)] == [b"ok\n"] * 3
    port.close()
