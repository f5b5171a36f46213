"""What every link shares: state, firmware identity, status, and line I/O on a port.

A link owns one already-open port object (anything with ``read``, ``write``,
``in_waiting``, ``close``; see :func:`~stringbot.links.ports.open_port`) and is
the only code that reads or writes it.  Every port error becomes a
:class:`~stringbot.errors.MachineFailure` naming the step and pin that was
running, never a traceback.
"""

import enum
import logging
import re
import time
from dataclasses import dataclass, field

import serial

from ..errors import MachineFailure

__all__ = ["LinkState", "FirmwareInfo", "Status", "Where", "LineLink", "strip_comment", "where_of"]

log = logging.getLogger(__name__)


class LinkState(enum.Enum):
    """Where a link is in its life; one owner (the link) changes it."""

    OPEN = "open"              # port open, firmware not yet known
    IDENTIFIED = "identified"  # firmware answered and matches the machine's dialect
    READY = "ready"            # alarms checked, homed if asked, modal state set
    STREAMING = "streaming"    # steps in flight
    HOLDING = "holding"        # feed hold sent; machine stopping or stopped
    FAILED = "failed"          # an error, alarm, reset or disconnect; machine told to stop
    CLOSED = "closed"


@dataclass
class FirmwareInfo:
    """Who answered on the port."""

    dialect: str               # "grbl", "grblhal", "marlin", or "" when unknown
    name: str                  # as the firmware names itself
    version: str = ""
    rx_buffer: int = 0         # receive buffer in bytes (character counting), 0 = not streamed so
    lines: tuple = ()          # everything it said while we asked


@dataclass
class Status:
    """A machine state report, firmware-neutral."""

    state: str                 # "Idle", "Run", "Hold", "Alarm", "Home", "Door", ...
    sub: str = ""              # e.g. "0" in "Hold:0" (hold complete)
    mpos: tuple | None = None  # machine position, axis order of the firmware (None = unknown)
    fields: dict = field(default_factory=dict)

    @property
    def stopped(self):
        """True when nothing moves: idle, alarm, or a completed hold."""
        return self.state in ("Idle", "Alarm", "Sleep", "Check") or \
            (self.state == "Hold" and self.sub == "0") or (self.state == "Door" and self.sub == "0")


@dataclass(frozen=True)
class Where:
    """The step a line belongs to, for messages and for the journal."""

    step: int | None = None
    pin: int | None = None
    sync: bool = False         # this line's answer means the step was executed
    item: object = None        # the step object itself, handed back on execution


def where_of(step, sync=False):
    """The :class:`Where` of a motion step: steps are numbered from 1 for people."""
    index = getattr(step, "index", None)
    return Where(step=None if index is None else index + 1, pin=getattr(step, "pin", None),
                 sync=sync, item=step if sync else None)


_COMMENT = re.compile(r"\s*(;.*|\([^)]*\))")


def strip_comment(line):
    """A G-code line without ``; comment`` or ``(comment)`` and surrounding blanks."""
    return _COMMENT.sub("", line).strip()


class LineLink:
    """Line-based I/O on a port with deadlines; subclasses speak a dialect.

    Parameters
    ----------
    port : serial.SerialBase-like
        An open port; its read timeout should be short (~0.05 s).
    response_timeout : float
        Seconds of silence after which a query counts as unanswered.
    """

    def __init__(self, port, *, response_timeout=3.0):
        self.port = port
        self.response_timeout = response_timeout
        self.state = LinkState.OPEN
        self.info = None
        self._rx = bytearray()
        self.where = Where()          # the step being executed (for messages)
        self.executed = []            # steps whose execution was confirmed, not yet taken
        self.lines_sent = 0
        self.bytes_sent = 0
        self.position_lost = False    # the firmware reset or alarmed: its position is not to be trusted

    #: the link's :class:`firmware_protocol.kinds.FirmwareKind` (set by the subclass)
    kind = None

    def restarted(self, line):
        """``line`` is the firmware's start-up line: it (re)started, its position may be lost."""
        return self.kind is not None and self.kind.is_banner(line)

    # ---- failures -----------------------------------------------------------------------
    def fail(self, message, where=None):
        """Mark the link failed and return the exception to raise (naming step and pin)."""
        self.state = LinkState.FAILED
        where = where or self.where
        return MachineFailure(message, step=where.step, pin=where.pin)

    def garbage(self, raw):
        """The machine said something unreadable: stop it if it was moving; the error to raise."""
        if self.state is LinkState.STREAMING:
            self.stop_quietly()
        if self.state is LinkState.OPEN:            # nothing understood yet: most likely the speed
            baud = getattr(self.port, "baudrate", None)
            return self.fail(f"the device on the port answers unreadable bytes ({raw[:24]!r}): check the "
                             f"baud rate (the machine file's controller.baud{f' = {baud}' if baud else ''} "
                             "must be the firmware's) and that this is the machine's port")
        return self.fail(f"the machine answered garbage: {raw[:60]!r}")

    def stop_quietly(self, hold=True):
        """After a failure: ask the machine to stop, best effort (subclasses know how)."""

    # ---- raw I/O ------------------------------------------------------------------------
    def write(self, data):
        try:
            self.port.write(data)
        except (serial.SerialException, OSError) as exc:
            raise self.fail(f"lost the connection to the machine while sending ({_short(exc)})") from None
        except serial.SerialTimeoutException:  # pragma: no cover - subclass of SerialException
            raise self.fail("the machine stopped accepting data (write timed out)") from None
        self.bytes_sent += len(data)

    def _fill(self):
        """Read what the port has (waits at most the port's read timeout)."""
        try:
            n = self.port.in_waiting
            chunk = self.port.read(n if n else 1)
        except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
            raise self.fail(f"lost the connection to the machine ({_short(exc)})") from None
        if chunk:
            self._rx += chunk
        return bool(chunk)

    def readline(self, timeout):
        """Next non-empty line as text (``\\r`` and blanks stripped), or None after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while True:
            i = self._rx.find(b"\n")
            if i >= 0:
                raw = bytes(self._rx[:i])
                del self._rx[:i + 1]
                text = raw.strip(b"\r \t\0")
                if not text:
                    continue
                try:
                    line = text.decode("ascii")
                except UnicodeDecodeError:
                    line = "\0"
                if any(ord(c) < 32 and c != "\t" for c in line):
                    raise self.garbage(raw)
                log.debug("<- %s", line)
                return line
            if len(self._rx) > 4096:
                raise self.garbage(bytes(self._rx[:60]))
            if time.monotonic() >= deadline:
                return None
            self._fill()

    def drain_input(self, quiet=0.05, limit=1.0):
        """Read and return the lines that arrive until ``quiet`` s pass without any."""
        lines = []
        end = time.monotonic() + limit
        while time.monotonic() < end:
            line = self.readline(quiet)
            if line is None:
                break
            lines.append(line)
        return lines

    def command(self, text, timeout=None):  # pragma: no cover - each dialect sends its own way
        """Send one line and wait for its answer."""
        raise NotImplementedError

    def _home_and_preamble(self, home, home_lines, preamble, home_timeout):
        """Home if asked (each homing line may take ``home_timeout`` s), then send the
        preamble's lines one by one (comments and blank lines left out); the link is ready."""
        if home:
            for line in home_lines:
                line = strip_comment(line)
                if line:
                    self.command(line, timeout=home_timeout)
        for line in preamble:
            line = strip_comment(line)
            if line:
                self.command(line)
        self.state = LinkState.READY

    def take_executed(self):
        """The steps confirmed executed since the last call, in order."""
        done, self.executed = self.executed, []
        return done

    def close(self):
        """Close the port (the machine is left as it is)."""
        if self.state is not LinkState.CLOSED:
            try:
                self.port.close()
            except Exception:  # closing a dead port must not hide the real error
                log.debug("closing the port failed", exc_info=True)
            self.state = LinkState.CLOSED


def _short(exc):
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text[:120]
