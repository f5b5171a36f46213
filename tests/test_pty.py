"""The simulator on a pseudo-terminal: real pyserial ports opened by path."""

import os
import threading
import time

import pytest
import serial

from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.pty import PtyServer

pytestmark = pytest.mark.timeout(30)

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"


@pytest.fixture
def serve(tmp_path):
    servers = []

    def start(machine="grbl-ring", faults=None, realtime=False):
        emulator, world = build_emulator(machine, record=tmp_path / "rec.json", faults=faults)
        path = tmp_path / "ttySIM"
        server = PtyServer(emulator, path, realtime=realtime, reopen_delay=0.2).start()
        stop = threading.Event()
        thread = threading.Thread(target=server.serve, args=(stop,), kwargs={"poll": 0.005}, daemon=True)
        thread.start()
        servers.append((server, stop, thread))
        return server, world, str(path)
    yield start
    for server, stop, thread in servers:
        stop.set()
        thread.join(5)
        server.close()


def test_exchange_lines_through_a_real_serial_port(serve):
    server, world, path = serve()
    assert os.path.islink(path) and os.readlink(path).startswith("/dev/pts/")
    port = serial.Serial(path, 115200, timeout=2)
    assert port.read(len(BANNER)) == BANNER           # held until the port was opened
    for line in (b"G0 X11.4\n", b"G0 Y12\n", b"G0 X12.6\n", b"G0 Y0\n", b"G4 P0\n"):
        port.write(line)
        assert port.readline() == b"ok\r\n"
    port.write(b"?")
    assert port.readline().startswith(b"<Idle|MPos:12.600,0.000,0.000|")
    assert [(w.pin, w.direction) for w in world.wraps] == [(10, 1)]
    port.write(b"G1 X1\n")
    assert port.readline() == b"error:22\r\n"
    port.close()


def test_disconnect_drops_the_port_and_it_comes_back_at_the_same_path(serve):
    server, world, path = serve(faults="disconnect@2")
    port = serial.Serial(path, 115200, timeout=1)
    assert port.read(len(BANNER)) == BANNER
    port.write(b"G0 X5\n")
    assert port.readline() == b"ok\r\n"
    port.write(b"G0 X6\n")                             # the cable is pulled as this line arrives
    with pytest.raises(serial.SerialException):
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            port.read(1)
            port.write(b"?")
    port.close()
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        if server.generation == 2 and os.path.exists(path):
            break
        time.sleep(0.02)
    assert server.generation == 2                      # a new pty (the kernel may reuse the number)
    port = serial.Serial(path, 115200, timeout=2)
    port.write(b"G4 P0\n?")
    assert port.readline() == b"ok\r\n"
    assert port.readline().startswith(b"<Idle|MPos:5.000,")   # the firmware ran on; X6 was lost
    port.close()


def test_marlin_on_a_pty(serve):
    server, world, path = serve("marlin-ring")
    port = serial.Serial(path, 250000, timeout=2)
    assert port.readline() == b"start\n"
    port.reset_input_buffer()
    port.write(b"N0 M110 N0*125\n")
    assert port.readline() == b"ok\n"
    port.close()


def test_simulate_command_serves_until_interrupted(tmp_path):
    import signal
    import subprocess
    import sys
    path = tmp_path / "ttyCLI"
    proc = subprocess.Popen([sys.executable, "-c", "from stringbot.cli import main; main()", "simulate",
                             "--machine", "grbl-ring", "--pty", str(path), "--record",
                             str(tmp_path / "rec.json")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        line = proc.stdout.readline()
        assert line.startswith(f"simulating grbl-ring on {path}")
        port = serial.Serial(str(path), 115200, timeout=2)
        assert port.read(len(BANNER)) == BANNER
        port.write(b"$I\n")
        assert port.readline() == b"[VER:1.1h.20190830:]\r\n"
        port.close()
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 130, err
    assert not path.exists()


def test_simulate_command_names_a_bad_option(tmp_path):
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", "simulate",
                           "--pty", str(tmp_path / "t"), "--faults", "reset@"], capture_output=True,
                          text=True, timeout=20)
    assert proc.returncode == 2
    assert "bad fault 'reset@'" in proc.stderr and "Traceback" not in proc.stderr


def test_realtime_mode_on_a_pty_takes_wall_clock_time(serve):
    server, world, path = serve(realtime=True)
    port = serial.Serial(path, 115200, timeout=3)
    assert port.read(len(BANNER)) == BANNER
    t0 = time.monotonic()
    port.write(b"G0 Y3\nG4 P0\n")                      # 3 mm at 500 mm/s^2: about 0.155 s
    assert port.readline() == b"ok\r\n" and port.readline() == b"ok\r\n"
    assert 0.1 < time.monotonic() - t0 < 2.0
    assert world.head_mm == 3.0
    port.close()
