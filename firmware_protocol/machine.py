"""The machine file: one TOML file per machine, its checked form, and its geometry.

This is a codec shared by both sides: the host plans moves for the machine it
describes, and the simulated machine builds its ring, pins and head from it.
Every key is checked at this edge (Klipper-style): unknown keys are typos,
values have types and bounds, and an error names the key and the expected form.

Bundled machines live in the top-level ``machines/`` folder (installed as the
package data ``firmware_protocol.machines``); ``find_machine_file("grbl-ring")``
finds them, a path finds the user's own.
"""

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .kinds import KINDS, gcode_kinds

__all__ = [
    "MachineFileError", "Machine", "load_machine", "find_machine_file", "bundled_machines",
    "AXES", "SCHEMA", "DYNAMIXEL_MAX_TURNS", "machine_from_dict",
]

#: The axis letters of each G-code firmware (its record in firmware_protocol.kinds).
AXES = {name: KINDS[name].axes for name in gcode_kinds()}


class MachineFileError(ValueError):
    """A machine file is missing, unreadable or breaks the contract (exit 2 on the CLI)."""


class _Key:
    """One key of the schema: its type, bounds, choices and default (``...`` = required)."""

    def __init__(self, kind, default=..., *, lo=None, hi=None, lo_open=False, choices=None, doc=""):
        self.kind, self.default, self.lo, self.hi = kind, default, lo, hi
        self.lo_open, self.choices, self.doc = lo_open, choices, doc

    def expected(self):
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        name = {float: "a number", int: "an integer", str: "a string", bool: "true or false",
                list: "a list"}[self.kind]
        if self.lo is not None and self.hi is not None:
            return f"{name} {'>' if self.lo_open else '>='} {self.lo} and <= {self.hi}"
        if self.lo is not None:
            return f"{name} {'>' if self.lo_open else '>='} {self.lo}"
        return name

    def check(self, value, where):
        ok_type = (isinstance(value, (int, float)) and not isinstance(value, bool)
                   if self.kind is float else
                   isinstance(value, self.kind) and not (self.kind is int and isinstance(value, bool)))
        if not ok_type:
            raise MachineFileError(f"{where} is {value!r}; expected {self.expected()}")
        if self.kind is float:
            value = float(value)
            if not math.isfinite(value):
                raise MachineFileError(f"{where} is {value!r}; expected {self.expected()}")
        if self.choices and value not in self.choices:
            raise MachineFileError(f"{where} is {value!r}; expected {self.expected()}")
        if self.lo is not None and (value <= self.lo if self.lo_open else value < self.lo):
            raise MachineFileError(f"{where} is {value!r}; expected {self.expected()}")
        if self.hi is not None and value > self.hi:
            raise MachineFileError(f"{where} is {value!r}; expected {self.expected()}")
        return value


#: The schema: section -> key -> _Key.  "" is the top level.
SCHEMA = {
    "": {
        "name": _Key(str),
        "description": _Key(str, ""),
    },
    "ring": {
        "pins": _Key(int, lo=3, hi=5000),
        "diameter_mm": _Key(float, lo=10.0, hi=5000.0),
        "pin_diameter_mm": _Key(float, lo=0.0, hi=20.0, lo_open=True),
        "pin0_angle_deg": _Key(float, 0.0, lo=-36000.0, hi=36000.0),
        "travel_deg": _Key(float, 36000.0, lo=360.0, hi=1e7,
                           doc="the ring axis stays within pin0_angle_deg +- travel_deg"),
        "steps_per_deg": _Key(float, None, lo=0.0, hi=1e6, lo_open=True,
                              doc="the firmware's steps per degree of the ring axis (GRBL $100 on X, "
                                  "grblHAL $103 on A, Marlin M92 A); `machines check` compares it"),
        "feed_deg_per_min": _Key(float, 36000.0, lo=0.0, hi=1e7, lo_open=True),
        "accel_deg_per_s2": _Key(float, 720.0, lo=0.0, hi=1e7, lo_open=True),
    },
    "head": {
        "in_mm": _Key(float, lo=-1000.0, hi=1000.0),
        "out_mm": _Key(float, lo=-1000.0, hi=1000.0),
        "feed_mm_per_min": _Key(float, 3000.0, lo=0.0, hi=1e6, lo_open=True),
        "accel_mm_per_s2": _Key(float, 500.0, lo=0.0, hi=1e6, lo_open=True),
        "steps_per_mm": _Key(float, None, lo=0.0, hi=1e6, lo_open=True,
                             doc="the firmware's steps per mm of the head axis (GRBL $101 on Y); "
                                 "the host allows one step of it when it compares positions; `machines check` compares it"),
        "travel_min_mm": _Key(float, None, lo=-1000.0, hi=1000.0,
                              doc="the head axis' mechanical end on the low side (the simulator records "
                                  "driving past it as a crash); default: a quarter of the IN-OUT "
                                  "distance beyond the lower of in_mm, out_mm, home_head_mm"),
        "travel_max_mm": _Key(float, None, lo=-1000.0, hi=1000.0,
                              doc="... and on the high side; default: a quarter of the IN-OUT distance "
                                  "beyond the higher"),
    },
    "controller": {
        "kind": _Key(str, choices=("gcode", "dynamixel")),
        "dialect": _Key(str, None, choices=tuple(gcode_kinds())),
        "ring_axis": _Key(str, None),
        "head_axis": _Key(str, None),
        "baud": _Key(int, 115200, lo=1200, hi=4_000_000),
        "homing": _Key(bool, False, doc="home ($H / G28) before winding"),
        "home_ring_deg": _Key(float, 0.0, lo=-36000.0, hi=36000.0,
                              doc="ring axis value declared at the home switch after homing"),
        "home_head_mm": _Key(float, None, lo=-1000.0, hi=1000.0,
                             doc="head axis value declared at the home switch; default head.in_mm"),
        "head_homing": _Key(bool, False, doc="a home switch on the head axis only (no ring switch): the "
                                             "head homes alone ($HY / G28 Y), which makes a resume after a "
                                             "lost position find the head by itself"),
        "reset_on_open": _Key(bool, False, doc="the board restarts whenever its port is opened (an "
                                               "Arduino Uno's auto-reset on DTR): position lost"),
        # kind = "dynamixel" (Protocol 2.0, X series); ignored for G-code machines
        "protocol": _Key(float, 2.0, choices=(2.0,)),
        "ring_id": _Key(int, 1, lo=0, hi=252),
        "head_id": _Key(int, 2, lo=0, hi=252),
        "model_number": _Key(int, None, lo=0, hi=65535, doc="expected model (ping); None = any X series"),
        "ticks_per_turn": _Key(int, 4096, lo=16, hi=1_000_000),
        "gear_ratio": _Key(float, 1.0, lo=0.0, hi=1000.0, lo_open=True,
                           doc="servo turns per ring turn"),
        "profile_velocity": _Key(int, 0, lo=0, hi=32767, doc="Profile Velocity (0.229 rpm units; 0 = max)"),
        "profile_acceleration": _Key(int, 0, lo=0, hi=32767, doc="Profile Acceleration (214.577 rev/min^2)"),
        "head_in_ticks": _Key(int, None, lo=0, hi=4095),
        "head_out_ticks": _Key(int, None, lo=0, hi=4095),
    },
    "thread": {
        "diameter_mm": _Key(float, lo=0.0, hi=5.0, lo_open=True),
        # written by `stringbot calibrate fit` from a photo of the wound calibration sheet
        "effective_mm": _Key(float, None, lo=0.0, hi=5.0, lo_open=True,
                             doc="calibrated: the width of a sharp, opaque thread that darkens the board as this "
                                 "one does; the planner draws this width (unset: diameter_mm)"),
        "board_gray": _Key(float, None, lo=0.0, hi=1.0,
                           doc="calibrated: the bare board's gray level (sRGB, 0 black, 1 the sheet's white paper)"),
        "thread_gray": _Key(float, None, lo=0.0, hi=1.0,
                            doc="calibrated: the gray of a spot the thread covers (sRGB, as board_gray)"),
    },
    # optional section (every key has a default)
    "winding": {
        "wrap_direction": _Key(str, "auto", choices=("auto", "cw", "ccw"),
                               doc="auto: from the incoming and outgoing chords; cw: the ring axis "
                                   "increases while the head is out (the thread goes round each pin "
                                   "clockwise as the plan is drawn); ccw: it decreases"),
        "dwell_s": _Key(float, 0.0, lo=0.0, hi=60.0, doc="pause after each pin (thread settles)"),
        "pause_every": _Key(int, 0, lo=0, hi=1_000_000, doc="a longer pause every N pins; 0 = never"),
        "pause_s": _Key(float, 0.0, lo=0.0, hi=3600.0, doc="length of that pause (thread tension)"),
    },
}

#: Extended position mode (Operating Mode 4) of X-series servos: +-256 turns of the servo.
DYNAMIXEL_MAX_TURNS = 256


#: Controller keys that only one kind of controller reads.
DYNAMIXEL_ONLY = frozenset(f"controller.{k}" for k in (
    "protocol", "ring_id", "head_id", "model_number", "ticks_per_turn", "gear_ratio",
    "profile_velocity", "profile_acceleration", "head_in_ticks", "head_out_ticks"))
GCODE_ONLY = frozenset(f"controller.{k}" for k in ("dialect", "ring_axis", "head_axis", "reset_on_open",
                                                   "head_homing"))


@dataclass(frozen=True)
class Machine:
    """A checked machine definition.

    ``values`` maps ``"section.key"`` (top-level keys without a section) to the
    checked value, defaults filled in.  The geometry of docs/design.md's physical
    model is derived here so that the host and the simulator agree on it.
    """

    name: str
    path: str | None
    values: dict[str, Any]

    def __getitem__(self, dotted: str) -> Any:
        return self.values[dotted]

    @property
    def pins(self) -> int:
        return self.values["ring.pins"]

    @property
    def pitch_deg(self) -> float:
        """Angle between neighbouring pins."""
        return 360.0 / self.pins

    @property
    def pitch_mm(self) -> float:
        """Arc length between neighbouring pin centres."""
        return math.pi * self.values["ring.diameter_mm"] / self.pins

    @property
    def free_gap_mm(self) -> float:
        """Room left between two pins once the thread is in the gap."""
        return self.pitch_mm - self.values["ring.pin_diameter_mm"] - self.values["thread.diameter_mm"]

    @property
    def gap_tolerance_deg(self) -> float:
        """How far from a gap's centre the head may cross the pin circle, in ring degrees."""
        return (self.free_gap_mm / 2.0) / (math.pi * self.values["ring.diameter_mm"]) * 360.0

    @property
    def circle_mm(self) -> float:
        """Head axis position at which the eyelet crosses the pin circle (midway IN to OUT)."""
        return (self.values["head.in_mm"] + self.values["head.out_mm"]) / 2.0

    @property
    def head_travel_mm(self) -> tuple[float, float]:
        """(low, high) mechanical ends of the head axis: ``head.travel_min_mm`` / ``travel_max_mm``,
        by default a quarter of the IN-OUT distance beyond IN, OUT and the home switch."""
        v = self.values
        ends = [v["head.in_mm"], v["head.out_mm"]]
        if v.get("controller.home_head_mm") is not None:
            ends.append(v["controller.home_head_mm"])
        margin = abs(v["head.out_mm"] - v["head.in_mm"]) / 4.0
        lo, hi = v.get("head.travel_min_mm"), v.get("head.travel_max_mm")
        return (min(ends) - margin if lo is None else lo, max(ends) + margin if hi is None else hi)

    @property
    def thread_width_key(self) -> str:
        """The key of the width the planner draws the thread at: ``thread.effective_mm`` once
        calibrated, else ``thread.diameter_mm``."""
        return "thread.effective_mm" if self.values.get("thread.effective_mm") is not None else "thread.diameter_mm"

    def pin_angle(self, pin: int) -> float:
        """Ring axis position (degrees) at which ``pin`` faces the head station."""
        return self.values["ring.pin0_angle_deg"] + pin * self.pitch_deg

    def to_toml(self) -> str:
        """The checked values as TOML text, defaults filled in.

        Keys left unset, and controller keys of the other controller kind, are omitted.
        """
        lines = []
        other = DYNAMIXEL_ONLY if self.values["controller.kind"] == "gcode" else GCODE_ONLY
        for section, keys in SCHEMA.items():
            if section:
                lines += ["", f"[{section}]"]
            for key in keys:
                dotted = f"{section}.{key}" if section else key
                value = self.values[dotted]
                if value is None or dotted in other:
                    continue
                text = ("true" if value else "false") if isinstance(value, bool) else (
                    f'"{value}"' if isinstance(value, str) else repr(value) if isinstance(value, float)
                    else str(value))
                lines.append(f"{key} = {text}")
        return "\n".join(lines) + "\n"

    def derived(self) -> list[tuple[str, str]]:
        """Derived figures as ``(label, text)`` rows: pitch, free gap, gap tolerance, reach."""
        v = self.values
        mm_per_deg = math.pi * v["ring.diameter_mm"] / 360.0
        travel = v["ring.travel_deg"]
        rows = [
            ("pitch", f"{self.pitch_deg:.4f} deg = {self.pitch_mm:.3f} mm between pin centres"),
            ("free gap", f"{self.free_gap_mm:.3f} mm between pins once the thread is in "
                         f"(pitch - pin {v['ring.pin_diameter_mm']:g} - thread {v['thread.diameter_mm']:g})"),
            ("gap tolerance", f"+-{self.gap_tolerance_deg:.4f} deg = +-{self.gap_tolerance_deg * mm_per_deg:.3f} mm "
                              "from a gap centre where the head may cross the pin circle"),
            ("pin circle", f"the eyelet crosses it at head = {self.circle_mm:g} mm "
                           f"(IN {v['head.in_mm']:g}, OUT {v['head.out_mm']:g})"),
            ("ring travel", f"{v['ring.pin0_angle_deg'] - travel:g} .. {v['ring.pin0_angle_deg'] + travel:g} deg "
                            f"(+-{travel / 360.0:g} turns)"),
        ]
        if v["ring.steps_per_deg"]:
            step = 1.0 / v["ring.steps_per_deg"]
            rows.append(("ring step", f"{step:.4f} deg = {step * mm_per_deg:.4f} mm at the pins "
                                      f"({self.gap_tolerance_deg / step:.0f} steps of gap tolerance)"))
        if v.get("thread.effective_mm") is not None:
            grays = "".join(f", {what} gray {v[key]:g}" for what, key in (("board", "thread.board_gray"),
                                                                          ("thread", "thread.thread_gray"))
                            if v.get(key) is not None)
            rows.append(("thread", f"calibrated: the planner draws {v['thread.effective_mm']:g} mm "
                                   f"({v['thread.effective_mm'] / v['thread.diameter_mm']:.2f} x the "
                                   f"{v['thread.diameter_mm']:g} mm diameter){grays}"))
        if v["controller.kind"] == "dynamixel":
            ticks = v["controller.gear_ratio"] * v["controller.ticks_per_turn"] / 360.0
            reach = (abs(v["ring.pin0_angle_deg"]) + travel) / 360.0 * v["controller.gear_ratio"]
            rows.append(("ring servo", f"{ticks:.2f} ticks per ring degree, {ticks * self.pitch_deg:.1f} per pin; "
                                       f"travel needs {reach:.1f} of {DYNAMIXEL_MAX_TURNS} servo turns"))
        return rows


def bundled_dir():
    """The folder of bundled machine files (installed package data or the source tree)."""
    here = Path(__file__).resolve().parent
    for candidate in (here / "machines", here.parent / "machines"):
        if candidate.is_dir() and any(candidate.glob("*.toml")):
            return candidate
    return here / "machines"


def bundled_machines():
    """Names of the bundled machines, sorted."""
    return sorted(p.stem for p in bundled_dir().glob("*.toml"))


def find_machine_file(name_or_path):
    """Resolve ``--machine``: a bundled name (``grbl-ring``) or a path to a TOML file."""
    text = str(name_or_path)
    path = Path(text)
    if path.suffix == ".toml" or "/" in text or "\\" in text:
        if not path.is_file():
            raise MachineFileError(f"machine file {text!r} does not exist; expected a TOML file "
                                   f"or one of: {', '.join(bundled_machines())}")
        return path
    candidate = bundled_dir() / f"{text}.toml"
    if not candidate.is_file():
        raise MachineFileError(f"unknown machine {text!r}; expected one of: "
                               f"{', '.join(bundled_machines())}, or a path to a .toml file")
    return candidate


def load_machine(name_or_path):
    """Read and check a machine file.

    Raises
    ------
    MachineFileError
        Naming the file, the key and the expected form.
    """
    path = find_machine_file(name_or_path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MachineFileError(f"machine file {str(path)!r} is not valid TOML: {exc}") from None
    return machine_from_dict(doc, source=str(path))


def machine_from_dict(doc, *, source="machine"):
    """Check a decoded machine document against :data:`SCHEMA`."""
    values = {}
    for section, keys in SCHEMA.items():
        table = doc if section == "" else doc.get(section)
        if section and table is None and all(k.default is not ... for k in keys.values()):
            table = {}
        if section and table is None:
            raise MachineFileError(f"{source}: missing section [{section}]")
        if not isinstance(table, dict):
            raise MachineFileError(f"{source}: [{section}] is not a table; expected [{section}] with keys")
        for key, spec in keys.items():
            dotted = f"{section}.{key}" if section else key
            where = f"{source}: {dotted}"
            if key in table:
                values[dotted] = spec.check(table[key], where)
            elif spec.default is ...:
                raise MachineFileError(f"{where} is missing; expected {spec.expected()}")
            else:
                values[dotted] = spec.default
        extra = set(table) - set(keys) - (set(SCHEMA) if section == "" else set())
        for key in sorted(extra):
            dotted = f"{section}.{key}" if section else key
            if not section and isinstance(table[key], dict):
                raise MachineFileError(f"{source}: unknown section [{key}] (a typo?); expected one of "
                                       f"{', '.join(f'[{s}]' for s in SCHEMA if s)}")
            raise MachineFileError(f"{source}: unknown key {dotted!r} (a typo?); expected one of "
                                   f"{', '.join(sorted(keys))}")
    machine = Machine(name=values["name"], path=source, values=values)
    _check_consistency(machine, source)
    return machine


def _check_consistency(m, source):
    v = m.values
    if v["controller.kind"] == "dynamixel":
        for key in ("controller.head_in_ticks", "controller.head_out_ticks"):
            if v[key] is None:
                raise MachineFileError(f"{source}: {key} is missing; expected an integer 0..4095 "
                                       "for kind = 'dynamixel'")
        reach = (abs(v["ring.pin0_angle_deg"]) + v["ring.travel_deg"]) / 360.0 * v["controller.gear_ratio"]
        if reach > DYNAMIXEL_MAX_TURNS:
            raise MachineFileError(
                f"{source}: ring.travel_deg {v['ring.travel_deg']} (+ |pin0_angle_deg|) turns the ring servo "
                f"{reach:.1f} turns; expected at most {DYNAMIXEL_MAX_TURNS} (extended position mode), i.e. "
                f"ring.travel_deg <= {DYNAMIXEL_MAX_TURNS * 360.0 / v['controller.gear_ratio'] - abs(v['ring.pin0_angle_deg']):g}")
        if v["controller.ring_id"] == v["controller.head_id"]:
            raise MachineFileError(f"{source}: controller.ring_id and controller.head_id are both "
                                   f"{v['controller.ring_id']}; expected two different servo ids")
    if v["thread.board_gray"] is not None and v["thread.thread_gray"] is not None \
            and not v["thread.thread_gray"] < v["thread.board_gray"]:
        raise MachineFileError(f"{source}: thread.thread_gray {v['thread.thread_gray']} is not darker than "
                               f"thread.board_gray {v['thread.board_gray']}; expected a thread that shows on the "
                               "board (gray levels 0 black .. 1 white)")
    if v["head.in_mm"] == v["head.out_mm"]:
        raise MachineFileError(f"{source}: head.in_mm equals head.out_mm ({v['head.in_mm']}); "
                               "expected two different positions (IN inside the pin circle, OUT outside)")
    stroke = abs(v["head.out_mm"] - v["head.in_mm"])
    clear = v["ring.pin_diameter_mm"] + v["thread.diameter_mm"]
    if stroke < clear:
        raise MachineFileError(
            f"{source}: the head's stroke |head.out_mm - head.in_mm| = {stroke:g} mm does not clear the pins: "
            f"expected at least ring.pin_diameter_mm + thread.diameter_mm = {clear:g} mm, so that the eyelet "
            "gets round a pin (IN inside the pin circle, OUT outside it)")
    home_head = v["controller.home_head_mm"]
    if home_head is not None and (home_head - m.circle_mm) * (v["head.in_mm"] - m.circle_mm) <= 0:
        raise MachineFileError(
            f"{source}: controller.home_head_mm is {home_head}, outside the pin circle (the head crosses it "
            f"at {m.circle_mm:g} mm); expected a position on the IN side, like head.in_mm = {v['head.in_mm']:g}, "
            "so that the head never sits among the pins while the ring turns")
    lo, hi = m.head_travel_mm
    inside = [v["head.in_mm"], v["head.out_mm"]] + ([home_head] if home_head is not None else [])
    if not lo < min(inside) or not max(inside) < hi:
        raise MachineFileError(
            f"{source}: the head's travel {lo:g} .. {hi:g} mm (head.travel_min_mm .. travel_max_mm) does not "
            f"contain head.in_mm {v['head.in_mm']:g}, head.out_mm {v['head.out_mm']:g}"
            + (f" and controller.home_head_mm {home_head:g}" if len(inside) > 2 else "")
            + "; expected travel_min_mm below all of them and travel_max_mm above")
    if m.free_gap_mm <= 0:
        raise MachineFileError(
            f"{source}: the pins do not fit: pitch {m.pitch_mm:.3f} mm <= pin {v['ring.pin_diameter_mm']} mm "
            f"+ thread {v['thread.diameter_mm']} mm; expected fewer pins, a larger ring or thinner pins")
    if v["controller.kind"] == "gcode":
        dialect = v["controller.dialect"]
        if dialect is None:
            raise MachineFileError(f"{source}: controller.dialect is missing; expected one of "
                                   + ", ".join(f"'{k}'" for k in gcode_kinds()) + " for kind = 'gcode'")
        for key in ("controller.ring_axis", "controller.head_axis"):
            axis = v[key]
            if axis is None or len(axis) != 1 or axis not in AXES[dialect]:
                raise MachineFileError(f"{source}: {key} is {axis!r}; expected one of "
                                       f"{', '.join(AXES[dialect])} for dialect {dialect!r}")
        if v["controller.ring_axis"] == v["controller.head_axis"]:
            raise MachineFileError(f"{source}: controller.ring_axis and controller.head_axis are both "
                                   f"{v['controller.ring_axis']!r}; expected two different axes")
