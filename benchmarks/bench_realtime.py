"""Wall-clock figures of the simulator's realtime mode and read timeouts (the tests assert none).

For a 3 mm head move (about 0.155 s of profile at 500 mm/s^2) through ``sim://`` and through a
pty, prints the wall time from the write to the second ``ok`` against the emulator's virtual
time; then how long an idle ``sim://`` read with a 0.2 s timeout really takes.  No asserts.

    python benchmarks/bench_realtime.py [--repeat 5]
"""

import argparse
import tempfile
import threading
import time
from pathlib import Path

import serial

from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.pty import PtyServer
from firmware_protocol.urlhandler import protocol_sim, register

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
MOVE = b"G0 Y3\nG4 P0\n"


def timed_move(port, emulator):
    port.read(len(BANNER))
    v0, t0 = emulator.now, time.monotonic()
    port.write(MOVE)
    port.readline()
    port.readline()
    return time.monotonic() - t0, emulator.now - v0


def bench_sim_url():
    url = "sim://?machine=grbl-ring&realtime=1"
    protocol_sim.forget(url)
    port = serial.serial_for_url(url, timeout=3)
    try:
        return timed_move(port, protocol_sim.session(url).emulator)
    finally:
        port.close()
        protocol_sim.forget(url)


def bench_pty(folder):
    emulator, _world = build_emulator("grbl-ring")
    server = PtyServer(emulator, Path(folder) / "ttyBENCH", realtime=True).start()
    stop = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stop,), kwargs={"poll": 0.005}, daemon=True)
    thread.start()
    try:
        port = serial.Serial(server.path, 115200, timeout=3)
        try:
            return timed_move(port, emulator)
        finally:
            port.close()
    finally:
        stop.set()
        thread.join(5)
        server.close()


def bench_read_timeout(timeout=0.2):
    url = "sim://?machine=grbl-ring"
    protocol_sim.forget(url)
    port = serial.serial_for_url(url, timeout=timeout)
    try:
        port.read(len(BANNER))
        t0 = time.monotonic()
        port.read(10)
        return time.monotonic() - t0
    finally:
        port.close()
        protocol_sim.forget(url)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    register()
    with tempfile.TemporaryDirectory() as folder:
        for name, run in (("sim:// realtime", bench_sim_url), ("pty realtime", lambda: bench_pty(folder))):
            for _ in range(args.repeat):
                wall, virtual = run()
                print(f"{name:16s}: 3 mm move {wall * 1000:7.1f} ms wall, {virtual * 1000:7.1f} ms virtual")
    for _ in range(args.repeat):
        print(f"sim:// idle read, timeout 200 ms: returned after {bench_read_timeout() * 1000:6.1f} ms")


if __name__ == "__main__":
    main()
