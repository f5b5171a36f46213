"""Safe moves by construction: what a move may do, checked on the moves themselves.

The physical model (docs/design.md) allows three kinds of move:

* a **ring move**: the ring turns with the head fully IN or fully OUT (at
  ``head.in_mm`` or ``head.out_mm``), the head does not move;
* a **head move**: the head moves with the ring at rest; if it crosses the pin
  circle, the ring stands at a gap (within the machine's gap tolerance);
* nothing else: no move combines the two.

:func:`check_moves` checks a path of moves against these rules (the hooking
moves of :func:`~stringbot.motion.hook_steps` keep them from the job's start,
and the tests check every bundled machine); :func:`side` and
:func:`gap_offset_deg` say where a head and a ring stand.
"""

import math

__all__ = ["side", "gap_offset_deg", "check_moves", "UnsafeMove"]


class UnsafeMove(ValueError):
    """A move that breaks the rules of :mod:`stringbot.motion.safety`."""


def side(machine, head_mm):
    """"in", "out" or "on" (the eyelet exactly on the pin circle) for a head position."""
    d = (head_mm - machine.circle_mm) * (1.0 if machine["head.out_mm"] > machine["head.in_mm"] else -1.0)
    return "on" if d == 0 else ("out" if d > 0 else "in")


def gap_offset_deg(machine, ring_deg):
    """``(gap, degrees from its centre)``: the gap nearest the station at ``ring_deg``
    (gap ``g`` lies between pins ``g`` and ``g + 1``, modulo the pin count)."""
    p = (ring_deg - machine["ring.pin0_angle_deg"]) / machine.pitch_deg
    g = math.floor(p)
    return g % machine.pins, abs(p - (g + 0.5)) * machine.pitch_deg


def check_moves(machine, start, moves, *, eps=1e-6):
    """Raise :class:`UnsafeMove` at the first move of ``moves`` (from ``start``, a
    ``(ring_deg, head_mm)``) that combines the axes, turns the ring with the head neither
    fully IN nor fully OUT, or takes the head across the pin circle away from a gap."""
    h_in, h_out = machine["head.in_mm"], machine["head.out_mm"]
    tol = machine.gap_tolerance_deg
    ring, head = start
    for n, mv in enumerate(moves):
        dr, dh = abs(mv.ring_deg - ring) > eps, abs(mv.head_mm - head) > eps
        if dr and dh:
            raise UnsafeMove(f"move {n + 1} turns the ring ({ring:g} -> {mv.ring_deg:g}) and moves the "
                             f"head ({head:g} -> {mv.head_mm:g}) together")
        if dr and min(abs(head - h_in), abs(head - h_out)) > eps:
            raise UnsafeMove(f"move {n + 1} turns the ring with the head at {head:g} mm, neither IN "
                             f"({h_in:g}) nor OUT ({h_out:g})")
        if dh and side(machine, head) != side(machine, mv.head_mm):
            gap, off = gap_offset_deg(machine, ring)
            if off > tol + eps:
                raise UnsafeMove(f"move {n + 1} takes the head across the pin circle at ring {ring:g}, "
                                 f"{off:.3f} deg from gap {gap}'s centre (tolerance {tol:.3f})")
        ring, head = mv.ring_deg, mv.head_mm
