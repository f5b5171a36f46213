"""A G-code link seen as a winding machine: steps in, executed steps out.

:class:`GcodeMachineLink` joins a protocol link (:class:`GrblLink` or
:class:`MarlinLink`: lines <-> bytes) and the motion layer's dialect (steps ->
lines) into the step-level interface the wind loop drives (documented in
:mod:`stringbot.winding`); a servo link implements the same interface directly.
"""

import logging
import re
import time

from ..motion import dialect_for
from ..motion.positions import position_tolerance
from .base import where_of
from .grbl import GrblLink
from .marlin import MarlinLink

__all__ = ["GcodeMachineLink", "gcode_machine_link"]

log = logging.getLogger(__name__)

_G54 = re.compile(r"^\[G54:([-\d.,]+)\]")


class GcodeMachineLink:
    """Step-level interface over a G-code protocol link.

    Parameters
    ----------
    proto : GrblLink or MarlinLink
    machine : firmware_protocol.machine.Machine
    """

    def __init__(self, proto, machine, *, sync="move"):
        if sync not in ("move", "step"):
            raise ValueError(f"sync is {sync!r}; expected 'move' or 'step'")
        self.proto = proto
        self.machine = machine
        self.dialect = dialect_for(machine)
        self.axes = _axis_order(machine)
        self.sync = sync
        self.on_move = None             # callable(step, move_index) once a move is executed
        self._step_index = 0            # first step not yet handed over as executed
        self._move_index = 0            # first move of it not known executed

    # the interface of stringbot.winding ------------------------------------------------
    @property
    def state(self):
        return self.proto.state

    @property
    def info(self):
        return self.proto.info

    @property
    def position_lost(self):
        return self.proto.position_lost

    def identify(self):
        info = self.proto.identify()
        self._read_settings()
        return info

    def _read_settings(self):
        """GRBL/grblHAL: read ``$$`` once (steps per unit for the position tolerance)."""
        if isinstance(self.proto, GrblLink) and self.proto.settings is None:
            self.proto.read_settings()

    def _axis_index(self, letter):
        names = self._axis_names()
        return names.index(letter) if letter in names else None

    @property
    def position_tolerance(self):
        """``(ring_deg, head_mm)``: how far a reported position may be from a point reached: one
        step of each axis (the firmware's ``$100``.. when read, else the machine file's) plus
        print and float32 rounding (see :mod:`stringbot.motion.positions`)."""
        m = self.machine
        steps = {}
        settings = getattr(self.proto, "settings", None) or {}
        for role, key in (("ring", "controller.ring_axis"), ("head", "controller.head_axis")):
            i = self._axis_index(m[key])
            value = settings.get(100 + i) if i is not None else None
            steps[role] = value if value else None
        decimals = 3 if isinstance(self.proto, GrblLink) else 2
        return position_tolerance(m, ring_steps=steps["ring"], head_steps=steps["head"],
                                  decimals=decimals)

    def prepare(self, *, home, resume_at=None):
        """Alarms, homing where the machine file says so, modal state."""
        home_lines = self.dialect.home() if home else []
        self.proto.prepare(home=bool(home_lines), preamble=self.dialect.preamble(),
                           home_lines=home_lines)

    def execute(self, steps, on_executed=None):
        """Run ``steps``: move by move (``sync="move"``) or streamed with a sync per step."""
        if self.sync == "step":
            def done(step):
                self._step_index, self._move_index = step.index + 1, 0
                if on_executed is not None:
                    on_executed(step)
            self.proto.execute(steps, self.dialect.step_lines, done)
            return
        for step in steps:
            self.run_step(step, 0, on_executed)

    def execute_lines(self, step, moves, on_executed=None):
        """Run the rest of ``step`` after a stop: ``moves`` are its Moves from the interrupted one on.

        Each Move is an absolute target: re-issued from wherever the axes stopped
        on its path, it finishes the same straight path.
        """
        self.run_step(step, len(step.moves) - len(moves), on_executed)

    def run_step(self, step, first, on_executed=None):
        """Moves ``first``.. of ``step``, each sent with a sync and waited for."""
        where = where_of(step)
        self._step_index = step.index
        for k in range(first, len(step.moves)):
            self._move_index = k
            self.proto.run_lines([self.dialect.move_line(step.moves[k])], where)
            self._move_index = k + 1
            if self.on_move is not None:
                self.on_move(step, k)
        if step.dwell_s > 0:
            self.proto.run_lines([self.dialect.dwell(step.dwell_s)], where)
        self._step_index, self._move_index = step.index + 1, 0
        if on_executed is not None:
            on_executed(step)
        else:
            self.proto.executed.append(step)

    def stop_point(self):
        """``{"step_index", "move"}``: the first step not handed over, the first of its moves
        not known executed (the one that was running, or about to)."""
        return {"step_index": self._step_index, "move": self._move_index}

    def finish(self):
        self.proto.finish(self.dialect.end())

    def hold(self):
        return self.proto.hold()

    def take_executed(self):
        return self.proto.take_executed()

    def status(self):
        return self.proto.status()

    def position(self):
        """``(ring_deg, head_mm)`` in the job's coordinates as the firmware believes, or None."""
        st = self.proto.status()
        if isinstance(self.proto, GrblLink):
            offset = self._work_offset()
            pos = st.mpos
            if pos is None:
                return None
            if offset is not None:
                pos = tuple(p - o for p, o in zip(pos, offset))
        else:
            axes = st.fields.get("axes") or {}
            ring = axes.get(self.machine["controller.ring_axis"])
            head = axes.get(self.machine["controller.head_axis"])
            return None if ring is None or head is None else (ring, head)
        return self._pick(pos)

    def _work_offset(self):
        """G54's offset from ``$#`` (the motion layer declares positions with ``G10 L20 P1``)."""
        proto = self.proto
        proto.write(b"$#\n")
        offset = None
        while True:
            line = proto.readline(proto.response_timeout)
            if line is None:
                return offset
            m = _G54.match(line)
            if m:
                offset = tuple(float(v) for v in m.group(1).split(","))
            elif line.startswith("ok") or line.startswith("error"):
                return offset

    def _axis_names(self):
        names = self.axes
        for line in getattr(self.proto.info, "lines", ()) or ():
            if line.startswith("[AXS:"):            # grblHAL names its axes in $I
                names = line.rstrip("]").split(":")[-1]
        return names

    def _pick(self, pos):
        values = dict(zip(self._axis_names(), pos))
        ring = values.get(self.machine["controller.ring_axis"])
        head = values.get(self.machine["controller.head_axis"])
        if ring is None or head is None:
            return None
        return ring, head

    # ---- for resume ----------------------------------------------------------------------
    def reconnect(self, timeout=600.0):
        """After a stop: settle the machine, identify it, clear an alarm without moving.

        A machine still running the lines it had (its host died) is waited for; one
        in feed hold is flushed (GRBL: soft reset once stopped, which keeps its
        position).  Returns True when the firmware's position is not to be trusted:
        it (re)started (banner) or raised an alarm.
        """
        proto = self.proto
        said = proto.drain_input(quiet=0.05, limit=2.5)
        grbl = isinstance(proto, GrblLink)
        if grbl:
            self._settle(timeout)
        info = proto.identify()
        self._read_settings()
        lost = proto.position_lost or any(_started(x) for x in list(said) + list(info.lines))
        if grbl and proto.status().state == "Alarm":
            lost = True
            proto.command("$X")
        return lost

    def _settle(self, timeout):
        proto = self.proto
        deadline = time.monotonic() + timeout
        while True:
            st = proto.status()
            if st.state == "Hold" and st.sub == "0":
                proto.flush()
                continue
            if st.state in ("Idle", "Alarm", "Check"):
                proto.drain_input(quiet=0.05, limit=0.5)
                proto.forget_unanswered()
                return st
            if time.monotonic() > deadline:
                raise proto.fail(f"the machine is still {st.state} after {timeout:.0f} s; stop it and resume")
            time.sleep(0.05)

    def restore_modal(self):
        """Millimetres, absolute positions, feed per minute (what a reset forgets)."""
        self.proto.prepare(home=False, preamble=self.dialect.preamble())

    def move_to(self, ring_deg, head_mm, *, axis):
        """One straight move at ``axis``'s feed ("ring" or "head"), waited for."""
        from ..motion import Move
        m = self.machine
        feed = m["ring.feed_deg_per_min"] if axis == "ring" else m["head.feed_mm_per_min"]
        self.proto.run_lines([self.dialect.move_line(Move(ring_deg, head_mm, feed))], self.proto.where)

    def set_position(self, ring_deg, head_mm):
        """Declare where the machine is (after homing or an operator's check)."""
        self.proto.command(self.dialect.set_position(ring_deg, head_mm))

    def home(self):
        for line in self.dialect.home():
            self.proto.command(line, timeout=getattr(self.proto, "motion_timeout", 600.0))

    def unlock(self):
        if isinstance(self.proto, GrblLink):
            self.proto.command("$X")

    def flush(self):
        """Drop queued lines (GRBL: soft reset once stopped)."""
        if isinstance(self.proto, GrblLink):
            self.proto.flush()

    def close(self):
        self.proto.close()

    @property
    def lines_sent(self):
        return self.proto.lines_sent


def _axis_order(machine):
    dialect = machine["controller.dialect"]
    if dialect == "grbl":
        return "XYZ"
    if dialect == "grblhal":
        return "XYZA" if "A" in (machine["controller.ring_axis"], machine["controller.head_axis"]) \
            else "XYZ"
    return "XYZA"


def gcode_machine_link(port, machine, **options):
    """The step-level link for a G-code ``machine`` over an open ``port``."""
    sync = options.pop("sync", "move")
    dialect = machine["controller.dialect"]
    if dialect in ("grbl", "grblhal"):
        proto = GrblLink(port, dialect, **options)
    else:
        proto = MarlinLink(port, **options)
    return GcodeMachineLink(proto, machine, sync=sync)



def _started(line):
    """A line a firmware prints when it (re)starts."""
    from firmware_protocol.grbl import is_banner
    return bool(line) and (is_banner(line) or line.strip() == "start")
