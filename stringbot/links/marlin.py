"""The Marlin link: line numbers, checksums, resends, ``busy`` keepalives, ``M400`` syncs.

Every line goes out as ``N<n> <gcode>*<checksum>`` (XOR of the bytes before
``*``), one at a time: Marlin answers ``ok`` once it has taken the line.  A
line that arrives damaged gets ``Error:...``, ``Resend: <n>`` and an ``ok``;
the link sends line ``n`` again (and any after it).  ``echo:busy: processing``
while a long command runs keeps the wait alive.  A step counts as executed
when the ``ok`` of the ``M400`` after its lines arrives (``M400`` waits for
every move to finish).

Silence after a line that waits on motion (``M400``, ``G4``, ``G28``, moves) is
normal when the busy keepalive is off (``M113 S0``): it is allowed up to
``motion_timeout``, and such a line is never sent twice (a duplicate would draw
a ``Resend:`` and shift which ``ok`` answers which line).  To find a lost
``ok`` meanwhile, the link sends the next numbered line early as ``M114``:
Marlin runs it only after the waiting line, so its ``X:...`` report proves
that line done.

A Marlin that sends ``busy:`` keepalives (``M113 S<period>``, on by default) says
something at least once a period while it waits on motion.  Once the link has
measured that period (the longest gap between two keepalives of one wait), a
motion wait that hears nothing for :func:`hang_after` (three periods, at least
:data:`HANG_FLOOR_S`) ends with "the machine stopped answering" instead of
waiting ``motion_timeout``; with keepalives heard but no period measured yet,
:data:`HANG_CAP_S` (three times ``M113``'s longest period) is the limit.
"""

import logging
import re
import time

from firmware_protocol import grbl as grbl_codes
from firmware_protocol import marlin as marlin_codes
from firmware_protocol.kinds import get_kind

from .base import FirmwareInfo, LineLink, LinkState, Status, Where, strip_comment, where_of

__all__ = ["MarlinLink", "numbered", "hang_after", "HANG_FLOOR_S", "HANG_CAP_S"]

log = logging.getLogger(__name__)

#: Keepalive periods of silence after which a waiting Marlin is declared unresponsive.
HANG_PERIODS = 3
#: Never sooner than this (seconds): a loaded host, a USB hiccup.
HANG_FLOOR_S = 5.0
#: Never later than this once keepalives were heard (``M113`` allows periods up to 60 s).
HANG_CAP_S = 180.0


def hang_after(period_s):
    """Seconds of silence that mean a Marlin whose keepalive period is ``period_s`` (None: not
    measured yet) has stopped: ``HANG_PERIODS`` periods within [HANG_FLOOR_S, HANG_CAP_S]."""
    if period_s is None:
        return HANG_CAP_S
    return min(max(HANG_PERIODS * period_s, HANG_FLOOR_S), HANG_CAP_S)

_RESEND = re.compile(r"^(?:Resend|rs)\s*:?\s*N?(\d+)", re.IGNORECASE)
_POS = re.compile(r"([XYZABCE]):\s*(-?\d+(?:\.\d+)?)")
_WAITS = re.compile(r"^(M400|G0*4|G0*28|G0*[0-3])(?!\d)", re.IGNORECASE)
_PROBE = "M114"


def waits_on_motion(text):
    """True for a line Marlin answers only once motion (or a dwell) allows."""
    return bool(_WAITS.match(text.strip()))


def numbered(n, text):
    """The wire form of line ``n``: ``N<n> <text>*<checksum>``."""
    body = f"N{n} {text}"
    return f"{body}*{marlin_codes.checksum(body)}"


class MarlinLink(LineLink):
    """A G-code link to Marlin 2.x.

    Parameters
    ----------
    port : an open pyserial port
    sync_line : ``M400``
    max_resends : resends of one line before giving up
    """

    dialect = "marlin"

    def __init__(self, port, dialect="marlin", *, sync_line=None, response_timeout=3.0,
                 motion_timeout=600.0, max_resends=5):
        super().__init__(port, response_timeout=response_timeout)
        self.dialect, self.kind = dialect, get_kind(dialect)
        self.sync_line = sync_line or self.kind.sync_line
        self.motion_timeout = motion_timeout
        self.max_resends = max_resends
        self.line_number = 0
        self.resends = 0
        self.last_position = None
        self.last_counts = None       # M114's "Count": the steppers' own step counts
        self.keepalives = False       # a busy: keepalive was heard (M113 is on)
        self.keepalive_s = None       # the longest gap measured between two keepalives of one wait
        self._history = {}
        self._swallow = 0
        self._awaiting = None
        self._heard = None            # a list while query() collects the echo: lines of an answer

    # ---- identification --------------------------------------------------------------
    def identify(self):
        seen = self.drain_input(quiet=0.05, limit=2.5)
        answer = []
        for attempt in range(2):
            self.write(b"M115\n")
            answer = self._collect_plain(self.response_timeout)
            if answer or attempt:
                break
        lines = tuple(seen) + tuple(answer)
        joined = " ".join(lines)
        grbl = grbl_codes.identify(lines)
        if grbl is not None or re.search(r"\bGrbl", joined, re.IGNORECASE) or \
                any(x.startswith("error:") for x in answer):
            title = grbl.title if grbl is not None else "GRBL"
            raise self.fail(f"the machine runs {title}, but the machine file says dialect {self.dialect!r}; "
                            f"use a machine file for {title} or check the port")
        version = self.kind.found_in(lines)
        if version is None:
            if lines:
                raise self.fail(f"the device on the port is not {self.kind.title}; it answered {lines[0][:60]!r}")
            raise self.fail(f"no answer from the machine (expected {self.kind.title}'s answer to M115); "
                            "check the port, the baud rate and that the machine is on")
        self.info = FirmwareInfo(dialect=self.kind.name, name=self.kind.title, version=version, lines=lines)
        self._reset_numbers()
        self.state = LinkState.IDENTIFIED
        log.info("firmware: Marlin %s", self.info.version)
        return self.info

    def _collect_plain(self, timeout):
        lines = []
        deadline = time.monotonic() + timeout
        while True:
            line = self.readline(max(0.0, deadline - time.monotonic()))
            if line is None:
                return lines
            lines.append(line)
            if line.startswith("ok") or line.lower().startswith("error"):
                return lines

    def _reset_numbers(self):
        """``M110 N0``: the next line is number 1."""
        self.line_number = 0
        self._history = {0: "M110 N0"}
        self._swallow = 0
        self._transmit(0, "M110 N0", Where())
        self._await(0, Where(), self.response_timeout)
        self.line_number = 1

    # ---- state -----------------------------------------------------------------------
    def status(self, timeout=None):
        """``M114``: the position Marlin believes in (no run state: Marlin has none to report)."""
        self.last_position = None       # never a report from before this M114 (a stale held position)
        self.command("M114", timeout=timeout)
        return self._status()

    def _status(self):
        pos = self.last_position or {}
        mpos = tuple(pos[a] for a in "XYZA" if a in pos) or None
        return Status(state="Idle", mpos=mpos, fields={"axes": dict(pos)})

    def command(self, text, timeout=None):
        self._send(text, Where(), timeout or self.response_timeout)

    def query(self, text, timeout=None):
        """Send ``text`` (``M503``) and return the ``echo:`` lines it answered before its ``ok``."""
        self._heard = []
        try:
            self.command(text, timeout=timeout)
            return list(self._heard)
        finally:
            self._heard = None

    def prepare(self, *, home=False, preamble=(), home_lines=("G28",)):
        self._home_and_preamble(home, home_lines, preamble, self.motion_timeout)

    # ---- streaming -------------------------------------------------------------------
    def execute(self, steps, lines_for, on_executed=None):
        """Send each step's lines then ``M400``; the step is executed when ``M400`` is answered."""
        self.state = LinkState.STREAMING
        for step in steps:
            where = where_of(step)
            self.where = where
            for text in lines_for(step):
                text = strip_comment(text)
                if text:
                    self._send(text, where, self.motion_timeout)
            self._send(self.sync_line, where, self.motion_timeout)
            self.executed.append(step)
            for done in self.take_executed():
                if on_executed is not None:
                    on_executed(done)
        self.state = LinkState.READY

    def run_lines(self, lines, where):
        """Send ``lines`` then ``M400``; return once ``M400`` is answered (all executed)."""
        self.state = LinkState.STREAMING
        self.where = where
        for text in lines:
            text = strip_comment(text)
            if text:
                self._send(text, where, self.motion_timeout)
        self._send(self.sync_line, where, self.motion_timeout)
        self.state = LinkState.READY

    def finish(self, lines=()):
        for line in lines:
            line = strip_comment(line)
            if line:
                self._send(line, Where(), self.motion_timeout)
        self._send(self.sync_line, Where(), self.motion_timeout)
        self.state = LinkState.READY

    def _send(self, text, where, timeout):
        n = self.line_number
        self._history[n] = text
        self.line_number = n + 1        # first: a Ctrl-C during the write must not reuse n (Marlin
        self._transmit(n, text, where)  # would take the next line for n's resend, unanswered)
        answered = self._await(n, where, timeout, motion=waits_on_motion(text))
        self._history.pop(n - 8, None)
        if not answered and text == self.sync_line:
            # an M400 known only to have arrived may still be waiting on motion: ask again
            self._send(text, where, timeout)

    def _transmit(self, n, text, where):
        wire = numbered(n, text)
        log.debug("-> %s", wire)
        self.write(wire.encode("ascii") + b"\n")
        self.lines_sent += 1

    def _await(self, n, where, timeout, motion=False):
        """Wait for line ``n``'s ``ok``, answering resend requests and keepalives.

        Marlin follows every ``Resend: k`` with an ``ok`` that answers nothing;
        ``self._swallow`` counts those still to come.  ``motion``: line ``n`` may
        rightly take up to ``timeout`` without a word (see the module's notes).
        """
        self._awaiting = (n, where, motion)
        answered = self._await_inner(n, where, timeout, motion)
        self._awaiting = None
        return answered

    def _await_inner(self, n, where, timeout, motion=False):
        deadline = time.monotonic() + timeout
        silence = time.monotonic() + self.response_timeout
        heard = time.monotonic()       # the last line of any kind
        last_busy = None               # the last keepalive of this wait
        probes = 0
        probe, reported = None, False  # the M114 sent early behind line n; its X: report came
        while True:
            hang = heard + hang_after(self.keepalive_s) if motion and self.keepalives else deadline
            line = self.readline(max(0.0, min(deadline, silence, hang) - time.monotonic()))
            now = time.monotonic()
            if line is None:
                if now >= deadline:
                    raise self.fail(f"the machine did not answer within {timeout:.0f} s", where)
                if now >= hang:
                    period = f"every {self.keepalive_s:.2g} s" if self.keepalive_s else "before"
                    raise self.fail(f"the machine stopped answering: nothing for {now - heard:.0f} s although "
                                    f"it sent busy keepalives {period} (frozen firmware, or a dead port)",
                                    where)
                if motion:
                    # still moving, or line n's ok was lost: never send it again; ask M114
                    # behind it, once (its answer comes when line n is done)
                    if probe is None:
                        probe = self.line_number
                        self._history[probe] = _PROBE
                        self._transmit(probe, _PROBE, where)
                        self.line_number = probe + 1
                    silence = now + self.response_timeout
                    continue
                if probes >= 2:
                    raise self.fail("the machine stopped answering", where)
                # silence: the answer may be lost.  Send the line again under its number:
                # Marlin asks for n+1 if it had it, or for n if it had not.
                probes += 1
                self._transmit(n, self._history[n], where)
                silence = now + self.response_timeout
                continue
            silence = now + self.response_timeout
            heard = now
            low = line.lower()
            if line.startswith("ok"):
                if self._swallow:
                    self._swallow -= 1
                    continue
                if probe is not None:
                    if reported:
                        log.warning("the answer to line %d was lost; M114 behind it came back", n)
                    else:
                        self._swallow += 1      # line n's ok: the probe's comes later
                return True
            m = _RESEND.match(line)
            if m:
                want = int(m.group(1))
                self.resends += 1
                self._swallow += 1
                if probe is not None and want == probe:
                    self._transmit(probe, _PROBE, where)
                    continue
                if want == n + 1:
                    return False       # it had line n (its answer was lost): received, maybe not done
                if want != n or self.resends > self.max_resends * 1000:
                    raise self.fail(f"the machine asked to resend line {want}, but line {n} was sent",
                                    where)
                self._transmit(n, self._history[n], where)
                continue
            if "busy" in low or low.startswith("wait"):
                deadline = max(deadline, now + self.response_timeout)
                if "busy" in low:
                    if last_busy is not None:
                        self.keepalive_s = max(self.keepalive_s or 0.0, now - last_busy)
                    self.keepalives, last_busy = True, now
                continue
            if low.startswith("error"):
                if "checksum" in low or "line number" in low:
                    continue           # a Resend follows
                self.stop_quietly()
                raise self.fail(f"the machine reported {line[:80]!r}", where)
            if low.startswith("echo:unknown command"):
                self.stop_quietly()
                raise self.fail(f"the machine did not understand a line: {line[5:80]!r}", where)
            if self.restarted(line) or low.startswith("echo:marlin") or low.startswith("marlin "):
                self.position_lost = True
                raise self.fail("the firmware reset itself mid-job (it printed its start banner); "
                                "its position may be lost", where)
            if line.startswith("X:") and _POS.search(line):
                logical, _, counts = line.partition("Count")
                self.last_position = {k: float(v) for k, v in _POS.findall(logical)}
                self.last_counts = {k: float(v) for k, v in _POS.findall(counts)} or None
                if probe is not None:
                    reported = True             # the probe ran: line n is done
                continue
            if low.startswith(("echo:", "//", "cap:", "firmware_name")):
                log.info("machine says: %s", line)
                if self._heard is not None:
                    self._heard.append(line)
                continue
            self.stop_quietly()
            raise self.fail(f"the machine answered garbage: {line[:60]!r}", where)

    # ---- stopping --------------------------------------------------------------------
    def hold(self, timeout=None):
        """Stop in a controlled way: let the one line in flight finish (the link never has more
        than one), so the machine stands still at a known point with its position kept.

        (Marlin's quickstop ``M410`` would lose steps; its ``P000`` needs the emergency parser.)
        """
        self.state = LinkState.HOLDING
        pending = self._awaiting
        if pending is not None:
            n, where, motion = pending
            self._await(n, where, timeout or self.motion_timeout, motion)
        return self._status()

    def stop_quietly(self, hold=True):
        """Nothing to do: at most one line is ever queued, and it is the one that failed."""
