"""Per-layer and per-colour figures of a colour plan: thread per spool, machine time, where to tie on.

Each layer of a colour plan is its own thread, wound after the one below it
(see :mod:`stringbot.planner.plan_file`); the planner lays a colour in runs,
so one colour may have several layers (:func:`colour_estimates` sums them).  A layer's thread runs along its
chords and round its pins (as in :mod:`.estimate`); its machine time is that
of its steps (the first one's ring turn from where the layer below ended
included), by the same trapezoid model; the spool change itself (the
operator's work) is not counted.
"""

import math
from dataclasses import dataclass

from .estimate import _turn, move_seconds
from .hooking import hook_steps, thread_neighbours

__all__ = ["LayerEstimate", "ColourEstimate", "layer_estimates", "colour_estimates"]


@dataclass(frozen=True)
class LayerEstimate:
    """Figures of one layer.

    Attributes
    ----------
    index : int
        Layer, from 0 (the bottom).
    color : str
    first_step : int
        Index of its first step in the plan's sequence.
    steps : int
        Pins it hooks.
    tie_on_pin : int
        Where its thread is tied on (its first pin).
    thread_m : float
        Thread, metres, wraps included.
    seconds : float
        Machine time of its steps.
    """

    index: int
    color: str
    first_step: int
    steps: int
    tie_on_pin: int
    thread_m: float
    seconds: float


def layer_estimates(plan, machine, *, steps=None):
    """One :class:`LayerEstimate` per layer of ``plan`` wound on ``machine``."""
    if steps is None:
        steps = hook_steps(plan, machine)
    ring_feed, ring_acc = machine["ring.feed_deg_per_min"], machine["ring.accel_deg_per_s2"]
    head_feed, head_acc = machine["head.feed_mm_per_min"], machine["head.accel_mm_per_s2"]
    pins, diameter = machine.pins, machine["ring.diameter_mm"]
    radius = (machine["ring.pin_diameter_mm"] + machine["thread.diameter_mm"]) / 2.0
    around = thread_neighbours(plan)
    per_step = []
    ring, head = (steps[0].moves[0].ring_deg, steps[0].moves[0].head_mm) if steps else (0.0, 0.0)
    for step in steps:
        t = step.dwell_s
        for mv in step.moves:
            dr, dh = abs(mv.ring_deg - ring), abs(mv.head_mm - head)
            t += max(move_seconds(dr, mv.feed or ring_feed, ring_acc), move_seconds(dh, mv.feed or head_feed, head_acc))
            ring, head = mv.ring_deg, mv.head_mm
        prev, nxt = around[step.index]
        per_step.append((t, radius * _turn(prev, step.pin, nxt, pins, step.direction)))
    out = []
    ends = list(plan.layer_starts[1:]) + [len(plan.sequence)]
    for k, (color, a, b) in enumerate(zip(plan.colors, plan.layer_starts, ends)):
        seq = plan.sequence[a:b]
        chords = sum(diameter * math.sin(math.pi * ((q - p) % pins) / pins) for p, q in zip(seq[:-1], seq[1:]))
        wraps = sum(w for _, w in per_step[a:b])
        out.append(LayerEstimate(index=k, color=color, first_step=a, steps=b - a, tie_on_pin=int(seq[0]),
                                 thread_m=(chords + wraps) / 1000.0, seconds=sum(t for t, _ in per_step[a:b])))
    return out


@dataclass(frozen=True)
class ColourEstimate:
    """Figures of one thread colour over all its layers (runs).

    Attributes
    ----------
    color : str
    runs : int
        Its layers.
    steps : int
        Pins they hook.
    thread_m : float
        Thread of that colour, metres, wraps included (what to have on its spool).
    seconds : float
        Machine time of its steps.
    """

    color: str
    runs: int
    steps: int
    thread_m: float
    seconds: float


def colour_estimates(plan, machine, *, layers=None):
    """One :class:`ColourEstimate` per thread colour of ``plan``, in order of first use."""
    layers = layer_estimates(plan, machine) if layers is None else layers
    out = []
    for color in dict.fromkeys(le.color for le in layers):
        mine = [le for le in layers if le.color == color]
        out.append(ColourEstimate(color=color, runs=len(mine), steps=sum(le.steps for le in mine),
                                  thread_m=sum(le.thread_m for le in mine), seconds=sum(le.seconds for le in mine)))
    return out
