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

    def start(machine="grbl-ring", faults=None, realtime=False, reopen_delay=0.2):
        emulator, world = build_emulator(machine, record=tmp_path / "rec.json", faults=faults)
        path = tmp_path / "ttySIM"
        server = PtyServer(emulator, path, realtime=realtime, reopen_delay=reopen_delay).start()
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
    assert port.readline().startswith(b"<Idle|MPos:4.995,")   # the firmware ran on; X6 was lost
    port.close()


def test_while_the_port_is_down_its_path_is_gone_and_no_other_pty_answers_there(serve):
    """A pulled cable takes the device node with it.  The path must not keep naming the closed pty:
    the system gives its number to the next pty opened (another simulator, a terminal), and a host
    that opened the path then would talk to that one (seen under load: a jog typed into another
    test's machine, a resume answered by nobody)."""
    server, world, path = serve(faults="disconnect@1", reopen_delay=3.0)
    port = serial.Serial(path, 115200, timeout=1)
    port.read(len(BANNER))
    port.write(b"G0 X5\n")                             # the cable is pulled as this line arrives
    deadline = time.monotonic() + 5
    while os.path.lexists(path) and time.monotonic() < deadline:
        time.sleep(0.01)
    port.close()
    assert not os.path.lexists(path)
    others = [os.openpty() for _ in range(4)]          # the freed number goes to one of these
    try:
        with pytest.raises(serial.SerialException, match="No such file"):
            serial.Serial(path, 115200, timeout=0.2)
        deadline = time.monotonic() + 10
        while not os.path.exists(path) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert server.generation == 2
        assert os.readlink(path) not in [os.ttyname(s) for _, s in others]
        port = serial.Serial(path, 115200, timeout=2)
        port.write(b"G4 P0\n")
        assert port.readline() == b"ok\r\n"           # the simulator, not one of the others
        port.close()
    finally:
        for m, s in others:
            os.close(m)
            os.close(s)


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


def test_realtime_mode_on_a_pty_runs_the_clock_at_wall_speed(serve):
    """No timed assert (figures: benchmarks/bench_realtime.py): the move takes its virtual time,
    and in realtime mode the virtual clock never runs ahead of the wall clock."""
    wall0 = time.monotonic()                         # before the emulator exists (its clock starts at 0)
    server, world, path = serve(realtime=True)
    port = serial.Serial(path, 115200, timeout=3)
    assert port.read(len(BANNER)) == BANNER
    port.write(b"G0 Y3\nG4 P0\n")                      # 3 mm at 500 mm/s^2: about 0.155 s
    assert port.readline() == b"ok\r\n" and port.readline() == b"ok\r\n"
    assert world.head_mm == 3.0
    assert server.emulator.now >= 0.15               # the sync waited for the whole move
    assert server.emulator.now <= time.monotonic() - wall0   # fast mode would jump ahead of the wall
    port.close()


def run_cli(*args):
    import subprocess
    import sys
    return subprocess.Popen([sys.executable, "-c", "from stringbot.cli import main; main()", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_simulate_refuses_an_existing_file_and_leaves_it_alone(tmp_path):
    plan = tmp_path / "plan.json"
    plan.write_text('{"format": "stringbot-plan"}')
    record = tmp_path / "rec.json"
    proc = run_cli("simulate", "--machine", "grbl-ring", "--pty", str(plan), "--record", str(record))
    out, err = proc.communicate(timeout=20)
    assert proc.returncode == 2, err
    assert err.count("\n") == 1 and str(plan) in err and "not a symlink to a pseudo-terminal" in err
    assert not plan.is_symlink() and plan.read_text() == '{"format": "stringbot-plan"}'
    assert not record.exists()                       # refused before anything was written
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.json"]


def test_pty_server_refuses_a_file_or_a_foreign_symlink_and_reuses_a_stale_pty_link(tmp_path):
    from firmware_protocol.pty import PtyPathError
    emulator, _world = build_emulator("grbl-ring")
    target = tmp_path / "t"
    target.write_text("x")
    elsewhere = tmp_path / "link"
    elsewhere.symlink_to(target)
    for path in (target, elsewhere):
        with pytest.raises(PtyPathError, match="not a symlink to a pseudo-terminal"):
            PtyServer(emulator, path).start()
    assert target.read_text() == "x" and os.readlink(elsewhere) == str(target)
    stale = tmp_path / "ttyOLD"
    stale.symlink_to("/dev/pts/999999")              # left by a killed server: dangling
    server = PtyServer(emulator, stale).start()
    try:
        assert os.readlink(stale) == server.slave_name
    finally:
        server.close()
    assert not os.path.lexists(stale)


def test_simulate_removes_its_symlink_on_sigterm(tmp_path):
    import signal
    path = tmp_path / "ttyTERM"
    proc = run_cli("simulate", "--machine", "grbl-ring", "--pty", str(path))
    try:
        line = proc.stdout.readline()
        assert line.startswith(f"simulating grbl-ring on {path}")
        assert os.readlink(path).startswith("/dev/pts/")
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "Traceback" not in err
    assert not os.path.lexists(path)


def _wind_through(tmp_path, sim, name):
    """Wind a small plan through ``sim``'s pty in a new process; the simulator's record must equal it."""
    import json
    import subprocess
    import sys

    from stringbot.planner import write_plan
    from test_wind_sim import small_plan

    plan = small_plan(n=12, seed=7)
    write_plan(plan, tmp_path / f"{name}.json")
    p = subprocess.run([sys.executable, "-c", "from stringbot.cli import main; main()", "wind",
                        str(tmp_path / f"{name}.json"), "--machine", "grbl-ring", "--port", str(sim.pty), "--yes"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    sim.stop()
    rec = json.loads(sim.record.read_text())
    assert [w["pin"] for w in rec["wraps"]] == plan.sequence and rec["collisions"] == []


def test_a_second_simulator_on_a_live_path_is_refused_and_the_first_keeps_serving(tmp_path):
    from test_wind_pty import Simulator

    first = Simulator(tmp_path, "grbl-ring")
    try:
        first.wait_port()
        pty, operator, lock = str(first.pty), str(first.pty) + ".operator", str(first.pty) + ".lock"
        target = os.readlink(pty)
        proc = run_cli("simulate", "--machine", "grbl-ring", "--pty", pty, "--record", str(tmp_path / "rec2.json"))
        out, err = proc.communicate(timeout=30)
        assert proc.returncode == 2, err
        lines = [x for x in err.splitlines() if x.strip()]
        assert len(lines) == 1 and "Traceback" not in err, err
        assert lines[0].startswith("stringbot: error: --pty:") and "in use by a running simulator" in lines[0]
        assert f"process {first.proc.pid}" in lines[0]
        assert first.proc.poll() is None                              # still running ...
        assert os.readlink(pty) == target and os.path.exists(operator)   # ... and reachable at its path
        assert open(lock).read().strip() == str(first.proc.pid)
        assert not (tmp_path / "rec2.json").exists()
        _wind_through(tmp_path, first, "plan")                         # the first one winds it exactly
    finally:
        first.stop()
    assert not any(os.path.lexists(p) for p in (pty, operator, lock))    # it cleaned up after itself


def test_the_path_of_a_killed_simulator_is_taken_over(tmp_path):
    from test_wind_pty import Simulator

    dead = Simulator(tmp_path, "grbl-ring")
    dead.proc.kill()
    dead.proc.wait()
    pty = str(dead.pty)
    assert os.path.lexists(pty) and os.path.exists(pty + ".lock")      # its leftovers, no holder
    dead.proc.stdout.close()
    dead.proc.stderr.close()
    alive = Simulator(tmp_path, "grbl-ring")
    try:
        deadline = time.monotonic() + 30          # the dead one's pts number may have been reused meanwhile
        while open(pty + ".lock").read().strip() != str(alive.proc.pid) and time.monotonic() < deadline:
            assert alive.proc.poll() is None, alive.proc.stderr.read()
            time.sleep(0.05)
        assert open(pty + ".lock").read().strip() == str(alive.proc.pid)
        alive.wait_port()
        _wind_through(tmp_path, alive, "plan")
    finally:
        alive.stop()
