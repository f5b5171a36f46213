"""Figures for the simulated G-code firmwares: lines per second and virtual seconds per pin.

Runs a hand-written hooking pattern (ring to the gap, head out, one pitch,
head in, sync) for many pins against each emulator directly and through
``sim://``, and prints throughput.  No asserts: a script that prints figures.

    python benchmarks/bench_emulator.py [--pins 500]
"""

import argparse
import time

import serial

from firmware_protocol import marlin as mc
from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.emulators.testing import collect
from firmware_protocol.machine import load_machine
from firmware_protocol.urlhandler import protocol_sim, register


def hook_lines(machine, pins):
    ring, head = machine["controller.ring_axis"], machine["controller.head_axis"]
    pitch = machine.pitch_deg
    h_in, h_out = machine["head.in_mm"], machine["head.out_mm"]
    sync = "M400" if machine["controller.dialect"] == "marlin" else "G4 P0"
    for k in range(pins):
        pin = (k * 37) % machine.pins
        a = machine.pin_angle(pin)
        feed = f" F{machine['ring.feed_deg_per_min']:.0f}" if sync == "M400" and k == 0 else ""
        yield [f"G0 {ring}{a - pitch / 2:.4f}{feed}", f"G0 {head}{h_out:.3f}", f"G0 {ring}{a + pitch / 2:.4f}",
               f"G0 {head}{h_in:.3f}", sync]


def bench_direct(name, pins):
    machine = load_machine(name)
    emu, world = build_emulator(machine)
    emu.transmit()
    marlin = machine["controller.dialect"] == "marlin"
    ok = b"ok\n" if marlin else b"ok\r\n"
    if machine["controller.homing"]:
        emu.receive(b"G28\n" if marlin else b"$H\n")   # home: belief = physical
        got = b""
        while not got.endswith(ok):
            got += collect(emu, len(ok))
    n = 0
    t0 = time.perf_counter()
    for lines in hook_lines(machine, pins):
        for line in lines:
            n += 1
            data = (mc.numbered(n, line) if marlin else line).encode() + b"\n"
            emu.receive(data)
            got = collect(emu, len(ok))
            while not got.endswith(ok):          # Marlin: busy keepalives before a long M400's ok
                got += collect(emu, len(ok))
    wall = time.perf_counter() - t0
    print(f"{name:14s} direct : {n / wall:8.0f} lines/s, {pins / wall:7.0f} pins/s, "
          f"{emu.now / pins:.3f} virtual s/pin, wraps {len(world.wraps)}, collisions {len(world.collisions)}")


def bench_url(name, pins):
    register()
    machine = load_machine(name)
    url = f"sim://?machine={name}"
    port = serial.serial_for_url(url, timeout=1)
    port.read(2000)
    if machine["controller.homing"]:
        port.write(b"$H\n")
        while not port.readline().startswith(b"ok"):
            pass
    n = 0
    t0 = time.perf_counter()
    for lines in hook_lines(machine, pins):
        for line in lines:
            port.write(line.encode() + b"\n")
            n += 1
            while not port.readline().startswith(b"ok"):
                pass
    wall = time.perf_counter() - t0
    port.close()
    protocol_sim.forget(url)
    print(f"{name:14s} sim:// : {n / wall:8.0f} lines/s, {pins / wall:7.0f} pins/s")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pins", type=int, default=500)
    args = parser.parse_args()
    for name in ("grbl-ring", "grblhal-ring", "marlin-ring"):
        bench_direct(name, args.pins)
    for name in ("grbl-ring", "grblhal-ring"):
        bench_url(name, args.pins)


if __name__ == "__main__":
    main()
