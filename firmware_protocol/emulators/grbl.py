"""Simulated GRBL 1.1h and grblHAL: bytes in, bytes out, on a virtual clock.

What the host sees is what GRBL's own documentation describes
(``doc/markdown/interface.md``): the banner after every reset, one ``ok`` or
``error:N`` per line, realtime ``?`` ``!`` ``~`` 0x18 picked off the stream at
once, status reports, alarms.  The receive buffer is GRBL's: 128 bytes fit
(``Bf:`` says 128 free when empty); while the firmware is blocked (planner full,
dwell, homing) the bytes a host oversends beyond that are dropped, and the
mangled line that results is answered with an error.  The planner holds 15
blocks and ``ok`` is withheld while it is full.

The firmware's *belief* (machine position, offsets, modal state, alarm) is
kept apart from the physical axes in :class:`~firmware_protocol.world.World`:
``physical = belief + offset`` for the ring and head axes.  A soft reset
(0x18, ``$RST=``, a ``reset`` fault) keeps the machine position (GRBL keeps its
step counters) and goes as GRBL's ``mc_reset`` and main loop go: motion stops
dead; if it was moving, ``ALARM:3`` and a 0.5 s pause (``report_alarm_message``)
in which everything the host sends is lost; then ``ok`` for a line that was
waiting in the main loop (planner full, a dwell or sync), then the banner.  A
reboot or a power loss wipes the position, so it reads 0 wherever the axes stand.  ``$H`` moves the head to
``head.in_mm`` and then the ring to the nearest whole turn (physical), and
sets belief = physical.
"""

import logging

from ..grbl import UNLOCK_MESSAGE
from .gcode_base import EPS, GcodeFirmware, Power, physical_home
from .grbl_parser import GrblError, GrblParser, fmt
from .grbl_system import GRBL, GRBLHAL, GrblState, build_steps, default_settings, format_settings, store_setting

__all__ = ["GrblState", "GrblEmulator", "GrblHalEmulator", "physical_home", "Power"]

log = logging.getLogger(__name__)

_EPS = EPS
#: GRBL's ``delay_ms(500)`` after printing an alarm: the main loop is stopped that long.
ALARM_PAUSE_SECONDS = 0.5


def clean_line(raw, limit):
    """GRBL's line reader: drop spaces, control bytes and comments, upcase; (text, overflow)."""
    out, paren, semicolon, overflow = [], False, False, False
    for c in raw:
        ch = chr(c)
        if paren or semicolon or overflow:
            if ch == ")" and paren:
                paren = False
            continue
        if c <= 0x20 or ch == "/":
            continue
        if ch == "(":
            paren = True
        elif ch == ";":
            semicolon = True
        elif len(out) >= limit - 1:
            overflow = True
        else:
            out.append(ch.upper() if "a" <= ch <= "z" else ch)
    return "".join(out), overflow


class GrblEmulator(GcodeFirmware):
    """GRBL 1.1h on a virtual clock, driving ``world``.

    Parameters
    ----------
    machine : firmware_protocol.machine.Machine
    world : firmware_protocol.world.World, optional
        The physical machine (one is made from ``machine`` if not given).
    faults : str or list of Fault, optional
        See :mod:`firmware_protocol.faults`.
    presets : list of firmware_protocol.settings.Preset
        Settings stored before power-up (``stringbot simulate --set '$100=40'``).
    """

    variant = GRBL

    def __init__(self, machine, *, world=None, faults=None, presets=()):
        self.base_axes = self.variant.base_axes
        super().__init__(machine, world=world, faults=faults, planner_blocks=self.variant.planner_blocks)
        self.settings = default_settings(self.variant, self.axes, machine)
        self.build_steps = dict(zip((self.ring_i, self.head_i), build_steps(machine)))
        self.apply_settings()
        self.user_string = ""
        self.startup_lines = ["", ""]
        self.parser = GrblParser(self.axes)
        self.apply_settings()
        for preset in presets:          # settings it was left with, before this power-up
            self.preset(preset)
        self.state = GrblState.IDLE
        self._raw = bytearray()
        self._wco_counter = self._ovr_counter = 0
        self._jog_cancelling = False
        self.after_response = None
        self._reset_at = None          # (virtual time the alarm pause ends, stray ok owed)
        self._boot(wipe=True, alarm=False)

    # ---- the Emulator interface -------------------------------------------------------------
    def receive(self, data):
        for c in bytes(data):
            if self.power is not Power.ON or not self.port_up or self._reset_at is not None:
                return                  # nobody hears it: off, booting, or pausing after an alarm
            if c in (0x3F, 0x21, 0x7E, 0x18):
                self._pump()
                self._realtime(c)
            elif c >= 0x80:
                if c == 0x85:
                    self._pump()
                    self._jog_cancel()
                # overrides (0x90..0xA4) and the door are accepted and ignored; others are discarded
            elif len(self._rx) < self.variant.rx_size:      # GRBL's ring has one spare slot: all 128 fit
                self._rx.append(c)
                if c in (0x0A, 0x0D):
                    self._pump()
            else:
                self.dropped_bytes += 1
        self._pump()

    def _event_times(self):
        times = super()._event_times()
        if self._reset_at is not None:
            times.append(max(self._reset_at[0] - self.now, 0.0))
        return times

    def _after_run(self):
        if self._reset_at is not None and self.now >= self._reset_at[0] - _EPS:
            self._finish_reset(self._reset_at[1], alarm=True)
        self._update_state()

    def _update_state(self):
        if self.state is GrblState.JOG and self._jog_cancelling and not self.motion.moving:
            self.motion.clear()
            self._on_steps()
            self.parser.position = list(self.motion.position)
            self._jog_cancelling = False
        if self.state in (GrblState.RUN, GrblState.JOG) and self.motion.empty:
            self.state = GrblState.IDLE

    # ---- output -----------------------------------------------------------------------------------
    def _respond(self, code, silent=False):
        if silent:
            log.info("fault: response %r dropped", "ok" if not code else f"error:{code}")
            return
        self._emit("ok" if not code else f"error:{code}")

    # ---- boot, reset, power -------------------------------------------------------------------------
    def _boot(self, *, wipe, alarm):
        """(Re)initialise as GRBL's main loop does after power-up or an abort."""
        self.motion.clear()
        if wipe:
            self._wipe_belief()
        self._on_steps()
        self.parser.reset(self.motion.position)
        self._rx.clear()
        self._raw.clear()
        self._task, self._timer = None, None
        self._wco_counter = self._ovr_counter = 0
        if alarm or (wipe and self.settings[22]) or self.state in (GrblState.ALARM, GrblState.SLEEP):
            self.state = GrblState.ALARM
        else:
            self.state = GrblState.IDLE
        self._jog_cancelling = False
        self._emit_banner()
        if self.state is GrblState.ALARM:
            self._emit(UNLOCK_MESSAGE)
        else:
            self._run_startup_lines()

    def _emit_banner(self):
        if self.power is Power.ON and self.port_up:
            self._out += b"\r\n" + self.variant.banner.encode("ascii") + b"\r\n"

    def _soft_reset(self):
        """``mc_reset``: stop dead keeping the position; ALARM:3 (6 when homing) and the pause if
        moving; a line waiting in the main loop is answered ``ok`` before the banner."""
        if self._reset_at is not None:
            return                      # GRBL sets its reset flag once
        moving = self.state in (GrblState.RUN, GrblState.JOG, GrblState.HOME) or (
            self.state is GrblState.HOLD and not self.motion.hold_complete)
        stray = self._task is not None and not self._task[2]
        self.motion.clear()
        self._task, self._timer = None, None
        self._jog_cancelling = False
        if not moving:
            self._finish_reset(stray, alarm=False)
            return
        log.info("reset while moving: alarm, %.1f s pause", ALARM_PAUSE_SECONDS)
        self._emit("ALARM:6" if self.state is GrblState.HOME else "ALARM:3")
        self.state = GrblState.ALARM
        self._reset_at = (self.now + ALARM_PAUSE_SECONDS, stray)

    def _finish_reset(self, stray, *, alarm):
        self._reset_at = None
        if stray:
            self._respond(0)
        self._boot(wipe=False, alarm=alarm)

    def _fault_reset(self):
        self._soft_reset()

    def _stop_resets(self):
        self._reset_at = None

    def _clear_input(self):
        self._raw.clear()

    def _power_on(self):
        self.state = GrblState.IDLE
        self._boot(wipe=True, alarm=False)

    # ---- the main loop --------------------------------------------------------------------------------
    def _pump(self):
        """Run GRBL's main loop until it blocks or runs out of input."""
        while self.running and self._reset_at is None:
            if not self._step_task():
                return
            if not self._rx:
                return
            c = self._rx.pop(0)
            if c in (0x0A, 0x0D):
                raw = bytes(self._raw)
                self._raw.clear()
                self._line(raw)
            elif len(self._raw) < 4096:
                self._raw.append(c)

    def _line(self, raw):
        got = self._line_faults(raw)
        if got is None:
            return
        raw, kinds = got
        silent = "drop-ok" in kinds
        if "error" in kinds:
            log.info("fault: line %r rejected", bytes(raw))
            self._respond(20, silent)
            return
        if "ignore" in kinds:
            log.info("fault: line %r acknowledged, not executed", bytes(raw))
            self._respond(0, silent)
            return
        text, overflow = clean_line(raw, 80)
        result = self._execute(text, overflow)
        self._start_line(result, silent, self.faults.lines)
        if self.after_response is not None:
            then, self.after_response = self.after_response, None
            then()

    def _execute(self, text, overflow):
        """One line: an error code / 0, or a generator that yields wait predicates and returns one."""
        if overflow:
            return 11
        if not text:
            return 0
        if text[0] == "$":
            from .grbl_commands import system_command
            return system_command(self, text)
        if self.state in (GrblState.ALARM, GrblState.JOG, GrblState.SLEEP):
            return 9
        try:
            action = self.parser.execute(text)
        except GrblError as exc:
            return exc.code
        if self.state is GrblState.CHECK:
            return 0
        return self._perform(action)

    def _perform(self, action):
        if action.sync:
            return self._synced_then(action)
        return self._perform_now(action)

    def _synced_then(self, action):
        """GRBL's buffer sync before an EEPROM write or a WCO change; WCO: in the next report."""
        while not self._synced():
            yield self._synced
        if action.wco:
            self._wco_counter = 0
        result = self._perform_now(action)
        if hasattr(result, "send"):
            result = yield from result
        return result

    def _perform_now(self, action):
        if action.kind == "move":
            return self._queue_moves([action.target], rapid=action.rapid, feed=action.feed,
                                     inverse=action.inverse_time, line_number=action.line_number)
        if action.kind == "moves":
            return self._queue_moves(action.targets, rapid=action.rapid, feed=action.feed,
                                     inverse=False, line_number=action.line_number)
        if action.kind == "dwell":
            return self._dwell(action.seconds)
        if action.kind == "end":
            return self._program_end(action)
        if action.kind == "pause":
            return self._pause()
        return 0

    # ---- line tasks (generators: yield a predicate to wait on, return the response code) --------------
    def _queue_moves(self, targets, *, rapid, feed, inverse, line_number, kind="line"):
        return self._queue_task(targets, rapid=rapid, feed=feed, inverse=inverse,
                                line_number=line_number, kind=kind)

    def _motion_queued(self, kind):
        if self.state is GrblState.IDLE:
            self.state = GrblState.JOG if kind == "jog" else GrblState.RUN

    def _synced(self):
        return self.motion.empty and self.state not in (GrblState.HOLD,)

    def _dwell(self, seconds):
        while not self._synced():
            yield self._synced
        self._timer = self.now + seconds
        yield lambda: self.now >= self._timer - _EPS
        self._timer = None
        return 0

    def _program_end(self, action):
        if action.target is not None:
            yield from self._queue_moves([action.target], rapid=action.rapid, feed=action.feed,
                                         inverse=False, line_number=action.line_number)
        while not self._synced():
            yield self._synced
        self._wco_counter = 0
        self._emit("[MSG:Pgm End]")
        return 0

    def _pause(self):
        while not self._synced():
            yield self._synced
        self.state = GrblState.HOLD
        self.motion.hold()
        yield lambda: self.state is not GrblState.HOLD
        return 0

    def _home(self):
        """``$H``: head to its switch, then the ring to its switch (nearest turn), belief = physical."""
        self.state = GrblState.HOME
        start = tuple(self.motion.position)
        for target in self._home_moves():
            self.motion.add(start, target, rapid=True, feed=0.0, kind="home")
            start = target
        while not self.motion.empty:
            yield lambda: self.motion.empty
        self.parser.position = self._belief_is_physical()
        self._wco_counter = 0
        self.state = GrblState.IDLE
        self._run_startup_lines()
        return 0

    def _run_startup_lines(self):
        for line in self.startup_lines:
            if not line:
                continue
            try:
                self.parser.execute(line)
                self._emit(f">{line}:ok")
            except GrblError as exc:
                self._emit(f">{line}:error:{exc.code}")

    # ---- realtime ---------------------------------------------------------------------------------------
    def _realtime(self, c):
        if c == 0x18:
            self._soft_reset()
        elif c == 0x3F:
            self._emit(self.status_report())
        elif c == 0x21:
            if self.state is GrblState.JOG:
                self._jog_cancel()
            elif self.state in (GrblState.RUN, GrblState.IDLE):
                self.state = GrblState.HOLD
                self.motion.hold()
        elif c == 0x7E:
            if self.state is GrblState.HOLD and self.motion.hold_complete:
                self.motion.resume()
                self.state = GrblState.IDLE if self.motion.empty else GrblState.RUN

    def _jog_cancel(self):
        """Decelerate the jog to rest; the rest of it is flushed once stopped (_update_state)."""
        if self.state is GrblState.JOG:
            self._jog_cancelling = True
            self.motion.hold()
            self._update_state()

    def status_report(self):
        """The ``<...>`` line for ``?`` (and advances GRBL's WCO/Ov refresh counters)."""
        state = self.state.value
        if self.state is GrblState.HOLD:
            state += ":0" if self.motion.hold_complete or self.motion.empty else ":1"
        inches = bool(self.settings[13])
        dec = 4 if inches else 3
        k = 1 / 25.4 if inches else 1.0
        pos = [self.whole_step(i, v) for i, v in enumerate(self.motion.position)]
        wco = self.parser.wco()
        mask = int(self.settings[10])
        if mask & 1:
            fields = ["MPos:" + ",".join(fmt(v * k, dec) for v in pos)]
        else:
            fields = ["WPos:" + ",".join(fmt((v - o) * k, dec) for v, o in zip(pos, wco))]
        if mask & 2:
            fields.append(f"Bf:{self.motion.free},{self.variant.rx_size - len(self._rx)}")
        spindle = self.parser.state.speed if self.parser.state.spindle != "M5" else 0.0
        fields.append(f"FS:{fmt(self.motion.speed * k, 1 if inches else 0)},{fmt(spindle, 0)}")
        busy = self.state in (GrblState.RUN, GrblState.HOLD, GrblState.JOG, GrblState.HOME)
        if self._wco_counter > 0:
            self._wco_counter -= 1
        else:
            self._wco_counter = (30 if busy else 10) - 1
            if self._ovr_counter == 0:
                self._ovr_counter = 1
            fields.append("WCO:" + ",".join(fmt(v * k, dec) for v in wco))
        if self._ovr_counter > 0:
            self._ovr_counter -= 1
        else:
            self._ovr_counter = (20 if busy else 10) - 1
            fields.append("Ov:100,100,100")
            acc = ("S" if self.parser.state.spindle == "M3" else "C" if self.parser.state.spindle == "M4"
                   else "") + ("F" if self.parser.state.coolant == "M8" else "")
            if acc:
                fields.append("A:" + acc)
        return "<" + "|".join([state] + fields) + ">"

    def _steps_per_unit(self, i):
        return self.settings.get(100 + i)

    def _rates(self):
        return [self.settings[110 + i] for i in range(len(self.axes))]

    def _accels(self):
        return [self.settings[120 + i] for i in range(len(self.axes))]

    def apply_settings(self):
        """Axis rates and accelerations take effect for the blocks planned next; steps per unit
        at once (the position GRBL reports moves, the motors do not)."""
        self.motion.rates, self.motion.accels = self._rates(), self._accels()
        for i, build in self.build_steps.items():
            old = self.step_scale[i]
            self._set_step_scale(i, self.settings[100 + i] / build, keep_steps=True)
            if hasattr(self, "parser") and old != self.step_scale[i]:
                self.parser.position[i] *= old / self.step_scale[i]
        if hasattr(self, "parser"):
            self.parser.arc_tolerance = self.settings[12]

    def preset(self, preset):
        """Start with a setting of ``--set`` (a :class:`~firmware_protocol.settings.Preset` of
        ``(N, value)``), stored as ``$N=value`` would; ValueError with GRBL's words if refused."""
        key, value = preset.value
        code = self.store_setting(key, value)
        if code:
            from ..grbl import describe_error
            raise ValueError(f"--set {preset.text!r}: the firmware answers error:{code} "
                             f"({describe_error(code)})")

    def restore(self, what):
        """``$RST=$``: settings back to the build's (the machine file's); ``$RST=#``: G54..G59,
        G28 and G30 to 0; ``$RST=*``: both, the startup lines and the ``$I`` string too."""
        if what in "$*":
            self.settings = default_settings(self.variant, self.axes, self.machine)
            self.apply_settings()
        if what in "#*":
            n = len(self.axes)
            self.parser.coord_systems = [[0.0] * n for _ in range(6)]
            self.parser.g28, self.parser.g30 = [0.0] * n, [0.0] * n
        if what == "*":
            self.startup_lines = ["", ""]
            self.user_string = ""

    def format_settings(self):
        return format_settings(self.settings)

    def store_setting(self, key, value):
        code = store_setting(self.settings, key, value, len(self.axes))
        if code == 0:
            self.apply_settings()
        return code


class GrblHalEmulator(GrblEmulator):
    """grblHAL: its banner, a 1024-byte receive buffer, 100 planner blocks, the A axis."""

    variant = GRBLHAL
