"""GRBL 1.1, grblHAL and FluidNC: what the firmware says, as constants and codecs.

Shared by both sides: the host link parses responses and status reports with
these, the simulated firmware produces them.  The GRBL family's one banner
detector (:func:`is_banner`: the link, resume's recovery and the tests use it)
and its identification (:func:`identify`) read the family's records in
:mod:`firmware_protocol.kinds`.  Sources: GRBL's own
``doc/markdown/interface.md``, ``commands.md``, ``settings.md`` and the
``doc/csv`` code tables (gnea/grbl), and grblHAL's ``$I`` report.

Line endings: GRBL ends every line it sends with ``\\r\\n``; hosts send ``\\n``
(a ``\\r\\n`` from the host is two line ends to GRBL, hence two ``ok``).
"""

import re
from dataclasses import dataclass, field

__all__ = [
    "VERSION", "BUILD", "BANNER", "HAL_VERSION", "HAL_BANNER",
    "RX_BUFFER_SIZE", "PLANNER_BLOCKS", "HAL_RX_BUFFER_SIZE", "HAL_PLANNER_BLOCKS", "LINE_BUFFER_SIZE",
    "STATUS_QUERY", "FEED_HOLD", "CYCLE_START", "SOFT_RESET", "SAFETY_DOOR", "JOG_CANCEL",
    "REALTIME_BYTES", "ERROR_CODES", "ALARM_CODES", "UNLOCK_MESSAGE", "EOL",
    "Status", "parse_status", "parse_error", "parse_alarm", "is_banner", "describe_error",
    "describe_alarm", "Identity", "identify",
]

EOL = b"\r\n"

VERSION = "1.1h"
BUILD = "20190830"
#: Printed (after a leading ``\r\n``) at power-up and after every reset.
BANNER = f"Grbl {VERSION} ['$' for help]"
HAL_VERSION = "1.1f"
HAL_BUILD = "20240101"
HAL_BANNER = f"GrblHAL {HAL_VERSION} ['$' or '$HELP' for help]"

#: Serial receive buffer of stock GRBL on an ATmega328P (``Bf:`` reports 128 free when empty).
RX_BUFFER_SIZE = 128
#: Planner blocks available to the host (``Bf:15,...`` when empty; ``BLOCK_BUFFER_SIZE`` 16 minus one).
PLANNER_BLOCKS = 15
#: Longest line GRBL accepts (``LINE_BUFFER_SIZE`` 80, one for the terminator): longer -> ``error:11``.
LINE_BUFFER_SIZE = 80
HAL_RX_BUFFER_SIZE = 1024
HAL_PLANNER_BLOCKS = 100

# Realtime commands: single bytes picked off the serial stream, never buffered, no response line.
STATUS_QUERY = b"?"
FEED_HOLD = b"!"
CYCLE_START = b"~"
SOFT_RESET = b"\x18"
SAFETY_DOOR = b"\x84"
JOG_CANCEL = b"\x85"
REALTIME_BYTES = frozenset(b"?!~\x18")

#: ``error:N`` codes of GRBL 1.1 (doc/csv/error_codes_en_US.csv).
ERROR_CODES = {
    1: "Expected command letter: G-code words consist of a letter and a value. Letter was not found.",
    2: "Bad number format: missing the expected G-code word value or numeric value format is not valid.",
    3: "Invalid statement: Grbl '$' system command was not recognized or supported.",
    4: "Value < 0: negative value received for an expected positive value.",
    5: "Setting disabled: homing cycle is not enabled via settings.",
    6: "Value < 3 usec: minimum step pulse time must be greater than 3usec.",
    7: "EEPROM read fail: using defaults.",
    8: "Not idle: Grbl '$' command cannot be used unless Grbl is IDLE.",
    9: "G-code lock: G-code commands are locked out during alarm or jog state.",
    10: "Homing not enabled: soft limits cannot be enabled without homing also enabled.",
    11: "Line overflow: max characters per line exceeded; the line was not executed.",
    12: "Step rate > 30kHz: '$' setting value causes the step rate to exceed the maximum supported.",
    13: "Check Door: safety door detected as opened and door state initiated.",
    14: "Line length exceeded: build info or startup line exceeded EEPROM line length limit.",
    15: "Travel exceeded: jog target exceeds machine travel; jog command ignored.",
    16: "Invalid jog command: jog command has no '=' or contains prohibited g-code.",
    17: "Setting disabled: laser mode requires PWM output.",
    20: "Unsupported command: unsupported or invalid g-code command found in block.",
    21: "Modal group violation: more than one g-code command from same modal group found in block.",
    22: "Undefined feed rate: feed rate has not yet been set or is undefined.",
    23: "G-code command in block requires an integer value.",
    24: "More than one g-code command that requires axis words found in block.",
    25: "Repeated g-code word found in block.",
    26: "No axis words found in block for g-code command or current modal state which requires them.",
    27: "Line number value is invalid.",
    28: "G-code command is missing a required value word.",
    29: "G59.x work coordinate systems are not supported.",
    30: "G53 only allowed with G0 and G1 motion modes.",
    31: "Axis words found in block when no command or current modal state uses them.",
    32: "G2 and G3 arcs require at least one in-plane axis word.",
    33: "Motion command target is invalid.",
    34: "Arc radius value is invalid.",
    35: "G2 and G3 arcs require at least one in-plane offset word.",
    36: "Unused value words found in block.",
    37: "G43.1 dynamic tool length offset is not assigned to configured tool length axis.",
    38: "Tool number greater than max supported value.",
}

#: ``ALARM:N`` codes of GRBL 1.1 (doc/csv/alarm_codes_en_US.csv).
ALARM_CODES = {
    1: "Hard limit triggered; machine position is likely lost. Re-homing is highly recommended.",
    2: "Soft limit: G-code motion target exceeds machine travel; machine position retained.",
    3: "Reset while in motion; machine position is likely lost. Re-homing is highly recommended.",
    4: "Probe fail: the probe is not in the expected initial state before starting probe cycle.",
    5: "Probe fail: probe did not contact the workpiece within the programmed travel.",
    6: "Homing fail: the active homing cycle was reset.",
    7: "Homing fail: safety door was opened during homing cycle.",
    8: "Homing fail: pull off travel failed to clear limit switch.",
    9: "Homing fail: could not find limit switch within search distances.",
}

#: Sent after the banner when GRBL starts in ALARM (homing enabled, or after an abort).
UNLOCK_MESSAGE = "[MSG:'$H'|'$X' to unlock]"


def describe_error(code):
    """One line for ``error:code`` (unknown codes are named as such)."""
    return ERROR_CODES.get(code, f"unknown GRBL error code {code}")


def describe_alarm(code):
    """One line for ``ALARM:code``."""
    return ALARM_CODES.get(code, f"unknown GRBL alarm code {code}")


_ERROR_RE = re.compile(r"^error:(\d+)$")
_ALARM_RE = re.compile(r"^ALARM:(\d+)$")


def parse_error(line):
    """``"error:20"`` -> 20; anything else -> None."""
    m = _ERROR_RE.match(line.strip())
    return int(m.group(1)) if m else None


def parse_alarm(line):
    """``"ALARM:3"`` -> 3; anything else -> None."""
    m = _ALARM_RE.match(line.strip())
    return int(m.group(1)) if m else None


def is_banner(line):
    """True for the start-up line of a firmware of the GRBL family (``Grbl 1.1h ['$' for help]``,
    ``GrblHAL 1.1f ...``, ``Grbl 3.7 [FluidNC v3.7.8 ...]``): printed at power-up and after every
    reset, so a host that sees it knows the firmware (re)started."""
    from .kinds import family

    return any(k.is_banner(line) for k in family("grbl"))


@dataclass(frozen=True)
class Identity:
    """Who of the GRBL family answered: its kind (a name of :data:`firmware_protocol.kinds.KINDS`),
    as people name it, its version, and the receive buffer and planner blocks ``$I`` reported
    (0 when it did not)."""

    kind: str
    title: str
    version: str
    rx_buffer: int = 0
    planner_blocks: int = 0


_OPT = re.compile(r"^\[OPT:([^,\]]*),(\d+),(\d+)")
_VER = re.compile(r"^\[VER:([^:\]]*)")


def identify(lines):
    """Which firmware of the GRBL family said ``lines`` (its start-up lines and its answer to
    ``$I``); None when none of them did.  The kinds that name themselves apart (FluidNC,
    grblHAL) are tried before plain GRBL (:func:`firmware_protocol.kinds.family`)."""
    from .kinds import family

    lines = [x.strip() for x in lines]
    rx = blocks = 0
    version = ""
    for line in lines:
        m = _OPT.match(line)
        if m:
            blocks, rx = int(m.group(2)), int(m.group(3))
        m = _VER.match(line)
        if m and not version:
            version = m.group(1)
    for kind in family("grbl"):
        found = kind.found_in(lines)
        if found is not None:
            banner = next((x.split()[1] for x in lines if kind.is_banner(x) and len(x.split()) > 1), "")
            return Identity(kind.name, kind.title, found or banner or version, rx, blocks)
    return None


@dataclass
class Status:
    """A parsed realtime status report ``<State|MPos:...|...>``.

    ``state`` is the machine state (``Idle``, ``Run``, ``Hold``, ``Jog``, ``Alarm``,
    ``Door``, ``Check``, ``Home``, ``Sleep``) and ``substate`` its ``:N`` code or
    None.  ``mpos``/``wpos`` are tuples (one of them given by the firmware;
    the other computed when a ``WCO`` is known).  ``planner_free`` and
    ``rx_free`` come from ``Bf:``; ``fields`` keeps every field's raw text.
    """

    state: str
    substate: int | None = None
    mpos: tuple | None = None
    wpos: tuple | None = None
    wco: tuple | None = None
    planner_free: int | None = None
    rx_free: int | None = None
    feed: float | None = None
    spindle: float | None = None
    line_number: int | None = None
    fields: dict = field(default_factory=dict)


def _floats(text):
    return tuple(float(v) for v in text.split(","))


_FIELD_09 = re.compile(r"([A-Za-z]+):([^:]*?)(?=,[A-Za-z]+:|$)")


def parse_status(line, *, wco=None, strict=True):
    """Parse a status report line; None if ``line`` is not one.

    Parameters
    ----------
    line : str or bytes
        ``<Idle|MPos:0.000,0.000,0.000|Bf:15,128|FS:0,0>`` (GRBL 1.1, with or without line end),
        or GRBL 0.9's ``<Idle,MPos:0.000,0.000,0.000,WPos:0.000,0.000,0.000>``.
    wco : tuple, optional
        The last work coordinate offset the host saw, used to fill in ``mpos``
        from ``WPos`` (or ``wpos`` from ``MPos``) when the report carries no ``WCO``.
    strict : bool
        Raise on a malformed known field; False leaves it unparsed (None) and keeps its text in
        ``fields``.

    Raises
    ------
    ValueError
        If ``strict`` and the line looks like a report (``<...>``) but a known field is malformed.
    """
    if isinstance(line, bytes):
        line = line.decode("ascii", "replace")
    text = line.strip()
    if not (text.startswith("<") and text.endswith(">")):
        return None
    body = text[1:-1]
    if "|" in body or "," not in body:
        head, *rest = body.split("|")
        parts = [p.partition(":")[::2] for p in rest]
    else:                                   # GRBL 0.9: <Idle,MPos:...,WPos:...>
        head, _, tail = body.partition(",")
        parts = _FIELD_09.findall(tail)
    state, _, sub = head.partition(":")
    st = Status(state=state, substate=int(sub) if sub.isdigit() else None)
    for name, value in parts:
        st.fields[name] = value
        try:
            _parse_field(st, name, value)
        except ValueError as exc:
            if strict:
                raise ValueError(f"malformed GRBL status report {text!r}: {exc}") from None
    offset = st.wco if st.wco is not None else wco
    if offset is not None:
        if st.mpos is not None and st.wpos is None and len(offset) == len(st.mpos):
            st.wpos = tuple(m - o for m, o in zip(st.mpos, offset))
        elif st.wpos is not None and st.mpos is None and len(offset) == len(st.wpos):
            st.mpos = tuple(w + o for w, o in zip(st.wpos, offset))
    return st


def _parse_field(st, name, value):
    """One field of a status report into ``st`` (ValueError when it is malformed)."""
    if name == "MPos":
        st.mpos = _floats(value)
    elif name == "WPos":
        st.wpos = _floats(value)
    elif name == "WCO":
        st.wco = _floats(value)
    elif name == "Bf":
        blocks, rx = value.split(",")
        st.planner_free, st.rx_free = int(blocks), int(rx)
    elif name == "FS":
        feed, speed = value.split(",")
        st.feed, st.spindle = float(feed), float(speed)
    elif name == "F":
        st.feed = float(value)
    elif name == "Ln":
        st.line_number = int(value)
