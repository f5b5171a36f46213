"""The GRBL / grblHAL / FluidNC link: character counting, status reports, feed hold.

Streaming follows GRBL's own interface document: the host keeps the count of
bytes it has sent that the firmware has not yet answered (``ok`` or
``error:N``, one per line, in order) and never lets it exceed the firmware's
receive buffer (128 bytes on GRBL; what ``$I``'s ``[OPT:...,blocks,rx]``
reports, e.g. 1024 on grblHAL).  Push messages (``<...>`` status, ``[...]``,
``ALARM:N``, the banner) are not answers and are handled apart.

A step counts as executed only when the answer to the ``G4 P0`` that follows
its lines arrives: GRBL answers a dwell only once every earlier motion has
finished.  Lines of the next step(s) may already be in the receive buffer
(``lookahead``), so the machine never waits for the host between steps.

An ``ok`` is only ever counted for the oldest unanswered line.  A lost ``ok``
is never inferred from an ``Idle`` status alone (GRBL reports ``Idle`` during
a ``G4`` dwell, with lines still waiting behind it): after a silence with the
machine idle, the link sends ``$G`` (the probe); GRBL reads it only once every
earlier line is done, and answers ``[GC:...]`` then ``ok``.  That ``[GC:...]``
accounts for every line sent before the probe.  The probe's few bytes are kept
free in the receive buffer, so it always fits.
"""

import logging
import re
import time
from collections import deque

from firmware_protocol import grbl as grbl_codes
from firmware_protocol.kinds import get_kind

from .base import LineLink, LinkState, Status, Where, strip_comment, where_of
from .grbl_identify import GrblIdentify

__all__ = ["GrblLink", "parse_status"]

log = logging.getLogger(__name__)

_RESET = b"\x18"
_PROBE = "$G"                          # answered [GC:...] + ok, once every earlier line is done
_PROBE_BYTES = len(_PROBE) + 1
_GC = re.compile(r"^\[(GC:|G\d)")      # $G's answer (GRBL 1.1 / 0.9)


def parse_status(line):
    """``<Idle|MPos:1.000,2.000,0.000|Bf:15,128|FS:0,0>`` -> :class:`Status` (GRBL 1.1 and 0.9 forms,
    by the family's one parser, :func:`firmware_protocol.grbl.parse_status`; a malformed position
    is None)."""
    st = grbl_codes.parse_status(line, strict=False) or grbl_codes.Status(state=line.strip()[1:-1])
    sub = "" if st.substate is None else str(st.substate)
    return Status(state=st.state, sub=sub, mpos=st.mpos or st.wpos, fields=st.fields)


class GrblLink(GrblIdentify, LineLink):
    """A G-code link to GRBL 1.1 or grblHAL.

    Parameters
    ----------
    port : an open pyserial port
    dialect : a GRBL-family kind of :data:`firmware_protocol.kinds.KINDS` (``controller.dialect``)
    sync_line : the line whose answer means "all motion finished" (default: the kind's, ``G4 P0``)
    lookahead : how many steps beyond the last executed one may be sent
    """

    def __init__(self, port, dialect="grbl", *, sync_line=None, lookahead=1,
                 response_timeout=3.0, motion_timeout=600.0, poll_interval=0.5):
        super().__init__(port, response_timeout=response_timeout)
        self.dialect = dialect
        self.kind = get_kind(dialect)
        self.sync_line = sync_line or self.kind.sync_line
        self.lookahead = lookahead
        self.motion_timeout = motion_timeout
        self.poll_interval = poll_interval
        self.rx_size = self.kind.rx_buffer
        self.planner_blocks = 0
        self._inflight = deque()      # (nbytes, Where) for lines sent and not yet answered
        self._inflight_bytes = 0
        self.last_status = None
        self.max_inflight_bytes = 0   # for tests: character counting never exceeds rx_size
        self.status_log = None        # list -> every status report is appended as (time, Status)
        self.status_interval = None   # seconds: ask ``?`` this often while waiting (measurements)
        self._last_query = 0.0
        self._probe = None            # the Where of the $G probe in flight, if any
        self._probe_seen = False      # its [GC:...] arrived: every line before it is done
        self.settings = None          # the firmware's $$ once read (read_settings)

    # ---- state -----------------------------------------------------------------------
    def status(self, timeout=None):
        """Ask ``?`` and return the next status report (answers in between are handled)."""
        self.write(b"?")
        deadline = time.monotonic() + (timeout or self.response_timeout)
        while True:
            line = self.readline(max(0.0, deadline - time.monotonic()))
            if line is None:
                raise self.fail("the machine stopped answering (no status report)")
            if line.startswith("<"):
                return self._status(line)
            self._handle(line)

    def _status(self, line):
        st = parse_status(line)
        self.last_status = st
        if self.status_log is not None:
            self.status_log.append((time.monotonic(), st, len(self._inflight)))
        return st

    def command(self, text, timeout=None):
        """Send one line and wait for its answer (send-response), e.g. ``$H`` or ``$X``."""
        self._send(text, Where())
        self._wait_answers(0, timeout or self.response_timeout)

    def prepare(self, *, home=False, preamble=(), home_lines=("$H",)):
        """Check for alarms, home if asked, set the modal state.

        An alarm on a machine that is not homed here is refused with the alarm's words.
        """
        st = self.status()
        if st.state == "Alarm":
            if not home:
                raise self.fail("the machine is in alarm (it asks to be homed or unlocked); "
                                "check it, then unlock it ($X: nothing moves)")
        elif st.state not in ("Idle", "Check"):
            raise self.fail(f"the machine is not idle (state {st.state}); stop or reset it first")
        self._home_and_preamble(home, home_lines, preamble, self.motion_timeout)

    # ---- streaming -------------------------------------------------------------------
    def execute(self, steps, lines_for, on_executed=None):
        """Stream ``steps``; call ``on_executed(step)`` as each one is confirmed executed.

        ``lines_for(step)`` gives the step's G-code lines; a sync line is appended.
        Returns when every step is executed.
        """
        self.state = LinkState.STREAMING
        pending = deque()                       # steps sent, not yet confirmed
        for step in steps:
            while len(pending) > self.lookahead:
                self._wait_answers(len(self._inflight) - 1, self.motion_timeout)
                self._deliver(pending, on_executed)
            where = where_of(step)
            if not pending:
                self.where = where
            for text in lines_for(step):
                text = strip_comment(text)
                if text:
                    self._send(text, where)
            self._send(self.sync_line, where_of(step, sync=True))
            pending.append(step)
            self._poll()
            self._deliver(pending, on_executed)
        while pending:
            self._wait_answers(len(self._inflight) - 1, self.motion_timeout)
            self._deliver(pending, on_executed)
        self.state = LinkState.READY

    def run_lines(self, lines, where):
        """Send ``lines`` and the sync line in one write; return once the sync is answered.

        The firmware gets them together, so nothing reaches it while an earlier
        move still runs: a fault on arrival finds the machine where the last
        executed line left it.
        """
        texts = [t for t in (strip_comment(x) for x in lines) if t] + [self.sync_line]
        data = b"".join(t.encode("ascii") + b"\n" for t in texts)
        self.state = LinkState.STREAMING
        self.where = where
        if len(data) > self._room():
            for t in texts:
                self._send(t, where)
        else:
            while self._inflight_bytes + len(data) > self._room():
                self._wait_answers(len(self._inflight) - 1, self.motion_timeout)
            log.debug("-> %s", " | ".join(texts))
            self.write(data)
            for t in texts:
                n = len(t) + 1
                self._inflight.append((n, where))
                self._inflight_bytes += n
                self.lines_sent += 1
            self.max_inflight_bytes = max(self.max_inflight_bytes, self._inflight_bytes)
        self._wait_answers(0, self.motion_timeout)
        self.state = LinkState.READY

    def _deliver(self, pending, on_executed):
        for step in self.take_executed():
            if pending and pending[0] is step:
                pending.popleft()
            if pending:
                self.where = where_of(pending[0])
            if on_executed is not None:
                on_executed(step)

    def finish(self, lines=()):
        """Send the closing lines and wait until the machine has executed them."""
        for line in lines:
            line = strip_comment(line)
            if line:
                self._send(line, Where())
        self._send(self.sync_line, Where())
        self._wait_answers(0, self.motion_timeout)
        self.state = LinkState.READY

    def _send(self, text, where):
        data = text.encode("ascii") + b"\n"
        if len(data) > self._room():
            raise self.fail(f"line longer than the firmware's receive buffer: {text[:40]!r}", where)
        while self._inflight_bytes + len(data) > self._room():
            self._wait_answers(len(self._inflight) - 1, self.motion_timeout)
        self._put(text, where)

    def _room(self):
        """Bytes lines may fill: the receive buffer less what the probe needs."""
        return self.rx_size - _PROBE_BYTES

    def _put(self, text, where):
        data = text.encode("ascii") + b"\n"
        log.debug("-> %s", text)
        self.write(data)
        self._inflight.append((len(data), where))
        self._inflight_bytes += len(data)
        self.max_inflight_bytes = max(self.max_inflight_bytes, self._inflight_bytes)
        self.lines_sent += 1

    def _poll(self):
        """Handle whatever answers are already waiting, without blocking."""
        while True:
            if self._rx.find(b"\n") < 0:
                try:
                    waiting = self.port.in_waiting
                except Exception:
                    waiting = 0
                if not waiting:
                    return
            line = self.readline(0.0)
            if line is None:
                return
            self._handle(line)

    def _wait_answers(self, at_most, timeout):
        """Read until no more than ``at_most`` lines are unanswered.

        While waiting on motion, silence is met with a status query.  A machine that
        does not answer it has gone away.  One that reports Idle twice may have lost
        an ``ok``, or may be in a dwell (GRBL reports Idle during ``G4``): the link then
        sends the ``$G`` probe, whose ``[GC:...]`` proves every earlier line done.
        Nothing is ever counted as answered on the strength of a status report.
        """
        deadline = time.monotonic() + timeout
        idle_polls = 0
        mine = []                             # probes sent here: each is one more line to wait for
        while len(self._inflight) > at_most:
            if self.status_interval:
                now = time.monotonic()
                if now - self._last_query >= self.status_interval:
                    self.write(b"?")
                    self._last_query = now
                line = self.readline(min(self.poll_interval, self.status_interval))
                if line is None and time.monotonic() - self._last_query < self.poll_interval:
                    continue
            else:
                line = self.readline(self.poll_interval)
            if line is not None:
                idle_polls = 0
                self._handle(line)
                continue
            if time.monotonic() > deadline:
                raise self.fail(f"the machine did not finish within {timeout:.0f} s")
            st = self.status()
            if st.state == "Alarm":
                raise self.fail("the machine went into alarm")
            if st.state == "Idle" and self._rx.find(b"\n") < 0:
                idle_polls += 1
                if idle_polls >= 2:
                    idle_polls = 0
                    before = self._probe
                    dropped = self._send_probe()
                    if dropped is not None and any(dropped is p for p in mine):
                        at_most -= 1
                    if self._probe is not None and self._probe is not before:
                        mine.append(self._probe)
                        at_most += 1
            else:
                idle_polls = 0

    def _send_probe(self):
        """Send ``$G`` behind the unanswered lines, unless one is already on its way.

        A probe whose ``[GC:...]`` came but whose ``ok`` did not is done (its ``ok``
        was lost): it is dropped first.  Returns the probe dropped, if any.
        """
        dropped = None
        if self._probe is not None:
            if not (self._probe_seen and self._inflight and self._inflight[0][1] is self._probe):
                return None                   # still behind a dwell or a long line
            log.warning("the answer to the $G probe was lost")
            dropped = self._answered()
        if not self._inflight:
            return dropped
        if self._inflight_bytes + _PROBE_BYTES > self.rx_size:  # pragma: no cover - room is kept
            return dropped
        log.info("the machine is idle with %d lines unanswered: asking $G to account for them",
                 len(self._inflight))
        self._probe, self._probe_seen = Where(), False
        self._put(_PROBE, self._probe)
        return dropped

    def _probe_answered(self):
        """``[GC:...]`` of the probe: every line sent before it is done, answered or not."""
        lost = 0
        while self._inflight and self._inflight[0][1] is not self._probe:
            self._answered()
            lost += 1
        self._probe_seen = True
        if lost:
            log.warning("%d answers were lost; the $G probe accounts for them", lost)

    def _answered(self, ok=True):
        nbytes, where = self._inflight.popleft()
        self._inflight_bytes -= nbytes
        if where is self._probe:
            self._probe, self._probe_seen = None, False
        if ok and where.sync and where.item is not None:
            self.executed.append(where.item)
        return where

    def _handle(self, line):
        """One line from the firmware while streaming."""
        if line.startswith("ok"):
            if not self._inflight:
                log.warning("an 'ok' for nothing sent: ignored")
                return
            self._answered()
        elif line.startswith("error"):
            code = _code(line)
            where = self._inflight[0][1] if self._inflight else self.where
            if self._inflight:
                self._answered(ok=False)      # a refused sync proves nothing was executed
            if self.state is LinkState.STREAMING:
                self.stop_quietly()           # a refused command between jobs moves nothing to stop
            raise self.fail(f"the machine refused a line: {_error_words(code) if code is not None else line}",
                            where)
        elif line.startswith("ALARM"):
            code = _code(line)
            if code in (1, 3, 6, 7, 8, 9, 10):
                self.position_lost = True
            self.stop_quietly(hold=False)
            raise self.fail(f"the machine raised {_alarm_words(code) if code is not None else line}")
        elif line.startswith("<"):
            self._status(line)
        elif self.restarted(line):
            self.position_lost = True
            if self.state is not LinkState.STREAMING and self.state is not LinkState.READY:
                log.info("the firmware (re)started: %s", line)
                return
            raise self.fail("the firmware reset itself mid-job (it printed its banner again); "
                            "its position may be lost")
        elif self._probe is not None and not self._probe_seen and _GC.match(line):
            self._probe_answered()
        elif line.startswith(("[", "$", ">", "Grbl")):
            log.info("machine says: %s", line)
        else:
            self.stop_quietly()
            raise self.fail(f"the machine answered garbage: {line[:60]!r}")

    # ---- stopping --------------------------------------------------------------------
    def hold(self, timeout=30.0):
        """Feed hold (``!``, realtime) and wait until the machine has stopped; returns its status.

        Answers that arrive meanwhile are handled: steps whose sync is answered are
        still reported through :meth:`take_executed`.
        """
        self.state = LinkState.HOLDING
        self.write(b"!")
        deadline = time.monotonic() + timeout
        while True:
            st = self.status()
            if st.stopped:
                self._poll_quietly()
                return st
            if st.state == "Home":
                # a homing cycle ignores feed hold: only a reset stops it (GRBL then alarms)
                self.write(_RESET)
                self.position_lost = True
                self.drain_input(quiet=0.2, limit=2.0)
                return self.status()
            if time.monotonic() > deadline:
                raise self.fail(f"the machine did not stop within {timeout:.0f} s of a feed hold")
            time.sleep(0.02)

    def _poll_quietly(self):
        """Take the answers that are still coming once stopped (best effort)."""
        try:
            while True:
                line = self.readline(0.05)
                if line is None:
                    return
                if line.startswith("ok"):
                    if self._inflight:
                        self._answered()
                elif self._probe is not None and not self._probe_seen and _GC.match(line):
                    self._probe_answered()
                elif line.startswith("<"):
                    self._status(line)
        except Exception:
            return

    def stop_quietly(self, hold=True):
        """After an error: feed hold, best effort (the caller raises the real error).  What is
        still queued stays queued: resume flushes it once the machine stands still."""
        state = self.state
        try:
            if hold:
                self.write(b"!")
        except Exception:
            pass
        self.state = state

    def flush(self):
        """Soft reset (0x18) to drop queued lines once stopped; reads the banner back."""
        self.write(_RESET)
        self.forget_unanswered()
        self.drain_input(quiet=0.2, limit=2.0)

    def forget_unanswered(self):
        """Start counting afresh (lines another session sent are not ours to count)."""
        self._inflight.clear()
        self._inflight_bytes = 0
        self._probe, self._probe_seen = None, False

    def unanswered(self):
        """Lines sent and not yet answered (for tests and for resume)."""
        return [w for _, w in self._inflight]


def _code(line):
    m = re.search(r":\s*(\d+)", line)
    return int(m.group(1)) if m else None


def _error_words(code):
    """``error:N`` with GRBL's own words for it."""
    return f"error:{code} ({grbl_codes.describe_error(code)})"


def _alarm_words(code):
    """``ALARM:N`` with GRBL's own words for it."""
    return f"ALARM:{code} ({grbl_codes.describe_alarm(code)})"
