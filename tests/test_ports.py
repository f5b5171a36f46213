"""Network ports: socket:// and rfc2217:// against the simulator served on a local TCP port.

The simulated machine (``sim://``) is served by :class:`firmware_protocol.tcp.TcpBridge`
in this process (raw bytes, or RFC 2217 through pyserial's own PortManager), or by
``socat`` in front of ``stringbot simulate --pty``; ``stringbot wind`` runs in its own
process, and the simulated world's record must equal the plan.
"""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time

import pytest
import serial

from firmware_protocol import urlhandler
from firmware_protocol.tcp import TcpBridge
from stringbot.links.ports import open_port, sim_url
from stringbot.planner.plan_file import write_plan
from test_cli_plan import one_error_line, run
from test_gcode_replay import make_plan, random_sequence

SEQ = random_sequence(40, seed=21)


@pytest.fixture
def plan_file(tmp_path):
    path = tmp_path / "p.json"
    write_plan(make_plan(SEQ), path)
    return path


@pytest.fixture
def served(tmp_path):
    bridges = []

    def serve(machine="grbl-ring", **kw):
        urlhandler.register()
        record = tmp_path / f"rec{len(bridges)}.json"
        port = serial.serial_for_url(sim_url(machine, record=record), timeout=0)
        bridge = TcpBridge(port, **kw).start()
        bridges.append((bridge, port))
        return bridge, record
    yield serve
    for bridge, port in bridges:
        bridge.close()
        port.close()
        urlhandler.protocol_sim.forget()


@pytest.mark.parametrize("rfc2217, nodelay", [(False, True), (False, False), (True, True)])
def test_wind_through_a_network_port(tmp_path, plan_file, served, rfc2217, nodelay):
    bridge, record = served(rfc2217=rfc2217, nodelay=nodelay)
    code, out, err = run("wind", plan_file, "--machine", "grbl-ring", "--port", bridge.url, "--yes")
    assert code == 0, err
    assert f"wound {len(SEQ)} pins" in out
    rec = json.loads(record.read_text())
    assert [w["pin"] for w in rec["wraps"]] == SEQ and rec["collisions"] == []


def test_a_socket_port_sends_at_once_acks_at_once_and_counts_what_waits(served):
    bridge, _ = served()
    port = open_port(bridge.url)
    try:
        sock = port._socket
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0
        port.write(b"$I\n")
        deadline = time.monotonic() + 10
        while port.in_waiting < 10 and time.monotonic() < deadline:
            time.sleep(0.01)
        n = port.in_waiting
        assert n >= 10, "in_waiting does not count the bytes waiting"
        assert len(port.read(n)) == n
    finally:
        port.close()


def test_rfc2217_opens_without_a_write_timeout(served):
    bridge, _ = served(rfc2217=True)
    port = open_port(bridge.url)
    try:
        assert port.write_timeout is None
        port.write(b"$I\n")
        got = b""
        deadline = time.monotonic() + 10
        while b"ok" not in got and time.monotonic() < deadline:
            got += port.read(64)
        assert b"[VER:" in got and b"ok" in got
    finally:
        port.close()


@pytest.mark.skipif(shutil.which("socat") is None, reason="socat not installed (apt-get install socat)")
def test_wind_through_socat_in_front_of_a_pty(tmp_path, plan_file):
    from test_wind_pty import Simulator
    sim = Simulator(tmp_path, "grbl-ring")
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    tcp = s.getsockname()[1]
    s.close()
    bridge = subprocess.Popen(["socat", f"TCP-LISTEN:{tcp},reuseaddr,bind=127.0.0.1", f"FILE:{sim.pty},raw,echo=0"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", tcp), timeout=0.2).close()
                break
            except OSError:
                time.sleep(0.05)
        # socat serves one connection and exits: start it afresh for the winding
        bridge.wait(timeout=10)
        bridge = subprocess.Popen(["socat", f"TCP-LISTEN:{tcp},reuseaddr,bind=127.0.0.1",
                                   f"FILE:{sim.pty},raw,echo=0"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(0.3)
        code, out, err = run("wind", plan_file, "--machine", "grbl-ring", "--port", f"socket://127.0.0.1:{tcp}", "--yes")
        assert code == 0, err
        pins, collisions = sim.wraps()
        assert pins == SEQ and not collisions
    finally:
        bridge.send_signal(signal.SIGTERM)
        bridge.wait()
        sim.stop()


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


@pytest.mark.parametrize("url, words", [
    ("socket://127.0.0.1:{free}", "the connection was refused"),
    ("rfc2217://127.0.0.1:{free}", "the connection was refused"),
    ("socket://no-such-host.invalid:23", "the host name"),
    ("socket://localhost", "expected socket://HOST:PORT"),
    ("socket://localhost:99999", "expected socket://HOST:PORT"),
    ("rfc2217://localhost:x", "expected rfc2217://HOST:PORT"),
])
def test_an_unreachable_or_malformed_network_port_is_one_line_exit_2(plan_file, url, words):
    code, _, err = run("wind", plan_file, "--machine", "grbl-ring", "--port", url.format(free=free_port()), "--yes")
    one_error_line(code, err, words)
    assert "resume with" not in err


@pytest.mark.parametrize("make, words", [
    (lambda d: (d / "notes.txt").write_text("x\n") and d / "notes.txt", "is a regular file, not a serial device"),
    (lambda d: (d / "folder").mkdir() or d / "folder", "is a folder, not a serial device"),
    (lambda d: os.mkfifo(d / "fifo") or d / "fifo", "is a FIFO, not a serial device"),
    (lambda d: "/dev/null", "is not a serial device (it takes no serial settings)"),
])
@pytest.mark.parametrize("command", ["wind", "machines check"])
def test_a_port_that_is_not_a_serial_device_is_bad_input(tmp_path, plan_file, make, words, command):
    port = str(make(tmp_path))
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    args = ["wind", plan_file, "--machine", "grbl-ring", "--yes"] if command == "wind" else \
        ["machines", "check", "grbl-ring"]
    code, _, err = run(*args, "--port", port)
    one_error_line(code, err, words)
    assert "expected a serial device (e.g. /dev/ttyUSB0, COM3) or a URL" in err
    assert {name: (tmp_path / name).read_bytes() for name in before} == before


def test_stringbot_links_imports_where_fcntl_and_termios_do_not_exist():
    """Windows has no fcntl, termios, tty or pty: every module of stringbot.links (and the CLI) must
    import without them (pyserial and the SDK, third-party, are loaded first as installed here)."""
    code = r'''
import importlib, pkgutil, sys
import click, dynamixel_sdk, serial, serial.tools.list_ports
POSIX = ("fcntl", "termios", "tty", "pty")
class NotHere:
    def find_spec(self, name, path=None, target=None):
        if name in POSIX:
            raise ImportError(f"No module named {name!r}")
for name in POSIX:
    sys.modules.pop(name, None)
sys.meta_path.insert(0, NotHere())
import stringbot.links
for info in pkgutil.iter_modules(stringbot.links.__path__):
    importlib.import_module("stringbot.links." + info.name)
import stringbot.cli, stringbot.winding, firmware_protocol.pty
print("imported", ", ".join(sorted(m for m in sys.modules if m.startswith("stringbot.links."))))
'''
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "stringbot.links.ports" in p.stdout and "stringbot.links.dynamixel_bus" in p.stdout
