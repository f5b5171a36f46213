"""The simulator's physical machine: ring, pins, thread head and the thread.

This is the ground truth that tests compare plans with (docs/design.md, "The
physical model").  It knows nothing of firmware or G-code: an emulator keeps
the firmware's belief (machine position, lost on a reset) apart and calls
:meth:`World.move` with *physical* positions for every motion segment it
executes.

Geometry
--------
Positions are physical axis values: ring degrees (pin ``i`` faces the head
station at ``pin0_angle_deg + i * pitch_deg``, and the ring may turn many
times, so angles are not wrapped) and head millimetres.  Internally the ring
position is expressed in *pin units* ``p = (ring_deg - pin0_angle_deg) /
pitch_deg``: pin ``k`` (``k`` any integer, pin ``k mod pins``) faces the
station at ``p = k`` and the gap between pins ``k`` and ``k + 1`` at
``p = k + 0.5``.

The eyelet crosses the pin circle at ``machine.circle_mm`` (midway between
``head.in_mm`` and ``head.out_mm``).  Its side is IN (towards ``in_mm``), OUT
(towards ``out_mm``) or ON (exactly at the circle).  Every *contact* with the
circle (arriving at it, or crossing it inside a segment) must happen within
``machine.gap_tolerance_deg`` of a gap centre, and while the eyelet stays ON
the circle the ring may only turn within that one gap's window; anything else
is a collision with a pin.

Threads
-------
A spool change is the operator's work, which no axis shows: the operator
tells the world (:meth:`World.tie_on`, reached through ``sim://``'s
:func:`firmware_protocol.urlhandler.protocol_sim.tie_on`) that a thread of a
colour is now tied on, and every later wrap carries that colour (``"color"``
in the record's wraps; a world nobody told has none).  The record's
``spools`` lists each tie-on: its colour, pin, how many wraps came before it
and whether the head was out (a thread tied on with the head out is caught
on the wrong side of the pin circle).

Wraps
-----
When the eyelet leaves the IN side and reaches the OUT side, the ring position
``p_out`` where it left the circle is remembered; when it next comes back IN,
at ``p_in``, every pin ``k`` with ``p_out < k < p_in`` (or ``p_in < k <
p_out``) has passed behind the head and the thread now goes round its outside:
each is a wrap, in the order the pins passed the station, with direction +1
when the ring axis increased (``p_in > p_out``) and -1 when it decreased.  Out
and back through the same gap wraps nothing, whatever the ring did in between
(the thread slides back off the pins it passed and re-passed); a full turn
while out wraps every pin.  The segment is a straight line in (ring, head), so
a diagonal move crosses the circle at the one instant the head passes
``circle_mm``, and the ring angle at that instant is what is checked.

Head travel
-----------
The head axis has mechanical ends (``machine.head_travel_mm``).  A segment
that drives the head past one stops the head at that end (the motor stalls,
the firmware does not know) while the ring goes on; it is recorded once as a
*crash* until the head moves away from the end again.

The record
----------
:meth:`World.record` is what an operator looking at the machine would see:
ring angle, head position and side, the number of motion segments, wraps,
collisions, crashes and the simulator's notable events (resets, power, the
port).  The file (``record_path``) is rewritten atomically at once after
every wrap, collision, crash and event; other changes (the axes moving) are
written at most every :attr:`World.save_interval` seconds of wall time, and
whatever is still unwritten is written by :meth:`World.flush`, which the
transports call whenever the machine waits for its host, when the port drops
or closes and when the simulator exits.
"""

import json
import math
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ["World", "Wrap"]

#: Numerical slack (in pin units) for positions computed by the G-code round trip.
_EPS = 1e-9


@dataclass(frozen=True)
class Wrap:
    """One pin the thread went round: ``pin`` index and ``direction`` (+1 ring axis up, -1 down),
    and the ``color`` of the thread tied on at the time (None: nobody said)."""

    pin: int
    direction: int
    color: str | None = None

    def as_dict(self):
        d = {"pin": self.pin, "direction": self.direction}
        if self.color is not None:
            d["color"] = self.color
        return d


def _write_atomic(path, text):
    """Write ``text`` to ``path``: temp file in the same folder, fsync, ``os.replace``.

    A symlink is written through (its target is replaced, the link stays); the file
    gets the mode any other output gets (kept if it exists, else 0666 less the umask);
    an ``OSError`` names the path.
    """
    path = Path(os.path.realpath(path)) if os.path.islink(path) else Path(path)
    try:
        mode = os.stat(path).st_mode & 0o7777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError) and exc.filename is None:
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        raise


class World:
    """The physical machine built from a :class:`~firmware_protocol.machine.Machine`.

    Parameters
    ----------
    machine : firmware_protocol.machine.Machine
        Geometry: pins, pitch, gap tolerance, head IN/OUT positions.
    record_path : str or path-like, optional
        If given, the JSON record (:meth:`record`) is rewritten atomically there:
        at the start, after every wrap, collision, crash and event, and for
        motion alone at most every ``save_interval`` seconds (see :meth:`flush`).
    save_interval : float
        Wall-clock seconds between two rewrites for motion alone.

    Notes
    -----
    The world starts with the ring at physical angle 0.0 deg, the head at
    ``head.in_mm`` and no wraps.
    """

    def __init__(self, machine, *, record_path=None, save_interval=0.1):
        self.machine = machine
        self.save_interval = save_interval
        self.record_path = None if record_path is None else Path(record_path)
        self._pins = machine.pins
        self._pitch = machine.pitch_deg
        self._pin0 = machine["ring.pin0_angle_deg"]
        self._circle = machine.circle_mm
        self._outward = 1.0 if machine["head.out_mm"] > machine["head.in_mm"] else -1.0
        self._tol = machine.gap_tolerance_deg / self._pitch  # in pin units
        self.ring_deg = 0.0
        self.head_mm = float(machine["head.in_mm"])
        self.wraps = []
        self._wrap_json = []        # wraps already serialised for the record file
        self.collisions = []
        self.crashes = []
        self.events = []
        self._travel = machine.head_travel_mm
        self._stalled = 0           # -1 / +1: the head is held at its low / high end by a crash
        self._dirty = False
        self._saved_at = 0.0
        self.moves = 0
        self.ring_travel_deg = 0.0
        self._side = -1             # last strict side: -1 IN, +1 OUT
        self._p_out = None          # pin units where the eyelet left the circle outwards
        self.thread_color = None    # the thread tied on (the operator says, :meth:`tie_on`)
        self.spools = []
        if self.record_path is not None:
            self._save()

    # ---- queries ------------------------------------------------------------------------
    def _side_of(self, head_mm):
        d = (head_mm - self._circle) * self._outward
        return 0 if d == 0 else (1 if d > 0 else -1)

    @property
    def head_out(self):
        """True when the eyelet is strictly outside the pin circle."""
        return self._side_of(self.head_mm) > 0

    @property
    def head_side(self):
        """``"in"``, ``"out"`` or ``"on"`` (the eyelet exactly on the pin circle)."""
        return {-1: "in", 0: "on", 1: "out"}[self._side_of(self.head_mm)]

    def pin_units(self, ring_deg):
        """Ring axis degrees -> pin units (pin ``k`` faces the station at ``k``)."""
        return (ring_deg - self._pin0) / self._pitch

    def tie_on(self, color, pin=None):
        """The operator tied a thread of ``color`` (``"#rrggbb"``) on, at ``pin``: later wraps are of it."""
        self.thread_color = str(color)
        self.spools.append({"color": self.thread_color, "pin": pin, "after_wraps": len(self.wraps),
                            "head_out": self.head_out})
        if self.record_path is not None:
            self._save()

    def record(self):
        """The world's record as a JSON-ready dict."""
        spools = {"spools": [dict(s) for s in self.spools]} if self.spools else {}
        return {
            "machine": self.machine.name,
            "pins": self._pins,
            "wraps": [w.as_dict() for w in self.wraps],
            "collisions": [dict(c) for c in self.collisions],
            "crashes": [dict(c) for c in self.crashes],
            "events": [dict(e) for e in self.events],
            "moves": self.moves,
            "ring_deg": self.ring_deg,
            "head_mm": self.head_mm,
            "head_side": self.head_side,
            "head_out": self.head_out,
            "ring_travel_deg": self.ring_travel_deg,
            **spools,
        }

    # ---- the record file ----------------------------------------------------------------
    def note(self, event, **detail):
        """A notable event (a reset, power lost, the port dropped): kept in the record, written now."""
        self.events.append({"event": event, "move": self.moves, **detail})
        self._save()

    def flush(self):
        """Write the record if something changed since it was last written."""
        if self._dirty:
            self._save()

    def close(self):
        """The simulator is done with the world: write the record (always: a write that an
        interruption cut short, e.g. Ctrl-C during its fsync, left the file behind the world)."""
        self._save()

    def _changed(self, now_worth_saving):
        if self.record_path is None:
            return
        if now_worth_saving or time.monotonic() - self._saved_at >= self.save_interval:
            self._save()
        else:
            self._dirty = True

    # ---- motion -------------------------------------------------------------------------
    def move(self, ring_deg, head_mm):
        """Move both axes in a straight line from the current physical position.

        Parameters
        ----------
        ring_deg : float
            Target ring angle, physical degrees (not wrapped).
        head_mm : float
            Target head position, mm.

        Returns
        -------
        list of Wrap
            The wraps this segment completed (also appended to :attr:`wraps`).
        """
        r1, h1 = float(ring_deg), float(head_mm)
        if not (math.isfinite(r1) and math.isfinite(h1)):
            raise ValueError(f"world.move({ring_deg!r}, {head_mm!r}): expected finite numbers")
        lo, hi = self._travel
        end = lo if h1 < lo else hi if h1 > hi else None
        if end is None:
            self._stalled = 0
            return self._segment(r1, h1)
        # the head runs into its end: up to there in a straight line, then the ring alone
        r0, h0 = self.ring_deg, self.head_mm
        side = -1 if end == lo else 1
        crash = self._stalled != side
        new = []
        if h0 != end:
            t = (end - h0) / (h1 - h0)
            new = self._segment(r0 + t * (r1 - r0), end, quiet=True)
        if crash:
            self._stalled = side
            self.crashes.append({"ring_deg": self.ring_deg, "head_mm": end, "driven_to_mm": h1,
                                 "move": self.moves, "reason": f"head driven to {h1:.3f} mm, past its "
                                 f"{'low' if side < 0 else 'high'} end at {end:g} mm: it stopped there"})
        if r1 != self.ring_deg:
            new += self._segment(r1, end, quiet=True)
        self._changed(True)
        return new

    def _segment(self, r1, h1, quiet=False):
        r0, h0 = self.ring_deg, self.head_mm
        self.moves += 1
        self.ring_travel_deg += abs(r1 - r0)
        s0, s1 = self._side_of(h0), self._side_of(h1)
        new = []
        changed = False
        if s0 == 0 and s1 == 0:
            # the eyelet slides along the pin circle: the ring may only turn inside one gap window
            if not self._same_gap_window(self.pin_units(r0), self.pin_units(r1)):
                changed |= self._collide(r1, h1, "head on the pin circle while the ring turned "
                                         f"from {r0:.4f} to {r1:.4f} deg, past a pin")
        elif s0 != 0 and s0 != s1:
            # arrives at (s1 == 0) or crosses the circle inside this segment
            t = (self._circle - h0) / (h1 - h0)
            rc = r0 + t * (r1 - r0)
            changed |= self._check_contact(rc)
            if s1 != 0:
                new = self._leave_circle(s1, rc)
        elif s0 == 0 and s1 != 0:
            # leaves the circle at the start of this segment (the contact was checked on arrival)
            new = self._leave_circle(s1, r0)
        self.ring_deg, self.head_mm = r1, h1
        if not quiet:
            self._changed(bool(new or changed))
        return new

    def _leave_circle(self, side, ring_at):
        """The eyelet is now strictly on ``side``, having left the circle at ``ring_at``."""
        if side == self._side:
            return []             # touched the circle and went back: nothing wrapped
        self._side = side
        p = self.pin_units(ring_at)
        if side > 0:
            self._p_out = p
            return []
        p_out, self._p_out = self._p_out, None
        if p_out is None:
            return []
        if p > p_out:
            ks = range(math.floor(p_out + _EPS) + 1, math.ceil(p - _EPS))
            direction = 1
        else:
            ks = range(math.ceil(p_out - _EPS) - 1, math.floor(p + _EPS), -1)
            direction = -1
        new = [Wrap(pin=k % self._pins, direction=direction, color=self.thread_color) for k in ks]
        self.wraps.extend(new)
        return new

    def _gap_offset(self, p):
        """(nearest gap index g, distance in pin units from the gap centre g + 0.5)."""
        g = math.floor(p)
        return g, abs(p - (g + 0.5))

    def _same_gap_window(self, pa, pb):
        ga, da = self._gap_offset(pa)
        gb, db = self._gap_offset(pb)
        return ga == gb and da <= self._tol + _EPS and db <= self._tol + _EPS

    def _check_contact(self, ring_at):
        g, off = self._gap_offset(self.pin_units(ring_at))
        if off <= self._tol + _EPS:
            return False
        nearest_pin = round(self.pin_units(ring_at)) % self._pins
        return self._collide(ring_at, self._circle,
                             f"head crossed the pin circle {off * self._pitch:.4f} deg from the centre "
                             f"of gap {g % self._pins}|{(g + 1) % self._pins} (tolerance "
                             f"{self._tol * self._pitch:.4f} deg), at pin {nearest_pin}")

    def _collide(self, ring_at, head_at, reason):
        self.collisions.append({"ring_deg": ring_at, "head_mm": head_at, "reason": reason,
                                "move": self.moves})
        return True

    def _save(self):
        if self.record_path is None:
            return
        self._dirty = True              # until the write below is done
        self._saved_at = time.monotonic()
        # The wraps list only grows: serialise each wrap once and join, so that rewriting the
        # record after every wrap stays linear in its size (a full plan is thousands of wraps).
        frags = self._wrap_json
        frags.extend(json.dumps(w.as_dict()) for w in self.wraps[len(frags):])
        rest = self.record()
        del rest["wraps"]
        head = json.dumps(rest, indent=1)[:-2]  # drop the closing "\n}"
        _write_atomic(self.record_path, head + ',\n "wraps": [\n  ' + ",\n  ".join(frags) + "\n ]\n}\n")
        self._dirty = False
