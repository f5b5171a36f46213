"""Plan + machine -> hooking moves, by the physical model of docs/design.md.

To hook pin ``j`` with wrap direction ``d`` (+1 or -1), with the head IN:

1. turn the ring until the gap on the approach side of ``j`` faces the head
   station (the gap between ``j - 1`` and ``j`` for ``d = +1``, between ``j``
   and ``j + 1`` for ``d = -1``);
2. head OUT through that gap;
3. turn the ring one pitch in direction ``d``, so the station passes behind ``j``;
4. head IN through the other gap.

The head crosses the pin circle only in steps 2 and 4, with the ring at a gap
centre, so it never touches a pin.

Positions are planned in *pin units* (``p = (ring_deg - pin0_angle_deg) /
pitch_deg``: pin ``k`` faces the station at ``p = k``, a gap at ``k + 0.5``),
unwrapped, so that the ring axis can be kept within ``ring.travel_deg`` of
``pin0_angle_deg`` (a servo has a multi-turn limit).  Between pins the ring
turns the shorter way to the next approach gap unless that would leave the
allowed travel; then it turns the other way.

The wrap direction
------------------
Pins are numbered clockwise as the plan is drawn.  Seen from pin ``j``, every
chord to a pin ``x`` leaves at the inscribed angle ``pi * ((x - j) mod N) / N``
from the tangent pointing towards pin ``j + 1``: chords to near-higher pins
leave almost along that tangent, chords to near-lower pins almost along the
opposite one.  The thread comes in from ``a`` and leaves to ``b`` and must go
round the *outside* of the pin.  With ``da = (a - j) mod N`` and ``db = (b -
j) mod N`` it turns by ``pi - pi * |da - db| / N`` (less than half a turn, the
two chords do not cross) in one sense and by more than half a turn (the
thread crosses itself in a loop round the pin) in the other.  Going round the
outside from the incoming side to the outgoing side is the short turn, so:

* ``db < da`` (``b`` lies before ``a`` going round from ``j`` towards higher
  numbers): the thread arrives on the lower-number side of ``j`` and leaves on
  the higher: direction +1 ("cw": the ring axis increases while the head is
  out; the thread turns clockwise as the plan is drawn);
* ``db > da``: direction -1 ("ccw");
* ``a == b`` (there and back): either way turns exactly half a turn; the one
  whose approach gap is nearer is taken;
* the first pin (the operator ties the thread end on): leave on ``b``'s side,
  +1 when ``db <= N / 2``; the last pin: arrive on ``a``'s side, +1 when
  ``da >= N / 2``.  In a colour plan every layer is its own thread: its first
  and last pins are a thread's ends.

``[winding] wrap_direction = "cw"`` or ``"ccw"`` in the machine file fixes the
direction for every pin instead.
"""

import math
from dataclasses import dataclass, field

from ..errors import BadInput

__all__ = ["Move", "HookStep", "hook_steps", "wrap_direction", "check_plan_fits", "thread_neighbours"]


@dataclass(frozen=True)
class Move:
    """One straight move to an absolute target, in machine axis units.

    Attributes
    ----------
    ring_deg : float
        Ring axis target, degrees (unwrapped: may exceed 360).
    head_mm : float
        Head axis target, mm.
    feed : float or None
        Feed rate, axis units per minute (None: the firmware's current feed).
    """

    ring_deg: float
    head_mm: float
    feed: float | None = None


@dataclass
class HookStep:
    """Everything the machine does for one pin of the sequence.

    Attributes
    ----------
    index : int
        Position of the pin in ``plan.sequence``.
    pin : int
    direction : int
        +1 when the ring axis increases while the head is out, -1 when it decreases.
    moves : list of Move
        From where the previous step left the machine, through hooking the pin,
        ending head IN.  The last four are always: the ring to the approach gap
        (head IN; possibly where it already is), head OUT, the ring one pitch,
        head IN.  The first step starts with the head brought IN where the ring is.
    dwell_s : float
        Pause after the moves (thread settling, tension pauses), seconds.
    total : int or None
        Number of steps of the whole job (for progress display).
    """

    index: int
    pin: int
    direction: int
    moves: list[Move] = field(default_factory=list)
    dwell_s: float = 0.0
    total: int | None = None


def check_plan_fits(plan, machine):
    """Raise :class:`BadInput` unless ``plan`` can be wound on ``machine``."""
    if not plan.connected:
        raise BadInput("plan is a disconnected chord set (field 'connected' is false); expected a "
                       "connected plan with a 'sequence' (plan again without --disconnected)")
    if plan.frame != "circle":
        raise BadInput(f"plan is for a {plan.frame} frame but machine {machine.name!r} winds a ring; expected a "
                       "plan made with --frame circle (wind a square frame by hand: stringbot pins)")
    if plan.pins != machine.pins:
        raise BadInput(f"plan has {plan.pins} pins but machine {machine.name!r} has ring.pins = "
                       f"{machine.pins}; expected the same pin count (plan with --pins {machine.pins} "
                       f"or pick another machine)")
    if len(plan.sequence) < 1:
        raise BadInput("plan field 'sequence' is empty; expected at least one pin")


def wrap_direction(prev, pin, nxt, pins):
    """The wrap direction at ``pin`` that takes the thread round its outside without crossing.

    Parameters
    ----------
    prev, nxt : int or None
        The pins before and after ``pin`` in the sequence (None at the ends).
    pin : int
    pins : int
        Number of pins on the ring.

    Returns
    -------
    int or None
        +1 or -1; None when both directions are equally good (``prev == nxt``
        or a lone pin), so the caller may pick the cheaper one.
    """
    if prev is None and nxt is None:
        return None
    if prev is None:
        return 1 if (nxt - pin) % pins <= pins / 2 else -1
    if nxt is None:
        return 1 if (prev - pin) % pins >= pins / 2 else -1
    da, db = (prev - pin) % pins, (nxt - pin) % pins
    if da == db:
        return None
    return 1 if db < da else -1


def thread_neighbours(plan):
    """``(prev, next)`` pin of each step along its own thread (None at a thread's ends: a colour
    plan's layers are separate threads)."""
    seq = [int(p) for p in plan.sequence]
    starts = set(getattr(plan, "layer_starts", [0]))
    ends = {s - 1 for s in starts} | {len(seq) - 1}
    return [(seq[k - 1] if k not in starts else None, seq[k + 1] if k not in ends else None)
            for k in range(len(seq))]


def _fixed_direction(machine):
    return {"auto": None, "cw": 1, "ccw": -1}[machine["winding.wrap_direction"]]


def _nearest_allowed(target, p_cur, direction, pins, limit):
    """Unwrapped approach position ``target + m * pins`` nearest ``p_cur`` with the hook in bounds."""
    m0 = round((p_cur - target) / pins)
    best = None
    for m in range(m0 - 2, m0 + 3):
        q = target + m * pins
        if -limit - 1e-9 <= min(q, q + direction) and max(q, q + direction) <= limit + 1e-9:
            if best is None or abs(q - p_cur) < abs(best - p_cur):
                best = q
    if best is None:  # cannot happen for travel_deg >= 360 (the schema's bound); be loud if it does
        raise BadInput(f"ring.travel_deg is too small to reach pin gap {target % pins} from the ring "
                       f"position; expected at least 360")
    return best


def hook_steps(plan, machine, *, start_ring_deg=None, start_index=0):
    """The hooking moves for every pin of the plan's sequence, the first included.

    Parameters
    ----------
    plan : stringbot.planner.Plan
    machine : firmware_protocol.machine.Machine
    start_ring_deg : float, optional
        Ring axis position the job starts from (default 0.0, where the machine
        powers up or homes).  The head is brought IN there first.
    start_index : int, optional
        Plan only the steps from this position in the sequence on (resuming):
        the ring turns from ``start_ring_deg`` to that pin, and every wrap
        direction is still the one the whole sequence gives.

    Returns
    -------
    list of HookStep

    Raises
    ------
    BadInput
        For a disconnected plan or a pin count that differs from the machine's.
    """
    check_plan_fits(plan, machine)
    pins, pitch = machine.pins, machine.pitch_deg
    pin0 = machine["ring.pin0_angle_deg"]
    head_in, head_out = machine["head.in_mm"], machine["head.out_mm"]
    ring_feed, head_feed = machine["ring.feed_deg_per_min"], machine["head.feed_mm_per_min"]
    limit = machine["ring.travel_deg"] / pitch
    fixed = _fixed_direction(machine)
    dwell, every, pause = machine["winding.dwell_s"], machine["winding.pause_every"], machine["winding.pause_s"]

    def deg(p):
        return pin0 + p * pitch

    start = 0.0 if start_ring_deg is None else float(start_ring_deg)
    if not math.isfinite(start):
        raise BadInput(f"start ring position is {start_ring_deg!r}; expected a finite number of degrees")
    p_cur = (start - pin0) / pitch
    seq = [int(p) for p in plan.sequence]
    total = len(seq)
    if isinstance(start_index, bool) or not isinstance(start_index, int) or not 0 <= start_index <= total:
        raise BadInput(f"start step is {start_index!r}; expected a step index 0..{total}")
    steps = []
    around = thread_neighbours(plan)
    for k in range(start_index, total):
        pin = seq[k]
        prev, nxt = around[k]
        d = fixed if fixed is not None else wrap_direction(prev, pin, nxt, pins)
        if d is None:  # free choice: the nearer approach gap
            options = []
            for cand in (1, -1):
                q = _nearest_allowed(pin - cand / 2, p_cur, cand, pins, limit)
                options.append((abs(q - p_cur), -cand, cand, q))
            _, _, d, q = min(options)
        else:
            q = _nearest_allowed(pin - d / 2, p_cur, d, pins, limit)
        moves = []
        if k == start_index:
            moves.append(Move(start, head_in, head_feed))
        moves += [Move(deg(q), head_in, ring_feed),     # the approach (may be where we are)
                  Move(deg(q), head_out, head_feed),
                  Move(deg(q + d), head_out, ring_feed),
                  Move(deg(q + d), head_in, head_feed)]
        p_cur = q + d
        wait = dwell + (pause if every and (k + 1) % every == 0 else 0.0)
        steps.append(HookStep(index=k, pin=pin, direction=d, moves=moves, dwell_s=wait, total=total))
    return steps
