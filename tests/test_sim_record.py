"""The simulator's record tells what an operator would see: position, head side, crashes, events.

Read from the record file only (as another process would), after the moments
the record promises to be current: a wrap, a collision, a crash, an event, the
port closed or dropped, the simulator's exit.
"""

import json
import signal
import subprocess
import sys
import time

import pytest
import serial

from firmware_protocol import urlhandler
from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.emulators.testing import run_exchange
from firmware_protocol.machine import load_machine
from firmware_protocol.urlhandler import protocol_sim
from firmware_protocol.world import World

pytestmark = pytest.mark.timeout(60)

OK = b"ok\r\n"
BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"


@pytest.fixture(scope="module", autouse=True)
def registered():
    urlhandler.register()


@pytest.fixture(scope="module")
def machine():
    return load_machine("grbl-ring")


def read(path):
    return json.loads(path.read_text())


def test_motion_alone_is_written_at_most_every_interval_and_on_flush(machine, tmp_path):
    path = tmp_path / "rec.json"
    w = World(machine, record_path=path, save_interval=3600.0)
    w.move(0.6, 0.0)                       # the first change after the start waits for the interval
    assert read(path)["moves"] == 0
    w.move(0.6, 3.0)
    w.flush()
    rec = read(path)
    assert (rec["moves"], rec["ring_deg"], rec["head_mm"], rec["head_side"]) == (2, 0.6, 3.0, "in")
    w.move(0.6, 6.0)                        # exactly on the pin circle, in the gap
    w.close()
    assert read(path)["head_side"] == "on" and read(path) == w.record()
    w = World(machine, record_path=path, save_interval=0.0)
    w.move(0.6, 12.0)                       # interval 0: every move is written
    assert (read(path)["head_side"], read(path)["head_out"]) == ("out", True)


def test_an_event_is_written_at_once(machine, tmp_path):
    path = tmp_path / "rec.json"
    w = World(machine, record_path=path, save_interval=3600.0)
    w.move(0.6, 12.0)
    w.note("reset", t=1.5)
    rec = read(path)
    assert rec["events"] == [{"event": "reset", "move": 1, "t": 1.5}]
    assert (rec["ring_deg"], rec["head_mm"]) == (0.6, 12.0)


def test_driving_the_head_past_its_end_is_one_crash_and_it_stops_there(machine, tmp_path):
    lo, hi = machine.head_travel_mm
    assert (lo, hi) == (-3.0, 15.0)         # a quarter of IN 0 .. OUT 12 beyond each
    path = tmp_path / "rec.json"
    w = World(machine, record_path=path)
    w.move(0.6, 12.0)
    w.move(0.6, 24.0)                       # past the high end
    w.move(10.0, 30.0)                      # still pushing: the same crash; the ring turns on
    assert (w.ring_deg, w.head_mm) == (10.0, hi)
    rec = read(path)
    assert len(rec["crashes"]) == 1 and rec["crashes"][0]["head_mm"] == hi
    assert rec["crashes"][0]["driven_to_mm"] == 24.0 and "past its high end" in rec["crashes"][0]["reason"]
    w.move(10.0, 12.0)
    w.move(10.0, -12.0)                     # a new excursion, to the other end, in one diagonal
    assert w.head_mm == lo and len(w.crashes) == 2 and read(path)["crashes"][1]["head_mm"] == lo


def test_a_crash_in_a_diagonal_move_stops_the_head_where_it_met_the_end(machine):
    w = World(machine)
    w.move(0.6, 12.0)
    w.move(10.6, 22.0)                      # the head meets 15 mm a third of the way
    assert w.crashes[0]["ring_deg"] == pytest.approx(3.6)
    assert (w.ring_deg, w.head_mm) == (10.6, 15.0)


def test_the_firmware_loses_the_steps_of_a_crash(tmp_path):
    """A wrong declaration (head said OUT while it is IN) drives the head into its end when it is
    sent IN; the firmware goes on believing, so OUT is then 3 mm short."""
    emu, world = build_emulator("grbl-ring", record=tmp_path / "rec.json")
    emu.transmit()
    run_exchange(emu, [(b"G10 L20 P1 Y12\n", OK),             # the head is IN (physical 0)
                       (b"G0 Y0\nG4 P0\n", OK + OK)])         # "IN" drives it towards -12
    assert world.head_mm == -3.0 and len(world.crashes) == 1
    run_exchange(emu, [(b"G0 Y12\nG4 P0\n", OK + OK)])        # "OUT": 12 mm of belief from -3
    assert world.head_mm == 9.0 and len(world.crashes) == 1
    run_exchange(emu, [(b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,-12.000,0.000>\r\n")])
    assert json.loads((tmp_path / "rec.json").read_text())["crashes"][0]["driven_to_mm"] == -12.0


def test_sim_url_record_is_current_once_the_port_is_closed(tmp_path):
    rec = tmp_path / "rec.json"
    url = f"sim://?machine=grbl-ring&record={rec}"
    port = serial.serial_for_url(url, timeout=0.3)
    port.read(len(BANNER))
    for line in (b"G0 X0.6\n", b"G0 Y12\n", b"G0 X1.8\n", b"G4 P0\n"):
        port.write(line)
        assert port.readline() == OK
    port.close()
    r = read(rec)
    assert (r["ring_deg"], r["head_mm"], r["head_side"], r["moves"]) == (80 / 44.4444, 12.0, "out", 3)
    assert r["wraps"] == [] and r["crashes"] == [] and r["collisions"] == []
    protocol_sim.forget(url)


def test_sim_url_record_when_the_port_drops(tmp_path):
    rec = tmp_path / "rec.json"
    url = f"sim://?machine=grbl-ring&record={rec}&faults=power@3"
    port = serial.serial_for_url(url, timeout=0.3)
    port.read(len(BANNER))
    for line in (b"G0 X0.6 Y12\n", b"G4 P0\n"):
        port.write(line)
        assert port.readline() == OK
    with pytest.raises(serial.SerialException):
        port.write(b"G0 X90\n")
        port.read(1)
    r = read(rec)                            # written when the power went, before any close
    assert [e["event"] for e in r["events"]] == ["power off"]
    assert (r["ring_deg"], r["head_mm"], r["head_side"]) == (27 / 44.4444, 12.0, "out")   # whole steps
    port.close()
    protocol_sim.forget(url)


def test_stringbot_simulate_writes_the_record_when_it_exits(tmp_path):
    rec, pty = tmp_path / "rec.json", tmp_path / "tty"
    sim = subprocess.Popen([sys.executable, "-c", "import sys; from stringbot.cli import main; main(sys.argv[1:])",
                            "simulate", "--machine", "grbl-ring", "--pty", str(pty), "--record", str(rec)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 20
        while not pty.exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        port = serial.Serial(str(pty), 115200, timeout=2)
        assert port.read(len(BANNER)) == BANNER
        for line in (b"G0 X0.6\n", b"G0 Y7\n", b"G4 P0\n"):
            port.write(line)
            assert port.readline() == OK
        port.close()
    finally:
        sim.send_signal(signal.SIGINT)
        sim.wait(timeout=20)
    r = read(rec)
    assert (r["ring_deg"], r["head_mm"], r["head_side"]) == (27 / 44.4444, 7.0, "out")
