"""Simulated Marlin 2.1: numbered, checksummed lines in; ``ok``, ``Resend:``, ``busy`` out.

The serial side follows Marlin's own queue: bytes wait in a 128-byte receive
buffer (bytes beyond it are dropped), complete lines move into a queue of 4
commands, and each is checked as it moves: a line that starts with ``N`` must
carry the next line number (``M110`` excepted) and a correct ``*`` checksum,
else Marlin answers ``Error:<why>, Last Line: <n>``, empties its receive
buffer and asks ``Resend: <n+1>`` followed by ``ok``.  Empty lines are skipped
without an answer.  A command is answered ``ok`` once it has been *processed*:
``G0``/``G1`` when their block is in the (15-block) planner, ``M400`` and
``G28`` only when motion has finished, ``G4`` after its dwell; while a command
blocks, ``echo:busy: processing`` comes every 2 s.  Unknown commands get
``echo:Unknown command: "<cmd>"`` and ``ok``.

``M0``/``M1`` (a spool change in stringbot's G-code) wait, once motion has
finished, for the operator: on the machine the click of its LCD, here ``M108``
(Break and Continue), which Marlin's emergency parser acts on as it arrives,
ahead of the queue; meanwhile ``echo:busy: paused for user`` comes every 2 s.
With ``S<seconds>`` or ``P<ms>`` the wait also ends after that time.
"""

import enum
import logging
import math
import re
from collections import deque

from .. import marlin as mc
from .gcode_base import EPS, GcodeFirmware, Power
from .marlin_settings import MarlinSettingsMixin
from .motion import arc_points

__all__ = ["MarlinEmulator", "MarlinState"]

log = logging.getLogger(__name__)

_PARAM = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))?")
_INT = re.compile(r"^\s*([-+]?\d+)")


class MarlinState(enum.Enum):
    READY = "ready"
    HALTED = "halted"        # after M112: nothing more until a reset


def _strtol(text):
    m = _INT.match(text)
    return int(m.group(1)) if m else 0


class MarlinEmulator(MarlinSettingsMixin, GcodeFirmware):
    """Marlin 2.1 on a virtual clock, driving ``world``; axes X Y Z plus the machine's rotary ``A``."""

    EOL = b"\n"
    base_axes = "XYZ"

    def __init__(self, machine, *, world=None, faults=None, presets=()):
        super().__init__(machine, world=world, faults=faults, planner_blocks=mc.PLANNER_BLOCKS)
        self._init_settings(presets)        # steps, feeds, accelerations, endstops: marlin_settings
        self.state = MarlinState.READY
        self.queue = deque()          # (command, silent, line count, ignore) checked, waiting to run
        self._raw = bytearray()
        self._busy_at = None          # next keepalive while a command blocks
        self._user_wait = False       # M0/M1 waits for the operator (M108, the LCD's click)
        self._ep_tail = b""           # the emergency parser's last bytes (M108 split across writes)
        self._boot(wipe=True)

    # ---- bytes in -------------------------------------------------------------------------------
    def receive(self, data):
        if self.power is not Power.ON or not self.port_up:
            return
        for c in bytes(data):
            if len(self._rx) < mc.RX_BUFFER_SIZE - 1:
                self._rx.append(c)
            else:
                self.dropped_bytes += 1
        seen = self._ep_tail + bytes(data).upper()
        self._ep_tail = seen[-3:]
        if b"M108" in seen and self._user_wait:     # the emergency parser: acts before the queue
            log.info("M108: the operator continues")
            self._user_wait = False
        self._pump()            # one write arrives as one USB packet: Marlin sees it all at once

    def _event_times(self):
        times = super()._event_times()
        if self._busy_at is not None and not self._user_wait:   # waiting for the operator: no event
            times.append(max(self._busy_at - self.now, 0.0))
        return times

    def _after_run(self):
        while self._busy_at is not None and self._task is not None and self.now >= self._busy_at - EPS:
            self._emit(mc.PAUSED_FOR_USER if self._user_wait else mc.BUSY_PROCESSING)
            self._busy_at += mc.KEEPALIVE_SECONDS

    # ---- the main loop ------------------------------------------------------------------------------
    def _pump(self):
        while self.running and self.state is MarlinState.READY:
            while len(self.queue) < mc.BUFSIZE and self._rx:
                c = self._rx.pop(0)
                if c in (0x0A, 0x0D):
                    raw = bytes(self._raw)
                    self._raw.clear()
                    if raw.strip(b" "):
                        self._line(raw)
                elif len(self._raw) < 4096:
                    self._raw.append(c)
            if not self._step_task():
                if self._busy_at is None:
                    self._busy_at = self.now + mc.KEEPALIVE_SECONDS
                return
            self._busy_at = None
            if not self.queue:
                return
            command, silent, seq, ignore = self.queue.popleft()
            if ignore:
                log.info("fault: %r acknowledged, not executed", command)
                self._respond(0, silent)
                continue
            self._start_line(self._command(command), silent, seq)

    def _line(self, raw):
        got = self._line_faults(raw)
        if got is None:
            return
        raw, kinds = got
        text = raw.decode("latin-1").split(";", 1)[0][:mc.MAX_CMD_SIZE - 1]
        command = text.lstrip(" ")
        if not command:
            return
        if "error" in kinds:
            log.info("fault: line %r rejected", command)
            self._line_error(mc.ERR_CHECKSUM_MISMATCH)
            return
        if command.startswith("N"):
            m110 = "M110" in command
            npos = command
            if m110:
                second = command.find("N", 4)
                if second != -1:
                    npos = command[second:]
            n = _strtol(npos[1:])
            if n != self.last_n + 1 and not m110:
                self._line_error(mc.ERR_LINE_NO)
                return
            star = command.rfind("*")
            if star == -1:
                self._line_error(mc.ERR_NO_CHECKSUM)
                return
            if _strtol(command[star + 1:]) != mc.checksum(command[:star]):
                self._line_error(mc.ERR_CHECKSUM_MISMATCH)
                return
            self.last_n = n
        self.queue.append((command, "drop-ok" in kinds, self.faults.lines, "ignore" in kinds))

    def _line_error(self, message):
        self._emit(f"Error:{message}{self.last_n}")
        self._rx.clear()
        self._raw.clear()
        self._emit(f"{mc.RESEND}{self.last_n + 1}")
        self._emit(mc.OK)

    def _respond(self, code, silent=False):
        if code is None:
            return
        if silent:
            log.info("fault: ok dropped")
            return
        self._emit(mc.OK)

    # ---- commands -----------------------------------------------------------------------------------
    def _command(self, command):
        """One queued command -> 0 (ok), None (no answer) or a task generator."""
        text = command
        if text.startswith("N"):
            text = re.sub(r"^N[-+]?\d*\s*", "", text)
        star = text.find("*")
        if star != -1:
            text = text[:star]
        text = text.rstrip(" ")
        m = re.match(r"^([GMT])(\d+)(?:\.\d+)?", text.upper())
        if not m:
            return self._unknown(text)
        letter, code = m.group(1), int(m.group(2))
        params = {}
        for p_letter, value in _PARAM.findall(text.upper()[m.end():]):
            params[p_letter] = float(value) if value else None
        handler = getattr(self, f"_{letter}{code}", None)
        if handler is None:
            return self._unknown(text)
        return handler(params)

    def _unknown(self, text):
        self._emit(f'{mc.UNKNOWN_COMMAND}{text}"')
        return 0

    def _planned(self):
        return list(self.motion.blocks[-1].target) if self.motion.blocks else list(self.motion.position)

    def _G0(self, p):
        if p.get("F"):
            self.feed = p["F"] * self.scale
        target = self._planned()
        for i, axis in enumerate(self.axes):
            if p.get(axis) is not None:
                value = p[axis] * self.scale
                target[i] = target[i] + value if self.relative else value - self.shift[i]
        target = self._soft_limited(target)
        if target == self._planned():
            return 0
        return self._queue_task([tuple(target)], rapid=False, feed=self.feed)

    _G1 = _G0

    def _G2(self, p, clockwise=True):
        """Arc in the XY plane (radius or I/J offsets), cut into 1 mm segments."""
        if p.get("F"):
            self.feed = p["F"] * self.scale
        start, target = self._planned(), self._planned()
        for i, axis in enumerate(self.axes):
            if p.get(axis) is not None:
                value = p[axis] * self.scale
                target[i] = target[i] + value if self.relative else value - self.shift[i]
        i0, i1 = self.axes.index("X"), self.axes.index("Y")
        offset = (0.0, 0.0)
        if p.get("R"):
            r = p["R"] * self.scale
            dx, dy = target[i0] - start[i0], target[i1] - start[i1]
            d = math.hypot(dx, dy)
            if d:
                e = -1.0 if clockwise ^ (r < 0) else 1.0
                h2 = (r - 0.5 * d) * (r + 0.5 * d)
                h = math.sqrt(h2) if h2 >= 0 else 0.0
                cx = (start[i0] + target[i0]) / 2 + e * h * (-dy / d)
                cy = (start[i1] + target[i1]) / 2 + e * h * (dx / d)
                offset = (cx - start[i0], cy - start[i1])
        else:
            offset = ((p.get("I") or 0.0) * self.scale, (p.get("J") or 0.0) * self.scale)
        if offset == (0.0, 0.0):
            self._emit("Error:G2/G3 bad parameters")
            return 0
        points = arc_points(start, target, i0, i1, offset, clockwise,
                            lambda angle, radius: math.floor(abs(angle * radius) / 1.0))
        return self._queue_task(points, rapid=False, feed=self.feed)

    def _G3(self, p):
        return self._G2(p, clockwise=False)

    def _G4(self, p):
        seconds = (p.get("P") or 0.0) / 1000.0 if p.get("S") is None else p["S"]
        return self._dwell_task(seconds)

    def _G20(self, p):
        self.scale = 25.4
        return 0

    def _G21(self, p):
        self.scale = 1.0
        return 0

    def _G28(self, p):
        axes = [a for a in self.axes if a in p] or list(self.axes)
        return self._home(axes)

    def _home(self, axes):
        while not self.motion.empty:
            yield lambda: self.motion.empty
        start = tuple(self.motion.position)
        for target in self._home_moves(axes):
            self.motion.add(start, target, rapid=True, feed=0.0, kind="home")
            start = target
        while not self.motion.empty:
            yield lambda: self.motion.empty
        physical = {self.ring_i, self.head_i}
        position = self._belief_is_physical()
        for i, axis in enumerate(self.axes):
            if axis in axes:
                self.shift[i] = 0.0
                if i not in physical:
                    position[i] = 0.0
        self.motion.set_position(position)
        self.homed.update(axes)
        return 0

    def _G90(self, p):
        self.relative = False
        return 0

    def _G91(self, p):
        self.relative = True
        return 0

    def _G92(self, p):
        planned = self._planned()
        for i, axis in enumerate(self.axes):
            if p.get(axis) is not None:
                self.shift[i] = p[axis] * self.scale - planned[i]
        return 0

    def _ok(self, p):
        return 0

    _M17 = _M18 = _M84 = _M82 = _M83 = _M108 = _M111 = _M117 = _T0 = _ok

    def _M0(self, p):
        """Wait for the operator (M108), or ``S`` seconds / ``P`` ms, once motion has finished."""
        while not self.motion.empty:
            yield lambda: self.motion.empty
        timed = p.get("S") is not None or p.get("P") is not None
        self._user_wait = True
        if timed:
            self._timer = self.now + (p["S"] if p.get("S") is not None else p["P"] / 1000.0)
            yield lambda: not self._user_wait or self.now >= self._timer - EPS
            self._timer = None
        else:
            yield lambda: not self._user_wait
        self._user_wait = False
        return 0

    _M1 = _M0

    def _M110(self, p):
        if p.get("N") is not None:
            self.last_n = int(p["N"])
        return 0

    def _M112(self, p):
        self._emit("Error:Printer halted. kill() called!")
        self.motion.clear()
        self.queue.clear()
        self.state = MarlinState.HALTED
        return None

    def _M114(self, p):
        planned = self._planned()
        logical = " ".join(f"{a}:{(v + s) / self.scale:.2f}" for a, v, s in zip(self.axes, planned, self.shift))
        counts = " ".join(f"{a}:{round(v * k)}" for a, v, k in zip(self.axes, self.motion.position, self.steps))
        self._emit(f"{logical} Count {counts}")
        return 0

    def _M115(self, p):
        self._emit(f"FIRMWARE_NAME:Marlin {mc.VERSION} (Jul 11 2023 12:00:00) SOURCE_CODE_URL:github.com/"
                   f"MarlinFirmware/Marlin PROTOCOL_VERSION:1.0 MACHINE_TYPE:{self.machine.name} "
                   f"EXTRUDER_COUNT:0 AXIS_COUNT:{len(self.axes)} UUID:cede2a2f-41a2-4748-9b12-c55c62f367ff")
        for cap in ("SERIAL_XON_XOFF:0", "BINARY_FILE_TRANSFER:0", "EEPROM:1", "AUTOREPORT_POS:0",
                    "AUTOREPORT_TEMP:0", "PROGRESS:0", "PRINT_JOB:1", "EMERGENCY_PARSER:0",
                    "HOST_ACTION_COMMANDS:0"):
            self._emit(f"Cap:{cap}")
        return 0

    def _M400(self, p):
        while not self.motion.empty:
            yield lambda: self.motion.empty
        return 0

    def _steps_per_unit(self, i):
        steps = getattr(self, "steps", None)
        return steps[i] if steps else None

    def _M410(self, p):
        self.motion.clear()
        self._on_steps()
        return 0

    # ---- boot, reset, power ---------------------------------------------------------------------------
    def _boot(self, *, wipe):
        self.motion.clear()
        if wipe:
            self._wipe_belief()
        self.queue.clear()
        self._rx.clear()
        self._raw.clear()
        self._task, self._timer, self._busy_at = None, None, None
        self._user_wait = False
        self.last_n = 0
        self.feed = 1500.0
        self.scale = 1.0
        self.relative = False
        self.shift = [0.0] * len(self.axes)
        self.homed = set()                      # axes homed since this start (software endstops)
        self.state = MarlinState.READY
        for line in (mc.START, f"echo:Marlin {mc.VERSION}",
                     "echo: Last Updated: 2023-07-11 | Author: (stringbot simulator)",
                     "echo:Compiled: Jul 11 2023", "echo: Free Memory: 4821  PlannerBufferBytes: 1232",
                     self._load_at_boot()):
            self._emit(line)

    def _clear_input(self):
        self._raw.clear()
        self.queue.clear()

    def _power_on(self):
        self._boot(wipe=True)
