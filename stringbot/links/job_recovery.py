"""What a G-code machine link does between windings: reconnect, declare, home, jog.

:class:`GcodeRecovery` is the half of :class:`~stringbot.links.job.GcodeMachineLink`
that a resume uses (``stringbot.winding.resume``): settle a machine left
running or holding, identify it again and say what it had lost, clear an
alarm without moving, move one axis at a time (each move verified like a
winding's), declare a position and read it back, home, and jog by a relative
amount on a machine whose position is not known (the operator's guided way
back to a reference).
"""

import logging
import time
from dataclasses import dataclass, field

from ..motion import Move
from .grbl import GrblLink

__all__ = ["GcodeRecovery", "Reconnected"]

log = logging.getLogger(__name__)


@dataclass
class Reconnected:
    """What a reconnect learned (journaled before anything is asked or refused)."""

    banner: bool = False             # the firmware (re)started: a reset, a power-up, a reboot on open
    alarm: str | None = None         # the alarm it was in ("ALARM:3", or "Alarm" from a status)
    cleared: bool = False            # the alarm was cleared ($X) without moving
    mpos: list | None = None         # the firmware's machine position, every axis (None: no report)
    said: list = field(default_factory=list)

    @property
    def wiped(self):
        """The firmware's position reads all zeros after a (re)start: it is gone."""
        return self.banner and self.mpos is not None and all(abs(v) < 1e-9 for v in self.mpos)

    @property
    def position_lost(self):
        return self.banner or self.alarm is not None

    def as_record(self):
        return {"banner": self.banner, "alarm": self.alarm, "alarm_cleared": self.cleared,
                "mpos": self.mpos, "position_wiped": self.wiped}


class GcodeRecovery:
    """Mixin of :class:`~stringbot.links.job.GcodeMachineLink`: the resume's operations."""

    def reconnect(self, timeout=600.0):
        """After a stop: settle the machine, identify it, clear an alarm without moving.

        A machine still running the lines it had (its host died) is waited for; one
        in feed hold is flushed (GRBL: soft reset once stopped, which keeps its
        position).  Returns a :class:`Reconnected`: whether the firmware (re)started
        (banner) or was in alarm, and the machine position it reports.
        """
        proto = self.proto
        said = proto.drain_input(quiet=0.05, limit=2.5)
        grbl = isinstance(proto, GrblLink)
        if grbl:
            said += self._settle(timeout)
        info = proto.identify()
        self._read_settings()
        lines = list(said) + list(info.lines)
        seen = Reconnected(said=lines)
        seen.banner = proto.position_lost or any(proto.restarted(x) for x in lines)
        alarms = [x for x in lines if x.startswith("ALARM")]
        seen.alarm = alarms[-1] if alarms else None
        if grbl:
            st = proto.status()
            if st.state == "Alarm":
                seen.alarm = seen.alarm or "Alarm"
                proto.command("$X")
                seen.cleared = True
                st = proto.status()
            seen.mpos = list(st.mpos) if st.mpos is not None else None
        else:
            st = proto.status()
            seen.mpos = list(st.mpos) if st.mpos is not None else None
        self._offset = self._count_shift = None
        self.here = self.rest = None
        return seen

    def _settle(self, timeout):
        proto = self.proto
        deadline = time.monotonic() + timeout
        said = []
        while True:
            st = proto.status()
            if st.state == "Hold" and st.sub == "0":
                proto.flush()
                continue
            if st.state in ("Idle", "Alarm", "Check"):
                said += proto.drain_input(quiet=0.05, limit=0.5)
                proto.forget_unanswered()
                return said
            if time.monotonic() > deadline:
                raise proto.fail(f"the machine is still {st.state} after {timeout:.0f} s; stop it and resume")
            time.sleep(0.05)

    def restore_modal(self):
        """Millimetres, absolute positions, feed per minute (what a reset forgets)."""
        self.proto.prepare(home=False, preamble=self.dialect.preamble())

    def move_to(self, ring_deg, head_mm, *, axis):
        """One straight move of ``axis`` ("ring" or "head") at its feed, waited for and verified.

        Only that axis is named in the line: the other one does not move, whatever the
        firmware believes of it.
        """
        m = self.machine
        feed = m["ring.feed_deg_per_min"] if axis == "ring" else m["head.feed_mm_per_min"]
        if self.here is not None:
            start = (ring_deg, self.here[1]) if axis == "head" else (self.here[0], head_mm)
        else:
            start = None
        move = Move(ring_deg, head_mm, feed)
        self.rest = None
        line = self.dialect.move_line(move, start) if start is not None else _one_axis(self, move, axis)
        self.proto.run_lines([line], self.proto.where)
        if self.verify:
            self._verify(move, self.proto.where, f"moving the {axis}")
        self.here = (ring_deg, head_mm)

    def set_position(self, ring_deg, head_mm):
        """Declare where the machine is (after homing or an operator's check) and read it back.

        Returns the position the firmware then reports (job coordinates).
        """
        self.proto.command(self.dialect.set_position(ring_deg, head_mm))
        self._offset = self._count_shift = None
        self.here = (ring_deg, head_mm)
        back = self.position()
        tol = self.position_tolerance
        if back is None or abs(back[0] - ring_deg) > tol[0] or abs(back[1] - head_mm) > tol[1]:
            raise self.proto.fail(f"declared ring {ring_deg:.3f}, head {head_mm:.3f}, but the machine "
                                  f"reads back {back}; check the machine file's axes")
        self.rest = (ring_deg, head_mm)
        self.proto.position_lost = False
        return back

    def home(self, axes=None):
        """Home (``$H`` / ``G28``), or only ``axes`` ("head", "ring") where the firmware can."""
        timeout = getattr(self.proto, "motion_timeout", 600.0)
        self.proto.command(self.dialect.home_command(axes), timeout=timeout)
        self._offset = self._count_shift = None
        self.here = self.rest = None

    def jog(self, *, ring=0.0, head=0.0):
        """Move by a relative amount (the operator's jog; the position need not be known)."""
        m = self.machine
        for axis, delta, feed in (("ring", ring, m["ring.feed_deg_per_min"]),
                                  ("head", head, m["head.feed_mm_per_min"])):
            if delta:
                self.rest = self.here = None
                # relative, then absolute again, then the sync: sent together and waited for
                self.proto.run_lines(self.dialect.jog_lines(axis, delta, feed), self.proto.where)

    def unlock(self):
        if isinstance(self.proto, GrblLink):
            self.proto.command("$X")

    def flush(self):
        """Drop queued lines (GRBL: soft reset once stopped)."""
        if isinstance(self.proto, GrblLink):
            self.proto.flush()


def _one_axis(link, move, axis):
    letter = link.dialect.ring_axis if axis == "ring" else link.dialect.head_axis
    value = move.ring_deg if axis == "ring" else move.head_mm
    from ..motion.gcode import fmt
    return f"G1 {letter}{fmt(value)} F{fmt(move.feed)}"


def started(line):
    """A line a firmware of any kind prints when it (re)starts: a banner of the records
    (:mod:`firmware_protocol.kinds`; the link's own kind: ``proto.restarted``)."""
    from firmware_protocol.kinds import KINDS
    return bool(line) and any(k.is_banner(line) for k in KINDS.values())
