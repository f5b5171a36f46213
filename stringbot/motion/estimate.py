"""How long a winding takes, how far the ring turns, and how much thread it uses.

Machine time sums a trapezoidal velocity profile per move (accelerate at the
axis' acceleration, cruise at the move's feed, decelerate), each move starting
and ending at rest: the hooking moves alternate between the two axes, so the
firmware's planner cannot blend them.  Dwell and tension pauses are added;
homing and the host's round trips are not.

The ring travel is set beside the shortest-arc lower bound: whatever the
hooking scheme, the ring must turn at least the shorter arc from facing one pin
of the sequence to facing the next.

The thread runs pin centre to pin centre (chords of the pin circle) plus, at
each pin, the arc it wraps round the pin (radius: pin plus thread, halved): the
turn of the thread there in its wrap direction (see
:mod:`stringbot.motion.hooking`), half a turn at the first and last pins.
"""

import math
from dataclasses import dataclass

__all__ = ["Estimate", "estimate", "move_seconds", "format_duration"]


@dataclass(frozen=True)
class Estimate:
    """Figures of one job.

    Attributes
    ----------
    seconds : float
        Machine time.
    ring_travel_deg : float
        Total ring axis travel.
    lower_bound_deg : float
        Shortest-arc lower bound of the ring travel.
    thread_m : float
        Thread length, metres, wraps included.
    wrap_m : float
        The part of ``thread_m`` that goes round pins.
    head_travel_mm : float
    steps : int
    moves : int
    """

    seconds: float
    ring_travel_deg: float
    lower_bound_deg: float
    thread_m: float
    wrap_m: float
    head_travel_mm: float
    steps: int
    moves: int

    @property
    def travel_ratio(self):
        """Ring travel over its lower bound (1.0 when the bound is 0)."""
        return self.ring_travel_deg / self.lower_bound_deg if self.lower_bound_deg else 1.0

    def as_dict(self):
        return {"seconds": self.seconds, "ring_travel_deg": self.ring_travel_deg,
                "lower_bound_deg": self.lower_bound_deg, "travel_ratio": self.travel_ratio,
                "thread_m": self.thread_m, "wrap_m": self.wrap_m, "head_travel_mm": self.head_travel_mm,
                "steps": self.steps, "moves": self.moves}


def move_seconds(distance, feed_per_min, accel):
    """Time of a move from rest to rest with a trapezoidal (or triangular) velocity profile.

    Parameters
    ----------
    distance : float
        Axis units (>= 0).
    feed_per_min : float
        Cruise speed, axis units per minute.
    accel : float
        Axis units per second squared.
    """
    if distance <= 0:
        return 0.0
    v = feed_per_min / 60.0
    if distance >= v * v / accel:               # reaches cruise speed
        return distance / v + v / accel
    return 2.0 * math.sqrt(distance / accel)    # triangle


def format_duration(seconds):
    """``1h 02m 03s`` / ``2m 03s`` / ``4.2s``."""
    if seconds < 60:
        return f"{seconds:.1f}s"
    s = round(seconds)
    h, rest = divmod(s, 3600)
    m, s = divmod(rest, 60)
    return f"{h}h {m:02d}m {s:02d}s" if h else f"{m}m {s:02d}s"


def _turn(prev, pin, nxt, pins, direction):
    """Angle (radians) the thread turns round ``pin`` in ``direction``."""
    if prev is None or nxt is None:
        return math.pi
    da, db = (prev - pin) % pins, (nxt - pin) % pins
    plus = math.pi - math.pi * (da - db) / pins
    return plus if direction > 0 else 2 * math.pi - plus


def estimate(plan, machine, *, steps=None):
    """Machine time, ring travel (and its lower bound) and thread length of winding ``plan``.

    Parameters
    ----------
    plan : stringbot.planner.Plan
    machine : firmware_protocol.machine.Machine
    steps : list of HookStep, optional
        Already computed by :func:`~stringbot.motion.hook_steps` (saves the work).

    Returns
    -------
    Estimate
    """
    from .hooking import hook_steps, thread_neighbours
    if steps is None:
        steps = hook_steps(plan, machine)
    ring_feed, ring_acc = machine["ring.feed_deg_per_min"], machine["ring.accel_deg_per_s2"]
    head_feed, head_acc = machine["head.feed_mm_per_min"], machine["head.accel_mm_per_s2"]
    seconds = ring_travel = head_travel = 0.0
    n_moves = 0
    ring, head = (steps[0].moves[0].ring_deg, steps[0].moves[0].head_mm) if steps else (0.0, 0.0)
    for step in steps:
        for mv in step.moves:
            dr, dh = abs(mv.ring_deg - ring), abs(mv.head_mm - head)
            t_ring = move_seconds(dr, mv.feed or ring_feed, ring_acc)
            t_head = move_seconds(dh, mv.feed or head_feed, head_acc)
            seconds += max(t_ring, t_head)
            ring_travel += dr
            head_travel += dh
            ring, head = mv.ring_deg, mv.head_mm
            n_moves += 1
        seconds += step.dwell_s

    pins, pitch = machine.pins, machine.pitch_deg
    seq = [int(p) for p in plan.sequence]
    bound = sum(min((b - a) % pins, (a - b) % pins) for a, b in zip(seq[:-1], seq[1:])) * pitch
    diameter = machine["ring.diameter_mm"]
    chords = sum(diameter * math.sin(math.pi * ((b - a) % pins) / pins) for a, b in plan.chord_list())
    radius = (machine["ring.pin_diameter_mm"] + machine["thread.diameter_mm"]) / 2.0
    wraps = 0.0
    around = thread_neighbours(plan)
    for step in steps:
        prev, nxt = around[step.index]
        wraps += radius * _turn(prev, step.pin, nxt, pins, step.direction)
    return Estimate(seconds=seconds, ring_travel_deg=ring_travel, lower_bound_deg=bound,
                    thread_m=(chords + wraps) / 1000.0, wrap_m=wraps / 1000.0,
                    head_travel_mm=head_travel, steps=len(steps), moves=n_moves)
