"""The wind loop: identify, prepare, tie on, wind step by step with a journal, end cleanly.

:class:`Winder` drives any link with the interface of :mod:`stringbot.winding`.
It owns the :class:`WindState`; the link owns its own state.  Ctrl-C arrives as
``KeyboardInterrupt`` in the main thread: the winder asks the link for a feed
hold, waits until the machine has stopped, journals what was executed and
raises :class:`~stringbot.errors.Interrupted`.
"""

import contextlib
import enum
import logging
import math
import time
from dataclasses import dataclass

from ..errors import BadInput, Interrupted, MachineFailure
from ..links import LinkState
from ..motion import move_seconds

__all__ = ["WindState", "Progress", "WindResult", "Winder", "step_seconds"]

log = logging.getLogger(__name__)


class WindState(enum.Enum):
    CONNECTING = "connecting"
    PREPARING = "preparing"
    WAITING = "waiting for the operator"
    WINDING = "winding"
    FINISHING = "finishing"
    DONE = "done"
    INTERRUPTED = "interrupted"
    FAILED = "failed"


@dataclass
class Progress:
    """What the progress callback gets after every executed step."""

    done: int                 # steps executed (of the whole plan)
    total: int
    step: int | None          # the step just executed, numbered from 1
    pin: int | None
    elapsed_s: float          # wall time of this run
    eta_s: float | None       # wall time still needed (machine-time model x measured rate)
    machine_s: float = 0.0    # the machine-time model's seconds still to go


@dataclass
class WindResult:
    """The summary of a winding run."""

    steps_done: int
    total: int
    first_step: int           # numbered from 1: where this run started
    wall_s: float
    machine_s: float          # the model's machine time of the steps this run wound
    firmware: str
    lines_sent: int
    journal: str | None

    @property
    def pins_per_second(self):
        wound = self.steps_done - (self.first_step - 1)
        return wound / self.wall_s if self.wall_s > 0 else math.inf


def step_seconds(steps, machine, start=(0.0, None)):
    """Machine seconds of each step by the motion layer's trapezoid model."""
    ring_feed, ring_acc = machine["ring.feed_deg_per_min"], machine["ring.accel_deg_per_s2"]
    head_feed, head_acc = machine["head.feed_mm_per_min"], machine["head.accel_mm_per_s2"]
    ring, head = start[0], start[1] if start[1] is not None else machine["head.in_mm"]
    out = []
    for step in steps:
        t = step.dwell_s
        for mv in step.moves:
            dr, dh = abs(mv.ring_deg - ring), abs(mv.head_mm - head)
            if dr > 1e-9:
                t += move_seconds(dr, mv.feed or ring_feed, ring_acc)
            if dh > 1e-9:
                t += move_seconds(dh, mv.feed or head_feed, head_acc)
            ring, head = mv.ring_deg, mv.head_mm
        out.append(t)
    return out


class Winder:
    """One winding run over an open link.

    Parameters
    ----------
    link : the step-level link (see :mod:`stringbot.winding`)
    steps : list of HookStep, the whole plan's
    machine : Machine
    journal : Journal or None
    progress : callable(Progress) or None
    confirm : callable(str) -> bool, or None to skip questions
    """

    def __init__(self, link, steps, machine, *, journal=None, progress=None, confirm=None):
        self.link = link
        self.steps = steps
        self.machine = machine
        self.journal = journal
        self.progress = progress
        self.confirm = confirm
        self.state = WindState.CONNECTING
        self.threads = None                 # a colour plan's spool changes (winding.layers.Threads)
        self.done = 0                       # steps executed (0..len(steps))
        self.est = step_seconds(steps, machine)
        self._t0 = None
        self._first = 0
        self._est_done = 0.0
        self._journal_broken = False

    # ---- the run ---------------------------------------------------------------------
    def start(self, *, home, before_homing=None):
        """Identify the firmware, check alarms, home if asked, set modal state.

        ``before_homing()`` (when homing) makes sure homing starts from a safe position and
        returns what it found (:func:`stringbot.winding.homing.check_before_homing`); that is
        journaled as a ``homing`` record before the first homing line."""
        self.state = WindState.CONNECTING
        info = self.link.info if _identified(self.link) else self.link.identify()
        self.state = WindState.PREPARING
        with self.stopping("while preparing (homing)"):
            if home and before_homing is not None:
                checked = before_homing()
                if self.journal is not None:
                    self.journal.append({"kind": "homing", **checked})
            self.link.prepare(home=home)
        return info

    @contextlib.contextmanager
    def stopping(self, what):
        """Around the moves before the winding proper (homing, the first moves): Ctrl-C stops the
        machine; any stop is journaled (a ``stop`` record) so that the next run knows of it."""
        try:
            yield
        except KeyboardInterrupt:
            self._stop_record("interrupted", f"interrupted {what}", self._hold_quietly())
            raise Interrupted(f"interrupted {what}: the machine is stopped; no step was wound meanwhile") from None
        except Interrupted as exc:
            self._declined(exc)
            raise
        except MachineFailure as exc:
            self._failed(exc)
            raise

    def _hold_quietly(self):
        """Ctrl-C outside the winding proper: stop the machine (its status, or None)."""
        self.state = WindState.INTERRUPTED
        try:
            return self.link.hold()
        except (KeyboardInterrupt, MachineFailure) as exc:
            log.warning("could not stop the machine cleanly: %s", exc)
            return None

    def _declined(self, exc):
        """The operator stopped (a question declined, a guide quit), or the winding stopped for a
        person (SpoolChange): the machine stands at rest where the last move ended; the stop record
        keeps that measured position (after a reboot, e.g. an Uno's on open, it is the truth)."""
        self.state = WindState.INTERRUPTED
        layer = getattr(exc, "layer", None)
        self._stop_record(getattr(exc, "reason", "interrupted"), str(exc), None,
                          **({} if layer is None else {"layer": layer}))

    @contextlib.contextmanager
    def stopping_on_ctrl_c(self, what):
        """Ctrl-C outside the winding proper (recovering): stop the machine, then say so."""
        try:
            yield
        except KeyboardInterrupt:
            self._hold_quietly()
            raise Interrupted(f"interrupted {what}: the machine is stopped; no step was wound meanwhile") from None

    def ask(self, message):
        """Ask the operator (True to go on); declining stops cleanly with nothing moved."""
        if self.confirm is None:
            return
        self.state = WindState.WAITING
        if not self.confirm(message):
            self.state = WindState.INTERRUPTED
            raise Interrupted("stopped by the operator before winding")

    def wind(self, first=0, *, first_moves=None, finish=True):
        """Wind steps ``first``.. to the end; ``first_moves`` are what is left of step ``first``."""
        self.state = WindState.WINDING
        self._first = first
        self.done = first
        self._t0 = time.monotonic()
        self._est_done = 0.0
        if hasattr(self.link, "on_move") and self.journal is not None:
            self.link.on_move = self._moved
        try:
            if first_moves is not None and first < len(self.steps):
                self._thread_for(first)
                self.link.execute_lines(self.steps[first], first_moves, self._executed)
                first += 1
            runs = [(first, len(self.steps))] if self.threads is None else self.threads.runs(first, len(self.steps))
            for a, b in runs:               # a colour plan: one run per layer, a spool change between
                self._thread_for(a)
                self.link.execute(self.steps[a:b], self._executed)
            if finish:
                self.state = WindState.FINISHING
                self.link.finish()
        except KeyboardInterrupt:
            self._interrupted()
        except Interrupted as exc:          # declined at a spool change, or stopped there for a person
            self._declined(exc)
            raise
        except MachineFailure as exc:
            self._failed(exc)
            raise
        self.state = WindState.DONE
        if self.journal is not None:
            self.journal.append({"kind": "finished"})
        return WindResult(steps_done=self.done, total=len(self.steps), first_step=self._first + 1,
                          wall_s=time.monotonic() - self._t0,
                          machine_s=sum(self.est[self._first:self.done]),
                          firmware=_firmware_name(self.link), lines_sent=self.link.lines_sent,
                          journal=str(self.journal.path) if self.journal else None)

    def _thread_for(self, step):
        """A colour plan: the thread of ``step``'s layer tied on (the operator asked at a spool change)."""
        if self.threads is not None and step < len(self.steps):
            previous, self.state = self.state, WindState.WAITING
            self.threads.before(step)
            self.state = previous

    # ---- bookkeeping -------------------------------------------------------------------
    def _executed(self, step):
        if self.journal is not None:
            self._journaled(self.journal.done, step.index, step.pin, after=step)
        self.done = step.index + 1
        self._est_done += self.est[step.index]
        if self.progress is not None:
            self.progress(self._progress(step))

    def _moved(self, step, move):
        """Move ``move`` of ``step`` executed (journaled so that resume knows where the head is)."""
        if move + 1 < len(step.moves) and self._outside(step.moves[move].head_mm):
            self._journaled(self.journal.append, {"kind": "move", "step": step.index, "move": move})

    def _journaled(self, write, *args, after=None):
        """Write a journal record; if the disk refuses (full, read-only, gone), stop the machine first
        and fail: the journal is the truth, and a winding it cannot follow must not go on."""
        try:
            write(*args)
        except OSError as exc:
            from .._files import problem
            self._journal_broken = True
            try:
                self.link.hold()
            except (MachineFailure, KeyboardInterrupt) as stop:
                log.warning("could not stop the machine cleanly: %s", stop)
            what = f"after step {after.index + 1} (pin {after.pin})" if after is not None else "mid-step"
            raise MachineFailure(f"cannot write the journal {str(self.journal.path)!r}: {problem(exc)}; the "
                                 f"machine is stopped {what}; make room, then resume") from None

    def _outside(self, head_mm):
        """Head past the pin circle (only those moves are journaled: they decide the head side)."""
        m = self.machine
        h_in, h_out = m["head.in_mm"], m["head.out_mm"]
        return abs(head_mm - h_out) < abs(head_mm - h_in)

    def _progress(self, step):
        elapsed = time.monotonic() - self._t0
        remaining = sum(self.est[self.done:]) if self.done < len(self.est) else 0.0
        wound = self.done - self._first
        if wound >= 3 and self._est_done > 0:
            rate = elapsed / self._est_done            # wall seconds per model second
            eta = remaining * rate
        else:
            eta = remaining
        return Progress(done=self.done, total=len(self.steps), step=step.index + 1, pin=step.pin,
                        elapsed_s=elapsed, eta_s=eta, machine_s=remaining)

    def _catch_up(self):
        """Journal the steps the link confirmed while stopping."""
        if self._journal_broken:
            return                # they stay unjournaled: resume finds them from the machine's position
        try:
            for step in self.link.take_executed():
                self._executed(step)
        except Exception:  # the journal write failing here must not hide the stop
            log.exception("could not journal the last executed steps")
        self._as_journaled()

    def _as_journaled(self):
        """A Ctrl-C that lands after a step's ``done`` line reached the journal but before
        :attr:`done` counted it (the fsync is the longest part of a step's bookkeeping) leaves the
        journal a step ahead: the journal is the truth the stop line, the stop record and
        ``--resume`` must all tell."""
        if self.journal is None or self._journal_broken:
            return
        from .journal import read_journal
        try:
            self.done = max(self.done, read_journal(self.journal.path).next_step)
        except (BadInput, OSError) as exc:
            log.warning("could not read the journal back: %s", exc)

    def _current(self):
        if self.done < len(self.steps):
            st = self.steps[self.done]
            return st.index + 1, st.pin
        return None, None

    def _interrupted(self):
        self.state = WindState.INTERRUPTED
        status = None
        try:
            status = self.link.hold()
        except KeyboardInterrupt:
            log.warning("second Ctrl-C: not waiting for the machine to stop")
        except MachineFailure as exc:
            log.warning("feed hold failed: %s", exc)
        self._catch_up()
        step, pin = self._current()
        point = self._stop_record("interrupted", "interrupted by the operator (Ctrl-C)", status)
        where = f"pin {pin}, step {step} of {len(self.steps)}" if step else "the end"
        raise Interrupted(f"interrupted at {where}{self._hooked_already(point)}: the machine is stopped; "
                          f"{self.done} of {len(self.steps)} steps done") from None

    def _hooked_already(self, point):
        """What the stop line adds when the stop (the link's ``point``, as journaled) came after the
        current step's pin was wrapped: its last move (the head back IN) is all that is left of it."""
        if not point or point["step_index"] != self.done or self.done >= len(self.steps):
            return ""
        st = self.steps[self.done]
        if point["move"] < len(st.moves) - 1:
            return ""
        left = "the head still out: step {} lacks only the head's move back in" if point["move"] == len(st.moves) - 1 \
            else "the head back in: step {} lacks only its end (its dwell, its sync)"
        return f" (pin {st.pin} is wrapped already, {left.format(st.index + 1)}, so it is not counted done)"

    def _failed(self, exc):
        self.state = WindState.FAILED
        self._catch_up()
        settle = getattr(self.link, "settle_after_failure", None)
        if settle is not None:
            settle()
        self._stop_record("failed", str(exc), None)

    def _stop_record(self, reason, message, status, **extra):
        """Journal the stop; returns the link's stop point (``{"step_index", "move"}``, None unknown)."""
        if self.journal is None:
            return None
        step, pin = self._current()
        pos = None
        point = None
        if hasattr(self.link, "stop_point"):
            try:
                stop = self.link.stop_point()
                point = {"step_index": stop["step_index"], "move": stop["move"]}
                # where the link last knew the machine without asking it now: a G-code link's
                # position measured at rest with nothing sent since (the held position after
                # Ctrl-C), a servo link's last reading with torque on; the resume's truth
                # after a reboot or a power loss
                pos = stop.get("position")
            except Exception:
                point = None
        try:
            self.journal.append({"kind": "stop", "reason": reason, "error": message,
                                 "step": step, "pin": pin, "next_step": self.done, "at": point,
                                 "position_lost": bool(getattr(self.link, "position_lost", False)),
                                 "position": list(pos) if pos else None, **extra})
        except OSError as exc:
            log.warning("could not write the journal's stop record: %s", exc)
        return point


def _firmware_name(link):
    info = getattr(link, "info", None)
    if info is None:
        return "?"
    return f"{info.name} {info.version}".strip()


def _identified(link):
    """The link has just identified the firmware (e.g. for the settings check): no need to ask again."""
    return getattr(link, "info", None) is not None and getattr(link, "state", None) is LinkState.IDENTIFIED
