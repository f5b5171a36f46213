"""Planner queue and motion timing of the simulated G-code firmware.

Each block is a straight line in axis space (ring degrees and head millimetres
mixed, as GRBL and Marlin mix them) run with a trapezoidal speed profile from
rest to rest: accelerate at the block's acceleration, cruise at its rate, stop
at its end.  (Real planners keep some speed through junctions; the string
machine's moves alternate between axes, where they stop anyway.)  A block's
rate and acceleration are limited per axis, like GRBL's
``limit_value_by_axis_maximum``.  A feed hold decelerates the running block at
its acceleration; resuming restarts it from rest.

The queue knows nothing of serial lines or the world: the firmware front asks
it how long until the next block ends (:meth:`MotionQueue.time_to_event`),
runs it forward (:meth:`MotionQueue.run`) and reads :attr:`MotionQueue.position`.
"""

import math
from collections import deque
from dataclasses import dataclass

__all__ = ["Profile", "Block", "MotionQueue"]

_EPS = 1e-12


class Profile:
    """Distance along a block over time: pieces of constant acceleration.

    ``Profile.move(s0, length, vmax, accel)`` starts at rest at ``s0`` and stops
    at ``length``; ``Profile.stop(s0, v0, length, accel)`` decelerates from
    speed ``v0`` to rest (not beyond ``length``).
    """

    def __init__(self, pieces):
        self.pieces = pieces          # [(duration, s_start, v_start, accel)]
        self.duration = sum(p[0] for p in pieces)

    @classmethod
    def move(cls, s0, length, vmax, accel):
        d = max(length - s0, 0.0)
        if d <= _EPS:
            return cls([])
        vp = min(vmax, math.sqrt(accel * d))
        t_ramp = vp / accel
        d_ramp = vp * vp / (2 * accel)
        d_cruise = max(d - 2 * d_ramp, 0.0)
        pieces = [(t_ramp, s0, 0.0, accel)]
        if d_cruise > _EPS:
            pieces.append((d_cruise / vp, s0 + d_ramp, vp, 0.0))
        pieces.append((t_ramp, s0 + d_ramp + d_cruise, vp, -accel))
        return cls(pieces)

    @classmethod
    def stop(cls, s0, v0, length, accel):
        if v0 <= _EPS:
            return cls([])
        t = v0 / accel
        if s0 + v0 * v0 / (2 * accel) > length:      # cannot happen on our own profiles; clamp anyway
            t = max((length - s0) * 2 / v0, 0.0)
            accel = v0 / t if t > 0 else accel
        return cls([(t, s0, v0, -accel)])

    def time_at(self, s):
        """Time into the profile at which distance ``s`` is reached (None: never)."""
        elapsed = 0.0
        for dur, s0, v, a in self.pieces:
            s_end = s0 + v * dur + 0.5 * a * dur * dur
            if s <= s_end + _EPS:
                d = max(s - s0, 0.0)
                if abs(a) < _EPS:
                    t = d / v if v > _EPS else 0.0
                else:
                    disc = max(v * v + 2 * a * d, 0.0)
                    t = (-v + math.sqrt(disc)) / a
                return elapsed + min(max(t, 0.0), dur)
            elapsed += dur
        return None

    def at(self, t):
        """(distance, speed) at time ``t`` into the profile."""
        for dur, s, v, a in self.pieces:
            if t <= dur:
                return s + v * t + 0.5 * a * t * t, max(v + a * t, 0.0)
            t -= dur
        if not self.pieces:
            return None, 0.0
        dur, s, v, a = self.pieces[-1]
        return s + v * dur + 0.5 * a * dur * dur, 0.0


@dataclass
class Block:
    """One queued straight-line motion (machine coordinates, the firmware's belief)."""

    start: tuple
    target: tuple
    length: float
    rate: float           # units per second
    accel: float          # units per second squared
    feed_report: float    # programmed rate, units/min (for FS:)
    line_number: int = 0
    kind: str = "line"    # "line", "jog", "home"
    s: float = 0.0        # distance done
    v: float = 0.0        # current speed
    t: float = 0.0        # time into the current profile
    profile: Profile = None
    watch: list = None    # [(distance along the block, tag)] to report once reached (sorted)

    def point(self, s):
        f = s / self.length if self.length else 1.0
        return tuple(a + (b - a) * f for a, b in zip(self.start, self.target))


class MotionQueue:
    """The planner buffer and the block being executed.

    Parameters
    ----------
    capacity : int
        Blocks the planner holds (15 on stock GRBL).
    rates : sequence of float
        Maximum rate per axis, units/min (GRBL ``$110``...).
    accels : sequence of float
        Acceleration per axis, units/s^2 (GRBL ``$120``...).
    """

    def __init__(self, capacity, rates, accels, position):
        self.capacity = capacity
        self.rates = list(rates)
        self.accels = list(accels)
        self.position = list(position)
        self.blocks = deque()
        self.holding = False      # a feed hold is in effect (decelerating or stopped)

    # ---- queries --------------------------------------------------------------------------
    @property
    def free(self):
        return self.capacity - len(self.blocks)

    @property
    def empty(self):
        return not self.blocks

    @property
    def moving(self):
        """True while an axis is in motion (a profile is running)."""
        if not self.blocks:
            return False
        b = self.blocks[0]
        return b.profile is not None and b.t < b.profile.duration

    @property
    def hold_complete(self):
        return self.holding and not self.moving

    @property
    def speed(self):
        """Current speed along the running block, units/min."""
        return self.blocks[0].v * 60.0 if self.moving else 0.0

    @property
    def current(self):
        return self.blocks[0] if self.blocks else None

    # ---- planning -------------------------------------------------------------------------
    def limits(self, delta, length):
        """(max rate units/min, max accel units/s^2) along ``delta`` within every axis' limit."""
        rate, accel = math.inf, math.inf
        for d, r, a in zip(delta, self.rates, self.accels):
            if d:
                unit = abs(d) / length
                rate = min(rate, r / unit)
                accel = min(accel, a / unit)
        return rate, accel

    def add(self, start, target, *, rapid, feed, inverse_time=False, line_number=0, kind="line"):
        """Queue a block from ``start`` to ``target``; returns it (None for a zero-length move)."""
        delta = [b - a for a, b in zip(start, target)]
        length = math.sqrt(sum(d * d for d in delta))
        if length <= 1e-9:
            return None
        max_rate, accel = self.limits(delta, length)
        if rapid:
            rate = max_rate
        elif inverse_time:
            rate = min(feed * length, max_rate)
        else:
            rate = min(feed, max_rate)
        block = Block(start=tuple(start), target=tuple(target), length=length, rate=rate / 60.0,
                      accel=accel, feed_report=rate, line_number=line_number, kind=kind)
        self.blocks.append(block)
        if len(self.blocks) == 1 and not self.holding:
            self._start(block)
        return block

    def _start(self, block):
        block.profile = Profile.move(block.s, block.length, block.rate, block.accel)
        block.t = 0.0

    # ---- control --------------------------------------------------------------------------
    def hold(self):
        """Feed hold: decelerate the running block to rest."""
        if self.holding:
            return
        self.holding = True
        b = self.current
        if b is not None and b.profile is not None:
            b.profile = Profile.stop(b.s, b.v, b.length, b.accel)
            b.t = 0.0

    def resume(self):
        """Cycle start after a completed hold: restart the current block from rest."""
        if not self.holding or self.moving:
            return
        self.holding = False
        b = self.current
        if b is not None:
            self._start(b)

    def clear(self):
        """Stop dead and forget every block (reset, power loss, jog cancel at rest)."""
        self.blocks.clear()
        self.holding = False

    def set_position(self, position):
        self.position = list(position)

    # ---- time -----------------------------------------------------------------------------
    def time_to_event(self):
        """Seconds until the running block ends, the hold comes to rest or a watched distance is
        reached; None when nothing moves."""
        if not self.moving:
            return None
        b = self.current
        left = max(b.profile.duration - b.t, 0.0)
        if b.watch:
            t = b.profile.time_at(b.watch[0][0])
            if t is not None:
                left = min(left, max(t - b.t, 0.0))
        return left

    @staticmethod
    def _due(b, s):
        t = b.profile.time_at(s) if b.profile is not None else None
        return t is not None and t <= b.t + 1e-12

    def reached(self, done=()):
        """Tags of the watched distances passed: on the blocks ``done`` and the running one."""
        tags = []
        for b in done:
            tags += [tag for _s, tag in b.watch or ()]
            b.watch = None
        b = self.current
        while b is not None and b.watch and (b.s >= b.watch[0][0] - 1e-9 or self._due(b, b.watch[0][0])):
            tags.append(b.watch.pop(0)[1])
        return tags

    def run(self, dt):
        """Advance by ``dt`` seconds; returns the blocks finished (in order).

        Stops at a block boundary only to start the next block at once; a hold
        leaves the current block where it came to rest.
        """
        done = []
        while self.blocks:
            b = self.blocks[0]
            if b.profile is None or (self.holding and b.t >= b.profile.duration):
                break
            remaining = b.profile.duration - b.t
            step = min(dt, remaining)
            b.t += step
            dt -= step
            s, v = b.profile.at(b.t)
            if s is not None:
                b.s, b.v = min(s, b.length), v
            self.position = list(b.point(b.s))
            if b.t >= b.profile.duration - _EPS:
                b.v = 0.0
                if b.s >= b.length - 1e-9:
                    self.position = list(b.target)
                    self.blocks.popleft()
                    done.append(b)
                    if self.blocks and not self.holding:
                        self._start(self.blocks[0])
                    if dt <= _EPS:
                        break
                    continue
                break               # hold complete
            break
        return done


def arc_points(start, target, i0, i1, center_offset, clockwise, segments_for):
    """Points along a G2/G3 arc in the plane of axes ``i0``, ``i1`` (other axes move linearly).

    ``center_offset`` is (offset0, offset1) from ``start`` to the centre;
    ``segments_for(angular_travel, radius)`` says how many straight segments
    to cut it into.  The last point is ``target`` exactly.
    """
    off0, off1 = center_offset
    c0, c1 = start[i0] + off0, start[i1] + off1
    r0, r1 = -off0, -off1
    t0, t1 = target[i0] - c0, target[i1] - c1
    angle = math.atan2(r0 * t1 - r1 * t0, r0 * t0 + r1 * t1)
    if clockwise:
        if angle >= -5e-7:
            angle -= 2 * math.pi
    elif angle <= 5e-7:
        angle += 2 * math.pi
    radius = math.hypot(off0, off1)
    n = max(int(segments_for(angle, radius)), 1)
    points = []
    for k in range(1, n):
        f = k / n
        theta = angle * f
        p = [a + (b - a) * f for a, b in zip(start, target)]
        p[i0] = c0 + r0 * math.cos(theta) - r1 * math.sin(theta)
        p[i1] = c1 + r0 * math.sin(theta) + r1 * math.cos(theta)
        points.append(tuple(p))
    points.append(tuple(target))
    return points
