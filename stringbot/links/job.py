"""A G-code link seen as a winding machine: steps in, executed *and verified* steps out.

:class:`GcodeMachineLink` joins a protocol link (:class:`GrblLink` or
:class:`MarlinLink`: lines <-> bytes) and the motion layer's dialect (steps ->
lines) into the step-level interface the wind loop drives (documented in
:mod:`stringbot.winding`); a servo link implements the same interface directly.

Never believe a move you did not see
------------------------------------
A firmware's ``ok`` to a sync line says the motion queue ran dry; it does not
say the machine is where the host meant it to be (a line answered ``ok`` but
never executed, a position wiped by a reset whose banner was lost).  So after
every move (and, streaming, after every step) the link asks the machine's own
report -- GRBL's ``?`` (``MPos`` less the work offset), Marlin's ``M114`` --
waits until it stands still, and compares it with the planned point within
one step of each axis (:attr:`GcodeMachineLink.position_tolerance`).  Only
then is the move handed to the wind loop (and journaled).  A machine that is
anywhere else stops the winding at once with one line naming both points; the
stop record keeps the position it reported.

Each move line names only the axis that moves (:meth:`GcodeDialect.move_line`
with the point it starts from), so a ring move never moves the head and a head
move never turns the ring, whatever the firmware believes of the other axis.
"""

import logging
import re
import time

from ..motion import Move, dialect_for
from ..motion.positions import position_tolerance
from .base import where_of
from .grbl import GrblLink
from .job_recovery import GcodeRecovery

__all__ = ["GcodeMachineLink", "gcode_machine_link"]

log = logging.getLogger(__name__)

_G54 = re.compile(r"^\[G54:([-\d.,]+)\]")


class GcodeMachineLink(GcodeRecovery):
    """Step-level interface over a G-code protocol link.

    Parameters
    ----------
    proto : GrblLink or MarlinLink
    machine : firmware_protocol.machine.Machine
    sync : "move" (default: each move waited for and verified) or "step" (a step's lines
        streamed with one sync; verified at each step's end)
    verify : bool
        Compare the machine's reported position with the plan after every move (default).
    """

    def __init__(self, proto, machine, *, sync="move", verify=True):
        if sync not in ("move", "step"):
            raise ValueError(f"sync is {sync!r}; expected 'move' or 'step'")
        self.proto = proto
        self.machine = machine
        self.dialect = dialect_for(machine)
        self.axes = proto.kind.status_axes(machine["controller.ring_axis"], machine["controller.head_axis"])
        self.sync = sync
        self.verify = verify
        self.on_move = None             # callable(step, move_index) once a move is executed
        self._step_index = 0            # first step not yet handed over as executed
        self._move_index = 0            # first move of it not known executed
        self.here = None                # (ring, head) the machine was last seen at (plan point)
        self.rest = None                # (ring, head) measured at rest, nothing sent since
        self.checks = 0                 # positions compared with the plan (for figures)
        self._offset = None             # GRBL: G54's offset (machine -> job coordinates)
        self._count_shift = None        # Marlin: job position less the step counts (at rest)
        self._tolerance = None

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
            self._tolerance = None

    @property
    def position_tolerance(self):
        """``(ring_deg, head_mm)``: how far a reported position may be from a point reached: one
        step of each axis (the firmware's ``$100``.. when read, else the machine file's) plus
        print and float32 rounding (see :mod:`stringbot.motion.positions`)."""
        if self._tolerance is None:
            m = self.machine
            steps = {}
            settings = getattr(self.proto, "settings", None) or {}
            for role, key in (("ring", "controller.ring_axis"), ("head", "controller.head_axis")):
                i = self._axis_index(m[key])
                value = settings.get(100 + i) if i is not None else None
                steps[role] = value if value else None
            decimals = 3 if isinstance(self.proto, GrblLink) else 2
            self._tolerance = position_tolerance(m, ring_steps=steps["ring"], head_steps=steps["head"],
                                                 decimals=decimals)
        return self._tolerance

    def prepare(self, *, home, resume_at=None):
        """Alarms, homing where the machine file says so, modal state."""
        home_lines = self.dialect.home() if home else []
        self.proto.prepare(home=bool(home_lines), preamble=self.dialect.preamble(),
                           home_lines=home_lines)
        self._offset = self._count_shift = None

    def execute(self, steps, on_executed=None):
        """Run ``steps``: move by move (``sync="move"``) or streamed with a sync per step."""
        if self.sync == "step":
            self._stream(steps, on_executed)
            return
        for step in steps:
            self.run_step(step, 0, on_executed)

    def _stream(self, steps, on_executed):
        prev = {"move": self.here}

        def lines_for(step):
            lines = self.dialect.step_lines(step, prev["move"])
            prev["move"] = step.moves[-1]
            return lines

        def done(step):
            if self.verify:
                self._verify(step.moves[-1], where_of(step), f"step {step.index + 1}")
            self.here = _point(step.moves[-1])
            self._step_index, self._move_index = step.index + 1, 0
            if on_executed is not None:
                on_executed(step)

        lookahead = getattr(self.proto, "lookahead", None)
        if self.verify and lookahead is not None:
            self.proto.lookahead = 0        # the machine stands still at each step's end
        self.rest = None
        try:
            self.proto.execute(steps, lines_for, done)
        finally:
            if lookahead is not None:
                self.proto.lookahead = lookahead

    def execute_lines(self, step, moves, on_executed=None):
        """Run the rest of ``step`` after a stop: ``moves`` are its Moves from the interrupted one on.

        Each Move is an absolute target: re-issued from wherever the axes stopped
        on its path, it finishes the same straight path.
        """
        self.run_step(step, len(step.moves) - len(moves), on_executed)

    def run_step(self, step, first, on_executed=None):
        """Moves ``first``.. of ``step``, each sent with a sync, waited for and verified."""
        where = where_of(step)
        self._step_index = step.index
        for k in range(first, len(step.moves)):
            self._move_index = k
            self._move(step.moves[k], where, f"move {k + 1} of step {step.index + 1}")
            self._move_index = k + 1
            if self.on_move is not None:
                self.on_move(step, k)
        if step.dwell_s > 0:
            self.rest = None
            self.proto.run_lines([self.dialect.dwell(step.dwell_s)], where)
        self._step_index, self._move_index = step.index + 1, 0
        if on_executed is not None:
            on_executed(step)
        else:
            self.proto.executed.append(step)

    def _move(self, move, where, what):
        """One move: its line (only the axes that change) and the sync, then the check."""
        self.rest = None
        self.proto.run_lines([self.dialect.move_line(move, self.here)], where)
        if self.verify:
            self._verify(move, where, what)
        self.here = _point(move)

    # ---- the machine's own report --------------------------------------------------------
    def _verify(self, move, where, what):
        """Stop unless the machine, at rest, reports ``move``'s target within the tolerance."""
        target = _point(move)
        here = self.at_rest(where)
        self.checks += 1
        tol = self.position_tolerance
        if here is not None and abs(here[0] - target[0]) <= tol[0] and abs(here[1] - target[1]) <= tol[1]:
            self.rest = target
            return
        self.rest = here
        seen = "no position" if here is None else f"ring {here[0]:.3f}, head {here[1]:.3f}"
        raise self.proto.fail(
            f"after {what} the machine reports {seen}, not the planned ring {target[0]:.3f}, head "
            f"{target[1]:.3f}: a line was acknowledged but not executed, or its position was wiped "
            "or jumped; stopped", where)

    def at_rest(self, where=None, timeout=None):
        """``(ring_deg, head_mm)`` the machine reports once it stands still (None: no position).

        GRBL: ``?`` until Idle (a sync answered early, e.g. lost on the way, leaves it moving
        a little longer); an alarm fails.  Marlin: ``M114`` after its ``M400``.
        """
        proto = self.proto
        if not isinstance(proto, GrblLink):
            return self._marlin_at_rest(where, timeout)
        deadline = time.monotonic() + (timeout or proto.motion_timeout)
        while True:
            st = proto.status()
            if st.state == "Alarm":
                proto.position_lost = True
                raise proto.fail("the machine went into alarm (its position is not to be trusted)",
                                 where or proto.where)
            if st.state in ("Idle", "Check") or (st.state == "Hold" and st.sub == "0"):
                return self._job_position(st)
            if time.monotonic() > deadline:
                raise proto.fail(f"the machine is still {st.state} after its move was answered",
                                 where or proto.where)
            line = proto.readline(0.01)             # let time pass (a simulated clock runs on reads)
            if line is not None:
                proto._handle(line)

    def _job_position(self, st):
        """A GRBL status -> ``(ring, head)`` in the job's (G54 work) coordinates."""
        if st.mpos is None:
            return None
        if "WPos" in st.fields and "MPos" not in st.fields:
            return self._pick(st.mpos)
        wco = st.fields.get("WCO")
        if wco:
            try:
                self._offset = tuple(float(v) for v in wco.split(","))
            except ValueError:
                pass
        if self._offset is None:
            self._offset = self._work_offset()
        offset = self._offset or (0.0,) * len(st.mpos)
        return self._pick(tuple(p - o for p, o in zip(st.mpos, offset)))

    def _marlin_at_rest(self, where, timeout=None):
        """Marlin's ``M114`` reports the *planned* position; its ``Count`` the steppers' own.  Once
        the two agree (the step counts calibrated against the position at the first read after
        each declaration or homing, at rest) the machine has arrived; while they differ it is still moving (an ``M400``
        answered early) and is asked again.  Counts that stop changing without agreeing (steps
        per unit unlike the machine file's) end the wait with a warning."""
        proto = self.proto
        m = self.machine
        steps = (m.values.get("ring.steps_per_deg"), m.values.get("head.steps_per_mm"))
        axes = (m["controller.ring_axis"], m["controller.head_axis"])
        deadline = time.monotonic() + (timeout or proto.motion_timeout)
        last = None
        while True:
            here = self._marlin_position(proto.status())
            counts = proto.last_counts or {}
            if here is None or not all(steps) or not all(a in counts for a in axes):
                return here
            actual = tuple(counts[a] / k for a, k in zip(axes, steps))
            if self._count_shift is None:
                self._count_shift = tuple(h - a for h, a in zip(here, actual))
                return here
            moved = tuple(a + sh for a, sh in zip(actual, self._count_shift))
            tol = self.position_tolerance
            if all(abs(x - y) <= t for x, y, t in zip(moved, here, tol)):
                return here
            if last == actual:
                log.warning("Marlin's step counts (%s) do not match its position %s: are its steps per "
                            "unit (M92) the machine file's?", actual, here)
                self._count_shift = None
                return here
            if time.monotonic() > deadline:
                raise proto.fail("the machine is still moving after its move was answered", where or proto.where)
            last = actual
            proto.readline(0.01)                    # let time pass

    def _marlin_position(self, st):
        axes = st.fields.get("axes") or {}
        ring = axes.get(self.machine["controller.ring_axis"])
        head = axes.get(self.machine["controller.head_axis"])
        return None if ring is None or head is None else (ring, head)

    def position(self):
        """``(ring_deg, head_mm)`` in the job's coordinates as the firmware believes, or None."""
        st = self.proto.status()
        if isinstance(self.proto, GrblLink):
            self._offset = self._work_offset()
            return self._job_position(st)
        return self._marlin_position(st)

    def raw_position(self):
        """The firmware's machine position, every axis in its order (GRBL ``MPos``), or None."""
        return self.proto.status().mpos

    def _work_offset(self):
        """G54's offset from ``$#`` (the motion layer declares positions with ``G10 L20 P1``)."""
        proto = self.proto
        if not isinstance(proto, GrblLink):
            return None
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

    def _axis_index(self, letter):
        names = self._axis_names()
        return names.index(letter) if letter in names else None

    def _pick(self, pos):
        values = dict(zip(self._axis_names(), pos))
        ring = values.get(self.machine["controller.ring_axis"])
        head = values.get(self.machine["controller.head_axis"])
        if ring is None or head is None:
            return None
        return ring, head

    # ---- stopping --------------------------------------------------------------------------
    def stop_point(self):
        """``{"step_index", "move"[, "position"]}``: the first step not handed over, the first of
        its moves not known executed, and where the machine was measured at rest when nothing
        has been sent since (the truth after a reboot, see :mod:`stringbot.winding.resume`)."""
        point = {"step_index": self._step_index, "move": self._move_index}
        if self.rest is not None and not self.proto.position_lost:
            point["position"] = [float(self.rest[0]), float(self.rest[1])]
        return point

    def finish(self):
        self.rest = None
        self.proto.finish(self.dialect.end())

    def hold(self):
        """Feed hold, wait until stopped; the position it stopped at is measured (``rest``)."""
        st = self.proto.hold()
        self.rest = None
        try:
            if not self.proto.position_lost:
                self.rest = (self._job_position(st) if isinstance(self.proto, GrblLink)
                             else self._marlin_position(self.proto.status()))
        except Exception:  # the hold itself succeeded; a failed reading only loses the hint
            log.debug("could not read the held position", exc_info=True)
        return st

    def settle_after_failure(self):
        """After a failure with the port alive and the position kept: wait until the machine
        stands still and measure where (best effort; ``rest`` stays None otherwise)."""
        if self.proto.position_lost or self.rest is not None:
            return
        try:
            here = self.at_rest(timeout=30.0) if isinstance(self.proto, GrblLink) else None
        except Exception:
            return
        self.rest = here

    def take_executed(self):
        return self.proto.take_executed()

    def status(self):
        return self.proto.status()

    def close(self):
        self.proto.close()

    @property
    def lines_sent(self):
        return self.proto.lines_sent


def _point(move):
    return (move.ring_deg, move.head_mm) if isinstance(move, Move) else tuple(move)


def gcode_machine_link(port, machine, **options):
    """The step-level link for a G-code ``machine`` over an open ``port``."""
    from .kinds import gcode_link

    sync = options.pop("sync", "move")
    verify = options.pop("verify", True)
    return GcodeMachineLink(gcode_link(port, machine, **options), machine, sync=sync, verify=verify)

