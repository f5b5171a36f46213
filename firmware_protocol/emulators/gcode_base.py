"""What the simulated G-code firmwares share: clock, world, port faults, the running line.

:class:`GcodeFirmware` owns the virtual clock and its events (motion blocks
ending, a dwell ending, the port coming back), the coupling of the firmware's
belief to the physical world (``physical = belief * step_scale + offset`` on
the ring and head axes, ``step_scale`` being the firmware's steps per unit
over the build's: 1 when they agree), the port going down on a ``power`` or ``disconnect`` fault, and the
line being executed as a *task*: a generator that yields a predicate to wait
on (room in the planner, motion finished, a time reached) and returns its
response.  GRBL and Marlin subclass it with their own line reader, parser and
words.
"""

import enum
import logging
import math

from ..faults import BOOT_SECONDS, DISCONNECT_SECONDS, FAULT_KINDS, MACHINE_KINDS, POWER_OFF_SECONDS, FaultPlan
from .base import Emulator
from .motion import MotionQueue

__all__ = ["Power", "GcodeFirmware", "physical_home", "ALL_AXES"]

log = logging.getLogger(__name__)

EPS = 1e-9
ALL_AXES = "XYZABC"


class Power(enum.Enum):
    ON = "on"
    OFF = "off"              # a power loss: the firmware is not running
    UNPLUGGED = "unplugged"  # the cable is out: the firmware runs, the port is gone
    BOOTING = "booting"      # the board restarts (reboot, reset on open): deaf and mute a moment
    FROZEN = "frozen"        # the main loop hangs (freeze): deaf and mute until power or a reboot


def physical_home(machine, ring_now):
    """Where the home switches are: (ring degrees nearest ``ring_now``, head mm).

    The ring's switch trips once a turn, at ``controller.home_ring_deg`` (0 if
    the machine file has none); the head's at ``controller.home_head_mm``
    (default ``head.in_mm``: the head homes to IN).
    """
    v = machine.values
    ring0 = v.get("controller.home_ring_deg") or 0.0
    head = v.get("controller.home_head_mm")
    head = v["head.in_mm"] if head is None else head
    return ring0 + round((ring_now - ring0) / 360.0) * 360.0, head


class GcodeFirmware(Emulator):
    """Common machinery; subclasses set ``EOL``, ``base_axes`` and implement the protocol."""

    EOL = b"\r\n"
    base_axes = "XYZ"

    def __init__(self, machine, *, world=None, faults=None, planner_blocks, rates=None, accels=None):
        super().__init__()
        if world is None:
            from ..world import World
            world = World(machine)
        self.machine, self.world = machine, world
        self.faults = faults if isinstance(faults, FaultPlan) else FaultPlan(faults or ())
        ring, head = machine["controller.ring_axis"], machine["controller.head_axis"]
        extra = "".join(a for a in ALL_AXES if a in (ring, head) and a not in self.base_axes)
        self.axes = self.base_axes + extra
        self.ring_i, self.head_i = self.axes.index(ring), self.axes.index(head)
        n = len(self.axes)
        self.motion = MotionQueue(planner_blocks, rates or [6000.0] * n, accels or [100.0] * n, [0.0] * n)
        self.offset = [0.0] * n
        self.step_scale = [1.0] * n   # physical units per firmware unit: its steps/unit over the build's
        self.power = Power.ON
        self._out = bytearray()
        self._rx = bytearray()
        self._task = None          # (generator, predicate it waits on, silent) of the running line
        self._timer = None         # virtual time a dwell ends
        self._port_back_at = None
        self._boot_at = None       # virtual time a rebooting board starts its firmware
        self._executing_seq = None  # line count of the line being started (for kind@N+F)
        self._fire_now = []        # faults of that line to fire once it has started
        self.dropped_bytes = 0

    # ---- the Emulator interface -------------------------------------------------------------
    def transmit(self):
        data = bytes(self._out)
        self._out.clear()
        return data

    def _event_times(self):
        times = [self.motion.time_to_event()]
        if self._timer is not None:
            times.append(max(self._timer - self.now, 0.0))
        if self._port_back_at is not None:
            times.append(max(self._port_back_at - self.now, 0.0))
        if self._boot_at is not None:
            times.append(max(self._boot_at - self.now, 0.0))
        t = self.faults.next_time()
        if t is not None:
            times.append(max(t - self.now, 0.0))
        return times

    def next_event_in(self):
        times = [t for t in self._event_times() if t is not None]
        return min(times) if times else None

    @property
    def busy(self):
        return bool(self._out) or self.next_event_in() is not None

    def advance(self, dt=None):
        if dt is None:
            nxt = self.next_event_in()
            if nxt is None:
                return 0.0
            dt = nxt
        remaining = dt
        while True:
            nxt = self.next_event_in()
            step = remaining if nxt is None else min(nxt, remaining)
            self._run(step)
            remaining -= step
            if remaining <= EPS:
                break
        return dt

    def _note(self, event, **detail):
        """A notable event for the world's record (virtual time ``t`` added)."""
        self.world.note(event, t=round(self.now, 6), **detail)

    def port_opened(self):
        """A host opened the port: a board with ``controller.reset_on_open`` restarts (an Arduino
        Uno resets on DTR).  Returns True when it did."""
        if not self.machine["controller.reset_on_open"] or self.power is Power.OFF:
            return False
        log.info("port opened: the board restarts (controller.reset_on_open)")
        self._note("reboot", at="port opened", moving=self.motion.moving)
        self._reboot()
        return True

    def reconnect(self):
        """Run the clock until the port is back (no-op if it is up)."""
        if self._port_back_at is not None:
            self.advance(max(self._port_back_at - self.now, 0.0))

    # ---- time -----------------------------------------------------------------------------------
    def _run(self, step):
        before = self.motion.position
        done = self.motion.run(step) if self.power is not Power.OFF else []
        self.now += step
        if self.motion.position != before or done:
            self._move_world([b.target for b in done] + [self.motion.position])
        for fault in self.motion.reached(done) + self.faults.due(self.now):
            self._fire(fault)
        if self._boot_at is not None and self.now >= self._boot_at - EPS:
            self._boot_at = None
            self.power = Power.ON
            self._power_on()
        if self._port_back_at is not None and self.now >= self._port_back_at - EPS:
            self._port_back()
        self._after_run()
        self._pump()

    def _after_run(self):
        """Subclass hook: state changes once time has passed."""

    def _move_world(self, points):
        for p in points:
            ring = self._to_physical(self.ring_i, p[self.ring_i])
            head = self._to_physical(self.head_i, p[self.head_i])
            if (ring, head) != (self.world.ring_deg, self.world.head_mm):
                self.world.move(ring, head)
                if self.world.head_mm != head:
                    # the head ran into its mechanical end: steps lost, the belief goes on without it
                    self.offset[self.head_i] += self.world.head_mm - head

    def _to_physical(self, i, belief):
        """Where axis ``i`` physically is when the firmware believes ``belief``: its motor stands
        on a whole step."""
        return self.whole_step(i, belief) * self.step_scale[i] + self.offset[i]

    #: The firmware counts whole steps (GRBL's ``lround(target * steps_per_mm)``): positions are
    #: reported and reached in steps.  False: exact positions (for comparisons only).
    whole_steps = True

    def _steps_per_unit(self, i):
        """The firmware's steps per unit of axis ``i`` (None: not counted in steps)."""
        return None

    def whole_step(self, i, value):
        """``value`` of axis ``i`` rounded to the firmware's nearest whole step (``lround``)."""
        spu = self._steps_per_unit(i) if self.whole_steps else None
        if not spu:
            return value
        return math.copysign(math.floor(abs(value) * spu + 0.5), value) / spu

    def _on_steps(self):
        """The firmware's position is its step counters: after a stop mid-block (a reset, a jog
        cancel) the planner and parser continue from the whole steps it stands on."""
        self.motion.set_position([self.whole_step(i, v) for i, v in enumerate(self.motion.position)])

    def _set_step_scale(self, i, scale, *, keep_steps):
        """A steps-per-unit setting of axis ``i`` changed (the motors have not moved).

        ``keep_steps`` (GRBL): the firmware counts its position in steps, so the
        position it reports changes; otherwise (Marlin) it keeps the position in
        units and recounts the steps.
        """
        old, self.step_scale[i] = self.step_scale[i], scale
        if scale == old:
            return
        position = list(self.motion.position)
        if keep_steps:
            position[i] *= old / scale
            self.motion.set_position(position)
        else:
            self.offset[i] += position[i] * (old - scale)

    def _physical(self):
        return [self.world.ring_deg, self.world.head_mm]

    def _wipe_belief(self):
        """The firmware forgets where it is: position 0 wherever the axes physically are."""
        physical = self._physical()
        self.motion.clear()
        self.motion.set_position([0.0] * len(self.axes))
        self.offset = [0.0] * len(self.axes)
        self.offset[self.ring_i], self.offset[self.head_i] = physical

    def _belief_is_physical(self):
        """After homing: the firmware's position is the physical one on the ring and head axes."""
        position = list(self.motion.position)
        position[self.ring_i], position[self.head_i] = self._physical()
        self.offset = [0.0] * len(self.axes)
        for i in (self.ring_i, self.head_i):
            self.offset[i] = position[i] - self.whole_step(i, position[i]) * self.step_scale[i]
        self.motion.set_position(position)
        return position

    def _home_moves(self, axes=None):
        """Belief targets that take the head, then the ring, to their switches (``axes``: letters)."""
        home_ring, home_head = physical_home(self.machine, self.world.ring_deg)
        targets, pos = [], list(self.motion.position)
        for i, value in ((self.head_i, home_head), (self.ring_i, home_ring)):
            if axes is None or self.axes[i] in axes:
                pos = list(pos)
                pos[i] = (value - self.offset[i]) / self.step_scale[i]
                targets.append(tuple(pos))
        return targets

    # ---- output -----------------------------------------------------------------------------------
    def _emit(self, line):
        if self.power is Power.ON and self.port_up:
            self._out += line.encode("latin-1") + self.EOL

    # ---- port faults ------------------------------------------------------------------------------
    def _line_faults(self, raw):
        """Count a received line; handle the faults that take the port or the firmware away.

        Returns ``(raw, kinds)``: the line as received (garbled in transit by
        a ``garble`` fault) and the set of fault kinds left for the protocol
        to apply (``error``, ``drop-ok``, ``ignore``); or None when the line is gone.
        """
        kinds = self.faults.next_line()
        for kind in MACHINE_KINDS:              # in order of precedence: the first takes the line
            if kind in kinds:
                self._fire_kind(kind, f"line={self.faults.lines}")
                return None
        if "garble" in kinds:
            raw = self.garble(raw)
        return raw, kinds

    @staticmethod
    def garble(raw):
        """Corrupt a line in transit: its middle byte becomes DEL (0x7F)."""
        raw = bytearray(raw)
        if raw:
            raw[len(raw) // 2] = 0x7F
        log.info("fault: line garbled to %r", bytes(raw))
        return bytes(raw)

    def _fire(self, fault):
        """A machine fault at a time or inside a motion (``kind@t=T``, ``kind@N+F``)."""
        if fault.fraction is not None:
            self.faults.mark_fired(fault)
        self._fire_kind(fault.kind, fault.when())

    def _fire_kind(self, kind, at):
        if self.power in (Power.OFF, Power.BOOTING) or (kind == "disconnect" and not self.port_up) \
                or (self.power is Power.FROZEN and kind in ("freeze", "disconnect", "reset")):
            log.info("fault %s@%s: nothing to hit (the firmware is %s)", kind, at, self.power.value)
            self._note(kind, at=at, skipped=f"the firmware is {self.power.value}")
            return
        log.info("fault %s@%s at t=%.4f", kind, at, self.now)
        self._note(FAULT_KINDS[kind].event or kind, at=at, moving=self.motion.moving)
        getattr(self, "_fault_" + kind.replace("-", "_"))()

    # the machine kinds of firmware_protocol.faults.FAULT_KINDS, each fired by _fault_<name>
    def _fault_power(self):
        self._port_down(Power.OFF, POWER_OFF_SECONDS)

    def _fault_disconnect(self):
        self._port_down(Power.UNPLUGGED, DISCONNECT_SECONDS)

    def _fault_reboot(self):
        self._reboot()

    def _fault_freeze(self):
        self._freeze()

    def _port_down(self, power, seconds):
        log.info("fault: port down (%s) for %.2f s", power.value, seconds)
        self.power = power
        self.port_up = False
        self._out.clear()
        self._rx.clear()
        self._clear_input()
        if power is Power.OFF:
            self.motion.clear()
            self._task, self._timer, self._boot_at = None, None, None
            self._stop_resets()
        self._port_back_at = self.now + seconds

    def _port_back(self):
        was_off = self.power is Power.OFF
        self._port_back_at = None
        self.power = Power.ON
        self.port_up = True
        self._note("power on" if was_off else "port up")
        if was_off:
            self._power_on()
        log.info("port back up")

    def _freeze(self):
        """The main loop hangs: nothing more is read, answered or planned (no ``busy``, no status
        report); motion already queued for the steppers runs out; a power cycle or a reboot
        (an Uno's reset on open) ends it."""
        self.power = Power.FROZEN
        self._out.clear()

    def _reboot(self):
        """The board restarts: everything in progress is lost at once; for BOOT_SECONDS it hears
        and says nothing; then the firmware starts with its position lost (:meth:`_power_on`)."""
        self.motion.clear()
        self._task, self._timer = None, None
        self._out.clear()
        self._rx.clear()
        self._clear_input()
        self._stop_resets()
        if self.power is Power.UNPLUGGED:       # nobody listens: it is up again by the time anyone does
            self._power_on()
            return
        self.power = Power.BOOTING
        self._boot_at = self.now + BOOT_SECONDS

    @property
    def running(self):
        """The firmware's main loop runs (with or without the port)."""
        return self.power in (Power.ON, Power.UNPLUGGED)

    def _stop_resets(self):
        """Subclass hook: forget a reset in progress (the board lost power or restarted)."""

    def _fault_reset(self):
        """Subclass hook: a soft reset (``reset`` fault); the firmware's own kind of reset."""
        self._reboot()

    def _clear_input(self):
        """Subclass hook: forget partial lines and queued commands."""

    def _power_on(self):
        """Subclass hook: the firmware starts after a power loss or a reboot (position lost)."""

    # ---- the running line ---------------------------------------------------------------------------
    def _start_line(self, result, silent, seq):
        """Start the task of received line ``seq``; then fire its ``kind@seq+F`` faults that no
        motion took (a line that moves nothing: as it starts)."""
        self._executing_seq = seq
        try:
            self._start_task(result, silent)
        finally:
            self._executing_seq = None
        now, self._fire_now = self._fire_now + self.faults.fractions(seq), []
        for fault in now:
            self._fire(fault)

    def _claim_watches(self, targets):
        """``{target index: [(distance into that block, fault)]}`` for the ``kind@N+F`` faults of
        the line being started (``_executing_seq``): F of the line's whole path length."""
        faults = self.faults.fractions(self._executing_seq) if self._executing_seq else []
        if not faults:
            return {}
        prev = self.motion.blocks[-1].target if self.motion.blocks else tuple(self.motion.position)
        lengths = []
        for target in targets:
            lengths.append(math.dist(prev, target))
            prev = target
        total = sum(x for x in lengths if x > 1e-9)
        watches = {}
        for fault in faults:
            if total <= 1e-9:
                self._fire_now.append(fault)
                continue
            d, before = fault.fraction * total, 0.0
            for i, length in enumerate(lengths):
                if length > 1e-9 and d <= before + length + 1e-12:
                    watches.setdefault(i, []).append((d - before, fault))
                    break
                before += length if length > 1e-9 else 0.0
        for w in watches.values():
            w.sort(key=lambda x: x[0])
        return watches

    def _start_task(self, result, silent):
        """Run a line's result: an immediate response, or a task generator."""
        if hasattr(result, "send"):
            try:
                self._task = (result, result.send(None), silent)
            except StopIteration as stop:
                self._respond(stop.value, silent)
        else:
            self._respond(result, silent)

    def _step_task(self):
        """Advance the running task as far as it can go; True when no task is left running."""
        while self._task is not None:
            gen, pred, silent = self._task
            if not pred():
                return False
            try:
                self._task = (gen, gen.send(None), silent)
            except StopIteration as stop:
                self._task = None
                self._respond(stop.value, silent)
        return True

    def _dwell_task(self, seconds):
        """Wait for motion to finish, then ``seconds``."""
        while not self.motion.empty:
            yield lambda: self.motion.empty
        self._timer = self.now + seconds
        yield lambda: self.now >= self._timer - EPS
        self._timer = None
        return 0

    def _queue_task(self, targets, *, rapid, feed, inverse=False, line_number=0, kind="line"):
        """Queue blocks to ``targets`` as the planner makes room."""
        watches = self._claim_watches(targets)
        for i, target in enumerate(targets):
            while self.motion.free <= 0:
                yield lambda: self.motion.free > 0
            start = self.motion.blocks[-1].target if self.motion.blocks else tuple(self.motion.position)
            block = self.motion.add(start, target, rapid=rapid, feed=feed, inverse_time=inverse,
                                    line_number=line_number, kind=kind)
            if block is not None:
                block.watch = watches.get(i)
                self._motion_queued(kind)
        return 0

    def _motion_queued(self, kind):
        """Subclass hook: a block went into the planner."""

    def _respond(self, code, silent=False):
        raise NotImplementedError

    def _pump(self):
        raise NotImplementedError
