"""Firmware settings as both sides write and read them: codecs, no I/O.

- **GRBL 1.1 / grblHAL** ``$`` settings (GRBL's ``settings.md``; grblHAL's
  ``settings.h``): ``$$`` answers one ``$N=value`` line each; ``$N=value``
  stores one in EEPROM.  Axis settings are numbered ``base + axis index`` in
  ``XYZABC`` order: ``$100``.. steps per unit, ``$110``.. max rate
  (units/min), ``$120``.. acceleration (units/s^2), ``$130``.. max travel;
  ``$20`` soft limits, ``$22`` homing cycle (grblHAL: bit 0 of a flag set),
  ``$13`` report in inches; grblHAL's ``$376`` names the rotary axes (bit 0 =
  A, 1 = B, 2 = C: the axis mask shifted right by 3) and ``$538`` the rotary
  axes that wrap (move the short way round).
- **Marlin 2.1**: ``M503`` reports the settings as the commands that set
  them (``echo:  M92 X80.00 Y80.00 Z400.00 A44.44``): ``M92`` steps per unit,
  ``M203`` max feedrate (units/s), ``M201`` max acceleration (units/s^2),
  ``M204`` acceleration (``P`` print, ``R`` retract, ``T`` travel: moves
  without extrusion use ``T``), ``M211`` software endstops.  ``M500`` stores
  them in EEPROM.
- **Dynamixel**: control-table items named on a command line,
  ``ID:ITEM=VALUE`` (``ring:Drive Mode=1``, ``2:44=200``).

:func:`parse_preset` reads the ``--set`` forms of ``stringbot simulate`` and
``sim://?set=...`` for each kind of firmware.
"""

import re
from dataclasses import dataclass, field

from . import dynamixel as dx
from .kinds import KINDS, get_kind

__all__ = [
    "AXES", "STEPS_PER_UNIT", "MAX_RATE", "ACCELERATION", "MAX_TRAVEL", "REPORT_INCHES",
    "SOFT_LIMITS", "HOMING", "ROTARY_AXES", "ROTARY_WRAP", "axis_setting", "setting_label",
    "parse_setting_line", "parse_settings", "setting_line", "number",
    "MARLIN_REPORTS", "MarlinSettings", "marlin_words", "m503_lines", "parse_m503",
    "ServoSetting", "parse_servo_setting", "Preset", "parse_preset", "PRESET_FORMS", "PRESET_EXAMPLES",
]

AXES = "XYZABC"

# GRBL / grblHAL setting numbers
REPORT_INCHES = 13
SOFT_LIMITS = 20
HOMING = 22
STEPS_PER_UNIT = 100
MAX_RATE = 110
ACCELERATION = 120
MAX_TRAVEL = 130
ROTARY_AXES = 376
ROTARY_WRAP = 538

_AXIS_NAMES = {STEPS_PER_UNIT: "steps/unit", MAX_RATE: "max rate", ACCELERATION: "acceleration",
               MAX_TRAVEL: "max travel"}
_GLOBAL_NAMES = {REPORT_INCHES: "report inches", SOFT_LIMITS: "soft limits", 21: "hard limits",
                 HOMING: "homing cycle", ROTARY_AXES: "rotary axes", ROTARY_WRAP: "rotary wrap"}


def axis_setting(base, axis):
    """``axis_setting(STEPS_PER_UNIT, "A")`` -> 103."""
    return base + AXES.index(axis)


def setting_label(n):
    """``$103 A steps/unit``, ``$22 homing cycle``."""
    base, index = divmod(n - 100, 10)
    if 100 <= n < 140 and index < len(AXES):
        return f"${n} {AXES[index]} {_AXIS_NAMES[100 + 10 * base]}"
    return f"${n} {_GLOBAL_NAMES.get(n, 'setting')}"


_SETTING = re.compile(r"^\$(\d+)=(.*?)\s*(?:\(.*\))?$")


def parse_setting_line(line):
    """``"$100=44.444"`` -> ``(100, 44.444)``; a value that is not a number stays text; None if
    the line is not a setting."""
    m = _SETTING.match(line.strip())
    if not m:
        return None
    text = m.group(2).strip()
    try:
        return int(m.group(1)), float(text)
    except ValueError:
        return int(m.group(1)), text


def parse_settings(lines):
    """The ``$N=value`` lines of a ``$$`` answer -> ``{N: value}`` (other lines ignored)."""
    out = {}
    for line in lines:
        got = parse_setting_line(line)
        if got is not None:
            out[got[0]] = got[1]
    return out


def number(value, decimals=4):
    """A value as a person (and a firmware) reads it: ``44.4444``, ``7200``, ``0.5``."""
    if isinstance(value, str):
        return value
    text = f"{float(value):.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def setting_line(n, value):
    """The line that stores setting ``n``: ``setting_line(100, 44.44444)`` -> ``"$100=44.4444"``."""
    return f"${n}={number(value)}"


# ---- Marlin ------------------------------------------------------------------------------------

#: The M503 reports this module reads and writes, with Marlin 2.1's headings.
MARLIN_REPORTS = (
    ("M92", "Steps per unit"),
    ("M203", "Max feedrates (units/s)"),
    ("M201", "Max Acceleration (units/s2)"),
    ("M204", "Acceleration (units/s2) (P<print-accel> R<retract-accel> T<travel-accel>)"),
    ("M211", "Soft Endstops"),
)

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")


def marlin_words(text):
    """``"M92 A40 Y80"`` -> ``("M92", {"A": 40.0, "Y": 80.0})``; None if not a G/M command."""
    text = text.strip().upper()
    m = re.match(r"^([GM]\d+)\b", text)
    if not m:
        return None
    return m.group(1), {letter: float(value) for letter, value in _WORD.findall(text[m.end():])}


@dataclass
class MarlinSettings:
    """What M503 reports of the motion settings (units/s, not per minute, as Marlin keeps them)."""

    steps: dict = field(default_factory=dict)        # M92: axis -> steps per unit
    max_feed: dict = field(default_factory=dict)     # M203: axis -> units/s
    max_accel: dict = field(default_factory=dict)    # M201: axis -> units/s^2
    accel: dict = field(default_factory=dict)        # M204: P, R, T -> units/s^2
    soft_endstops: bool | None = None                # M211 S
    soft_min: dict = field(default_factory=dict)     # M211's Min: axis -> position
    soft_max: dict = field(default_factory=dict)

    def copy(self):
        return MarlinSettings(dict(self.steps), dict(self.max_feed), dict(self.max_accel),
                              dict(self.accel), self.soft_endstops, dict(self.soft_min),
                              dict(self.soft_max))


def _axes_words(values, axes, decimals=2):
    return " ".join(f"{a}{values[a]:.{decimals}f}" for a in axes if a in values)


def m503_lines(s, axes):
    """The lines Marlin 2.1 prints for ``M503`` (those of :data:`MARLIN_REPORTS`), ``echo:``-prefixed."""
    out = []
    for code, heading in MARLIN_REPORTS:
        out.append(f"echo:; {heading}:")
        if code == "M92":
            out.append(f"echo:  M92 {_axes_words(s.steps, axes)}")
        elif code == "M203":
            out.append(f"echo:  M203 {_axes_words(s.max_feed, axes)}")
        elif code == "M201":
            out.append(f"echo:  M201 {_axes_words(s.max_accel, axes)}")
        elif code == "M204":
            out.append(f"echo:  M204 {_axes_words(s.accel, 'PRT')}")
        else:
            on = bool(s.soft_endstops)
            out.append(f"echo:  M211 S{int(on)} ; {'ON' if on else 'OFF'}")
            out.append(f"echo:  Min:  {_axes_words(s.soft_min, axes)}   Max:  {_axes_words(s.soft_max, axes)}")
    return out


def parse_m503(lines):
    """M503's lines -> :class:`MarlinSettings` (what is missing stays empty / None)."""
    s = MarlinSettings()
    targets = {"M92": s.steps, "M203": s.max_feed, "M201": s.max_accel, "M204": s.accel}
    for raw in lines:
        text = raw.strip()
        if text.lower().startswith("echo:"):
            text = text[5:].strip()
        text = text.split(";", 1)[0].strip()
        if text.startswith("Min:") and "Max:" in text:
            low, high = text[4:].split("Max:", 1)
            s.soft_min.update({a: float(v) for a, v in _WORD.findall(low)})
            s.soft_max.update({a: float(v) for a, v in _WORD.findall(high)})
            continue
        words = marlin_words(text)
        if words is None:
            continue
        code, values = words
        if code in targets:
            targets[code].update(values)
        elif code == "M211" and "S" in values:
            s.soft_endstops = bool(values["S"])
    return s


# ---- Dynamixel ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class ServoSetting:
    """One control-table item to write: ``who`` is a servo id or ``"ring"`` / ``"head"``."""

    who: object
    item: str
    value: int


_SERVO_FORM = KINDS["dynamixel"].set_form


def parse_servo_setting(text):
    """``"ring:Drive Mode=1"`` or ``"2:44=200"`` -> :class:`ServoSetting`; ValueError names the form."""
    who, colon, rest = text.partition(":")
    item, eq, value = rest.partition("=")
    who, item = who.strip().lower(), item.strip()
    if not colon or not eq or not item or not (who in ("ring", "head") or who.isdigit()):
        raise ValueError(f"{text!r} is not a servo setting; expected {_SERVO_FORM}")
    if item.isdigit():
        f = dx.FIELD_AT.get(int(item))
    else:
        f = next((f for name, f in dx.CONTROL_TABLE.items() if name.lower() == item.lower()), None)
    if f is None or not f.writable:
        names = ", ".join(n for n, f in dx.CONTROL_TABLE.items() if f.writable)
        raise ValueError(f"{text!r}: {item!r} is not a writable control-table item; expected one of {names}")
    try:
        number_ = int(value.strip(), 0)
    except ValueError:
        raise ValueError(f"{text!r}: value {value.strip()!r} is not an integer; expected {_SERVO_FORM}") from None
    if not f.lo <= number_ <= f.hi:
        raise ValueError(f"{text!r}: {f.name} takes {f.lo}..{f.hi}")
    return ServoSetting(int(who) if who.isdigit() else who, f.name, number_)


# ---- presets: the --set forms ------------------------------------------------------------------------

#: What ``--set`` takes and an example (one that mis-sets its bundled machine), per kind of firmware.
PRESET_FORMS = {k.name: f"{k.set_form} (e.g. '{k.set_example}')" for k in KINDS.values()}
PRESET_EXAMPLES = {k.name: k.set_example for k in KINDS.values()}

_MARLIN_SETTERS = ("M92", "M203", "M201", "M204", "M211")


@dataclass(frozen=True)
class Preset:
    """A setting a simulated machine starts with: GRBL ``(N, value)``, Marlin ``(code, words)``,
    Dynamixel a :class:`ServoSetting`."""

    text: str
    value: object


def parse_preset(kind, text):
    """One ``--set`` for a ``kind`` of firmware (a name of :data:`firmware_protocol.kinds.KINDS`).

    Raises
    ------
    ValueError
        Naming the text and the expected form (or the kind, when there is no such kind).
    """
    text = text.strip()
    rules = get_kind(kind).settings
    form = PRESET_FORMS[kind]
    if rules in ("grbl", "grblhal"):
        got = parse_setting_line(text)
        if got is None or isinstance(got[1], str):
            raise ValueError(f"--set {text!r}: expected {form}")
        return Preset(text, got)
    if rules == "marlin":
        words = marlin_words(text)
        if words is None or words[0] not in _MARLIN_SETTERS or not words[1]:
            raise ValueError(f"--set {text!r}: expected {form}")
        return Preset(text, words)
    try:
        return Preset(text, parse_servo_setting(text))
    except ValueError as exc:
        raise ValueError(f"--set {exc}") from None
