"""Marlin 2.1: line numbers, checksums and what the firmware says, as constants and codecs.

Shared by both sides: the host link numbers its lines and parses ``Resend:``
with these, the simulated firmware checks and produces them.  Sources:
Marlin's G-code documentation (M110, M400, M114, M115) and its serial
protocol (``N<n> <command>*<checksum>``, the checksum being the XOR of every
byte before ``*``).  Marlin ends its lines with ``\\n``.
"""

import re

__all__ = [
    "VERSION", "EOL", "OK", "START", "RX_BUFFER_SIZE", "BUFSIZE", "PLANNER_BLOCKS", "MAX_CMD_SIZE",
    "KEEPALIVE_SECONDS", "BUSY_PROCESSING", "PAUSED_FOR_USER", "ERR_CHECKSUM_MISMATCH", "ERR_LINE_NO", "ERR_NO_CHECKSUM",
    "RESEND", "UNKNOWN_COMMAND", "checksum", "numbered", "parse_numbered", "parse_resend",
    "parse_position", "is_error",
]

VERSION = "2.1.2.1"
EOL = b"\n"
OK = "ok"
#: The first line after a reset or power-up.
START = "start"
RX_BUFFER_SIZE = 128          # bytes, as on an AVR or most STM32 builds
BUFSIZE = 4                   # commands queued ahead of the one running
PLANNER_BLOCKS = 15           # BLOCK_BUFFER_SIZE 16, one kept free
MAX_CMD_SIZE = 96             # longer lines are cut
#: ``echo:busy: processing`` comes every this many seconds while a command blocks (M113 S2).
KEEPALIVE_SECONDS = 2.0
BUSY_PROCESSING = "echo:busy: processing"
PAUSED_FOR_USER = "echo:busy: paused for user"
ERR_CHECKSUM_MISMATCH = "checksum mismatch, Last Line: "
ERR_LINE_NO = "Line Number is not Last Line Number+1, Last Line: "
ERR_NO_CHECKSUM = "No Checksum with line number, Last Line: "
RESEND = "Resend: "
UNKNOWN_COMMAND = 'echo:Unknown command: "'


def checksum(text):
    """XOR of every byte of ``text`` (str or bytes), as Marlin computes it for ``*``."""
    data = text.encode("latin-1") if isinstance(text, str) else bytes(text)
    value = 0
    for b in data:
        value ^= b
    return value


def numbered(n, command):
    """``numbered(1, "G0 X1")`` -> ``"N1 G0 X1*<checksum>"`` (no line end)."""
    body = f"N{n} {command}"
    return f"{body}*{checksum(body)}"


_NUMBERED = re.compile(r"^N(-?\d+)\s*(.*?)\*(\d+)$")


def parse_numbered(line):
    """``"N1 G0 X1*96"`` -> ``(1, "G0 X1", True)`` (checksum good?); None if not numbered."""
    text = line.strip()
    m = _NUMBERED.match(text)
    if not m:
        return None
    return int(m.group(1)), m.group(2).strip(), checksum(text[:text.rindex("*")]) == int(m.group(3))


_RESEND_RE = re.compile(r"^(?:Resend|rs)\s*:?\s*N?(\d+)", re.IGNORECASE)


def parse_resend(line):
    """``"Resend: 4"`` -> 4; anything else -> None."""
    m = _RESEND_RE.match(line.strip())
    return int(m.group(1)) if m else None


def is_error(line):
    """True for Marlin's ``Error:...`` lines."""
    return line.strip().startswith("Error:")


_POS_RE = re.compile(r"([XYZABCE]):(-?\d+(?:\.\d+)?)")


def parse_position(line):
    """``M114``'s ``X:0.00 Y:0.00 Z:0.00 A:0.00 Count X:0 ...`` -> ``{"X": 0.0, ...}`` (before Count)."""
    head = line.split("Count")[0]
    return {axis: float(value) for axis, value in _POS_RE.findall(head)}
