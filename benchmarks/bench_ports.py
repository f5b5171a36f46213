"""Pins per second through network ports: socket:// and rfc2217:// against the simulator.

The simulated machine (``sim://``, virtual clock) is served on a local TCP port,
by :class:`firmware_protocol.tcp.TcpBridge` (raw bytes, or RFC 2217 through
pyserial's PortManager) or by ``socat`` bridging TCP to ``stringbot simulate
--pty``; the host is ``stringbot wind --port URL`` in its own process, as a
user runs it.  Prints one row per way of serving.

    python benchmarks/bench_ports.py [--pins 200] [--machine grbl-ring]
"""

import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STRINGBOT = [sys.executable, "-c", "import sys; from stringbot.cli import main; main(sys.argv[1:])"]
sys.path.insert(0, str(ROOT / "benchmarks"))
from matrix_user import homes  # noqa: E402


def plan_file(folder, pins):
    sys.path.insert(0, str(ROOT / "tests"))
    from test_gcode_replay import make_plan, random_sequence

    from stringbot.planner.plan_file import write_plan
    path = Path(folder) / "bench.json"
    write_plan(make_plan(random_sequence(pins, seed=11)), path)
    return path


def wind(plan, machine, url):
    journal = Path(str(plan) + f".{time.monotonic_ns()}.journal")
    t = time.monotonic()
    p = subprocess.run(STRINGBOT + ["wind", str(plan), "--machine", machine, "--port", url, "--yes",
                                    "--journal", str(journal)] + (["--head-side", "in"] if homes(machine) else []),
                       capture_output=True, text=True, timeout=3600)
    wall = time.monotonic() - t
    if p.returncode != 0:
        return f"failed (exit {p.returncode}): {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ''}"
    m = re.search(r"\(([\d.]+) pins/s\)", p.stdout)
    return f"{m.group(1)} pins/s (command {wall:.1f} s)"


def bridged(plan, machine, *, rfc2217, nodelay):
    import serial

    from firmware_protocol import urlhandler
    from firmware_protocol.tcp import TcpBridge
    from stringbot.links.ports import sim_url
    urlhandler.register()
    port = serial.serial_for_url(sim_url(machine) + f"&record={plan}.{rfc2217}{nodelay}.rec.json", timeout=0)
    bridge = TcpBridge(port, rfc2217=rfc2217, nodelay=nodelay).start()
    try:
        return bridge.url, wind(plan, machine, bridge.url)
    finally:
        bridge.close()
        port.close()


def through_socat(plan, machine, folder):
    socat = shutil.which("socat")
    if not socat:
        return "socat://", "socat not installed (apt-get install socat)"
    pty = Path(folder) / "pty"
    sim = subprocess.Popen(STRINGBOT + ["simulate", "--machine", machine, "--pty", str(pty)],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while not pty.exists():
        time.sleep(0.05)
    import socket
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    tcp = s.getsockname()[1]
    s.close()
    bridge = subprocess.Popen([socat, f"TCP-LISTEN:{tcp},reuseaddr,bind=127.0.0.1", f"FILE:{pty},raw,echo=0"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(0.5)
    try:
        url = f"socket://127.0.0.1:{tcp}"
        return url + " (socat -> pty)", wind(plan, machine, url)
    finally:
        bridge.send_signal(signal.SIGTERM)
        bridge.wait()
        sim.send_signal(signal.SIGINT)
        sim.wait()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pins", type=int, default=200)
    ap.add_argument("--machine", default="grbl-ring")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        plan = plan_file(folder, args.pins)
        print(f"{args.pins} pins on {args.machine}; load average {os.getloadavg()[0]:.2f}")
        rows = [("socket:// (TcpBridge, TCP_NODELAY)",) + bridged(plan, args.machine, rfc2217=False, nodelay=True),
                ("socket:// (TcpBridge, Nagle on)",) + bridged(plan, args.machine, rfc2217=False, nodelay=False),
                ("rfc2217:// (PortManager, TCP_NODELAY)",) + bridged(plan, args.machine, rfc2217=True, nodelay=True),
                ("socat",) + through_socat(plan, args.machine, folder)]
        for name, url, result in rows:
            print(f"{name:<40} {result}")


if __name__ == "__main__":
    main()
