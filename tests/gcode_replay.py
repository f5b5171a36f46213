"""A small G-code replayer for tests: feeds the emitted program's motion to the physical world.

It understands what :mod:`stringbot.motion.gcode` writes: ``G0``/``G1`` with
axis words and ``F``, ``G4`` (ignored: no motion), ``G10 L20 P1`` and ``G92``
(declare the current position), ``$H`` and ``G28`` (homing as the emulators do
it: head to ``home_head_mm``, ring to ``home_ring_deg`` on the nearest turn), ``G21``/``G90``/``G94``,
``M2``/``M400``/``M117`` and ``;`` comments.  Anything else fails the test.
"""

import re

from firmware_protocol.world import World

WORD = re.compile(r"([A-Z])(-?\d+(?:\.\d*)?)")


def replay(text, machine, *, world=None):
    """Replay ``text`` on a fresh :class:`World` (or ``world``); return the world and the ring range."""
    w = world or World(machine)
    ring_axis, head_axis = machine["controller.ring_axis"], machine["controller.head_axis"]
    phys = {ring_axis: w.ring_deg, head_axis: w.head_mm}
    offset = {ring_axis: 0.0, head_axis: 0.0}          # work = physical + offset (turns, after homing)
    lo = hi = w.ring_deg
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.split(";", 1)[0].strip()
        if not line:
            continue
        if line == "$H" or line.startswith("G28"):
            # like the emulators: the head to its switch, then the ring to its switch (the nearest
            # turn), and the firmware's position := the physical one
            home_ring = machine["controller.home_ring_deg"]
            home_head = machine["controller.home_head_mm"]
            home_head = machine["head.in_mm"] if home_head is None else home_head
            ring_at = home_ring + round((phys[ring_axis] - home_ring) / 360.0) * 360.0
            w.move(phys[ring_axis], home_head)
            w.move(ring_at, home_head)
            phys = {ring_axis: ring_at, head_axis: home_head}
            offset = {ring_axis: 0.0, head_axis: 0.0}
            lo, hi = min(lo, ring_at), max(hi, ring_at)
            continue
        if line.startswith("M117"):
            continue
        words = WORD.findall(line)
        assert "".join(c + v for c, v in words) == line.replace(" ", ""), f"line {n}: cannot parse {raw!r}"
        code = words[0][0] + words[0][1]
        args = {c: float(v) for c, v in words[1:]}
        if code in ("G0", "G1"):
            target = dict(phys)
            for axis in (ring_axis, head_axis):
                if axis in args:
                    target[axis] = args[axis] - offset[axis]
            assert set(args) <= {ring_axis, head_axis, "F"}, f"line {n}: unexpected axis in {raw!r}"
            w.move(target[ring_axis], target[head_axis])
            phys = target
            lo, hi = min(lo, w.ring_deg), max(hi, w.ring_deg)
        elif code == "G10" or code == "G92":
            for axis in (ring_axis, head_axis):
                if axis in args:
                    offset[axis] = args[axis] - phys[axis]
        elif code in ("G4", "G21", "G90", "G94", "M2", "M400"):
            pass
        else:
            raise AssertionError(f"line {n}: unexpected command {raw!r}")
    return w, (lo, hi)
