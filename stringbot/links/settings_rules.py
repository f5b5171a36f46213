"""What the machine file needs of the firmware's settings, setting by setting (pure: no I/O).

:func:`compare` takes the settings a firmware reported (GRBL/grblHAL ``$$``,
Marlin ``M503``, the Dynamixel control table) and the machine file, and
returns a :class:`Report`: one :class:`Row` per setting with the firmware's
value, what the machine file needs (naming its key), a :class:`Verdict` and
the exact line that fixes it (``$100=44.4444``, ``M92 A44.4444``,
``1:Drive Mode=0``).  Only ``Verdict.DISAGREES`` rows stop a winding.

A value read back is compared within its printed precision (GRBL prints 3
decimals, Marlin 2): ``$100=44.444`` agrees with ``steps_per_deg = 44.4444``.
"""

import enum
from dataclasses import dataclass, field

from firmware_protocol import dynamixel as dx
from firmware_protocol import settings as fs
from firmware_protocol.kinds import KINDS, kind_of

__all__ = ["Verdict", "Row", "Report", "compare", "PERSISTENCE"]


class Verdict(enum.Enum):
    OK = "ok"
    DISAGREES = "DISAGREES"        # the winding would go wrong or stop: refused
    UNCHECKED = "unchecked"        # the machine file does not say (e.g. no steps_per_deg)
    SET_AT_START = "wind sets it"  # the link writes it before the first move
    NOTE = "note"                  # worth knowing; the winding is not affected


@dataclass(frozen=True)
class Row:
    setting: str                   # e.g. "$100 X steps/unit (ring)"
    firmware: str                  # its value as read
    needs: str                     # what the machine file needs, naming the key
    verdict: Verdict
    fix: tuple = ()                # lines to send that fix it
    hint: str = ""                 # what else to do (edit the machine file, rebuild)


#: What becomes of a fix once sent, per kind of firmware (firmware_protocol.kinds).
PERSISTENCE = {k.name: k.persistence for k in KINDS.values()}


@dataclass
class Report:
    """The comparison of one firmware with one machine file."""

    machine: object
    kind: str                      # a name of firmware_protocol.kinds.KINDS
    rows: list
    save: tuple = ()               # lines that make the fixes stick (Marlin: M500)
    notes: list = field(default_factory=list)
    firmware: str = ""             # who answered, e.g. "Grbl 1.1h"

    @property
    def disagreements(self):
        return [r for r in self.rows if r.verdict is Verdict.DISAGREES]

    @property
    def agrees(self):
        return not self.disagreements

    @property
    def fixes(self):
        """Every line that fixes a disagreement, in order, then the saving line(s) if any apply."""
        lines = []
        for row in self.disagreements:
            lines += [x for x in row.fix if x not in lines]
        if lines and self.save:
            lines += list(self.save)
        return lines


def compare(machine, firmware):
    """Compare ``firmware`` (what :mod:`.settings_check` read) with ``machine``; -> :class:`Report`.

    ``firmware`` is ``{N: value}`` for GRBL/grblHAL, a
    :class:`firmware_protocol.settings.MarlinSettings` for Marlin, and
    ``{"ring": {item: value, "id": i, "model": m}, "head": {...}}`` for Dynamixel.
    """
    kind = kind_of(machine)
    if kind.settings == "dynamixel":
        return Report(machine, kind.name, _dynamixel_rows(machine, firmware))
    if kind.settings == "marlin":
        rows, notes = _marlin_rows(machine, firmware)
        return Report(machine, kind.name, rows, save=("M500",), notes=notes)
    return Report(machine, kind.name, _grbl_rows(machine, firmware, rotary=kind.settings == "grblhal"))


def _close(value, need, decimals):
    return abs(value - need) <= 0.5 * 10 ** -decimals + 1e-9 * abs(need)


def _at_least(value, need, decimals):
    return value >= need or _close(value, need, decimals)


def _n(value):
    return fs.number(value)


# ---- GRBL / grblHAL ------------------------------------------------------------------------------

def _grbl_rows(m, s, *, rotary):
    ring, head = m["controller.ring_axis"], m["controller.head_axis"]
    rows = []

    def row(n, role, need, key, *, minimum, unit=""):
        label = f"{fs.setting_label(n)} ({role})"
        if need is None:
            value = s.get(n)
            return rows.append(Row(label, "-" if value is None else _n(value), f"not in the machine file ({key})",
                                   Verdict.UNCHECKED))
        needs = f"{'>= ' if minimum else ''}{_n(need)}{unit} ({key})"
        if n not in s or isinstance(s[n], str):
            return rows.append(Row(label, "missing", needs, Verdict.DISAGREES,
                                   hint=f"the firmware has no ${n}: a build with the {label.split()[1]} axis "
                                        "is needed"))
        good = _at_least(s[n], need, 3) if minimum else _close(s[n], need, 3)
        rows.append(Row(label, _n(s[n]), needs, Verdict.OK if good else Verdict.DISAGREES,
                        fix=() if good else (fs.setting_line(n, need),)))

    row(fs.axis_setting(fs.STEPS_PER_UNIT, ring), "ring", m["ring.steps_per_deg"], "ring.steps_per_deg",
        minimum=False)
    row(fs.axis_setting(fs.STEPS_PER_UNIT, head), "head", m["head.steps_per_mm"], "head.steps_per_mm",
        minimum=False)
    row(fs.axis_setting(fs.MAX_RATE, ring), "ring", m["ring.feed_deg_per_min"], "ring.feed_deg_per_min",
        minimum=True)
    row(fs.axis_setting(fs.MAX_RATE, head), "head", m["head.feed_mm_per_min"], "head.feed_mm_per_min",
        minimum=True)
    row(fs.axis_setting(fs.ACCELERATION, ring), "ring", m["ring.accel_deg_per_s2"], "ring.accel_deg_per_s2",
        minimum=True)
    row(fs.axis_setting(fs.ACCELERATION, head), "head", m["head.accel_mm_per_s2"], "head.accel_mm_per_s2",
        minimum=True)
    rows.append(_homing_row(m, s))
    rows.append(_soft_limits_row(m, s, ring, head))
    inches = s.get(fs.REPORT_INCHES)
    if inches is not None:
        good = not inches
        rows.append(Row(fs.setting_label(fs.REPORT_INCHES), _n(inches), "0 (positions reported in mm)",
                        Verdict.OK if good else Verdict.DISAGREES, fix=() if good else ("$13=0",)))
    if rotary and ring in "ABC":           # grblHAL's $376 / $538
        rows += _rotary_rows(s, ring)
    return rows


def _homing_row(m, s):
    label = fs.setting_label(fs.HOMING)
    value = s.get(fs.HOMING)
    want = bool(m["controller.homing"])
    needs = "1 (controller.homing = true)" if want else "0 (controller.homing = false)"
    if value is None or isinstance(value, str):
        return Row(label, "missing", needs, Verdict.DISAGREES)
    good = bool(int(value) & 1) == want
    fixed = (int(value) | 1) if want else (int(value) & ~1)
    hint = "" if good else ("homing ($H) is refused with error:5 while it is off" if want else
                            "with homing on, the firmware starts locked in alarm and waits for $H")
    return Row(label, _n(value), needs, Verdict.OK if good else Verdict.DISAGREES,
               fix=() if good else (fs.setting_line(fs.HOMING, fixed),), hint=hint)


def _soft_limits_row(m, s, ring, head):
    label = fs.setting_label(fs.SOFT_LIMITS)
    value = s.get(fs.SOFT_LIMITS)
    ring_n, head_n = fs.axis_setting(fs.MAX_TRAVEL, ring), fs.axis_setting(fs.MAX_TRAVEL, head)
    span, reach = 2 * m["ring.travel_deg"], abs(m["head.out_mm"] - m["head.in_mm"])
    needs = f"0, or ${ring_n} >= {_n(span)} and ${head_n} >= {_n(reach)} (ring.travel_deg, head travel)"
    if value is None or isinstance(value, str):
        return Row(label, "missing", needs, Verdict.UNCHECKED)
    if not value:
        return Row(label, _n(value), needs, Verdict.OK)
    travels = f"{_n(value)} (${ring_n}={_n(s.get(ring_n, 0))}, ${head_n}={_n(s.get(head_n, 0))})"
    good = _at_least(s.get(ring_n, 0), span, 3) and _at_least(s.get(head_n, 0), reach, 3)
    return Row(label, travels, needs, Verdict.OK if good else Verdict.DISAGREES,
               fix=() if good else ("$20=0",),
               hint="" if good else "soft limits would stop the ring before it has turned ring.travel_deg")


def _rotary_rows(s, ring):
    bit = 1 << "ABC".index(ring)
    rows = []
    label = f"{fs.setting_label(fs.ROTARY_AXES)} (bit {bit.bit_length() - 1} = {ring})"
    value = s.get(fs.ROTARY_AXES)
    needs = f"{ring} set: {ring} in degrees (controller.ring_axis = {ring!r})"
    if value is None or isinstance(value, str):
        rows.append(Row(label, "missing", needs, Verdict.UNCHECKED,
                        hint="this grblHAL does not report $376: check that A moves in degrees"))
    else:
        good = bool(int(value) & bit)
        rows.append(Row(label, _n(value), needs, Verdict.OK if good else Verdict.DISAGREES,
                        fix=() if good else (fs.setting_line(fs.ROTARY_AXES, int(value) | bit),)))
    wrap = s.get(fs.ROTARY_WRAP)
    if wrap is not None and not isinstance(wrap, str):
        good = not int(wrap) & bit
        rows.append(Row(f"{fs.setting_label(fs.ROTARY_WRAP)} (bit {bit.bit_length() - 1} = {ring})", _n(wrap),
                        f"{ring} clear: the ring counts whole turns", Verdict.OK if good else Verdict.DISAGREES,
                        fix=() if good else (fs.setting_line(fs.ROTARY_WRAP, int(wrap) & ~bit),),
                        hint="" if good else "a wrapped axis moves the short way round, not the way each "
                                             "pin is hooked"))
    return rows


# ---- Marlin -------------------------------------------------------------------------------------

def _marlin_rows(m, ms):
    ring, head = m["controller.ring_axis"], m["controller.head_axis"]
    rows, notes = [], []

    def row(code, axis, role, values, need, key, *, minimum, unit=""):
        label = f"{code} {axis} ({role})"
        value = values.get(axis)
        if need is None:
            return rows.append(Row(label, "-" if value is None else _n(value), f"not in the machine file ({key})",
                                   Verdict.UNCHECKED))
        needs = f"{'>= ' if minimum else ''}{_n(need)}{unit} ({key})"
        if value is None:
            return rows.append(Row(label, "missing", needs, Verdict.DISAGREES,
                                   hint=f"M503 reports no {axis}: a build with axis {axis} is needed"))
        good = _at_least(value, need, 2) if minimum else _close(value, need, 2)
        rows.append(Row(label, _n(value), needs, Verdict.OK if good else Verdict.DISAGREES,
                        fix=() if good else (f"{code} {axis}{_n(need)}",)))

    row("M92", ring, "ring steps/deg", ms.steps, m["ring.steps_per_deg"], "ring.steps_per_deg", minimum=False)
    row("M92", head, "head steps/mm", ms.steps, m["head.steps_per_mm"], "head.steps_per_mm", minimum=False)
    row("M203", ring, "ring max feed", ms.max_feed, m["ring.feed_deg_per_min"] / 60.0,
        "ring.feed_deg_per_min / 60", minimum=True, unit=" deg/s")
    row("M203", head, "head max feed", ms.max_feed, m["head.feed_mm_per_min"] / 60.0,
        "head.feed_mm_per_min / 60", minimum=True, unit=" mm/s")
    row("M201", ring, "ring max accel", ms.max_accel, m["ring.accel_deg_per_s2"], "ring.accel_deg_per_s2",
        minimum=True)
    row("M201", head, "head max accel", ms.max_accel, m["head.accel_mm_per_s2"], "head.accel_mm_per_s2",
        minimum=True)
    top = max(m["ring.accel_deg_per_s2"], m["head.accel_mm_per_s2"])
    row("M204", "T", "travel accel", ms.accel, top, "the larger of ring and head accel", minimum=True)
    rows.append(_endstops_row(m, ms, ring, head, notes))
    return rows, notes


def _endstops_row(m, ms, ring, head, notes):
    pin0, travel = m["ring.pin0_angle_deg"], m["ring.travel_deg"]
    lo_h, hi_h = sorted((m["head.in_mm"], m["head.out_mm"]))
    needs = (f"S0, or {ring} {_n(pin0 - travel)}..{_n(pin0 + travel)} and {head} {_n(lo_h)}..{_n(hi_h)} "
             "inside (ring.travel_deg, head travel)")
    if ms.soft_endstops is None:
        return Row("M211 soft endstops", "missing", needs, Verdict.UNCHECKED,
                   hint="M503 does not report M211 (a build without software endstops)")
    if not ms.soft_endstops:
        return Row("M211 soft endstops", "S0", needs, Verdict.OK)

    def inside(axis, lo, hi):
        a, b = ms.soft_min.get(axis), ms.soft_max.get(axis)
        return a is None or b is None or (a <= lo + 0.005 and b >= hi - 0.005)

    span = " ".join(f"{a}{_n(ms.soft_min.get(a, float('nan')))}..{_n(ms.soft_max.get(a, float('nan')))}"
                    for a in (ring, head))
    good = inside(ring, pin0 - travel, pin0 + travel) and inside(head, lo_h, hi_h)
    if not good:
        notes.append("Marlin turns its software endstops on again at every start: to keep them off, build it "
                     f"with wider {ring}_MIN_POS/{ring}_MAX_POS or without software endstops on {ring}")
    return Row("M211 soft endstops", f"S1 {span}", needs, Verdict.OK if good else Verdict.DISAGREES,
               fix=() if good else ("M211 S0",),
               hint="" if good else "the endstops would stop the ring before it has turned ring.travel_deg")


# ---- Dynamixel ------------------------------------------------------------------------------------

RPM_PER_UNIT, REV_PER_MIN2_PER_UNIT = 0.229, 214.577


def _dynamixel_rows(m, servos):
    c = lambda key: m[f"controller.{key}"]
    rows = []
    ring, head = servos["ring"], servos["head"]
    for role, servo in (("ring", ring), ("head", head)):
        sid = servo["id"]
        name = f"{role} (id {sid})"
        model = servo.get("model")
        if model in dx.MODELS:
            good = c("ticks_per_turn") == 4096
            rows.append(Row(f"{name} model, ticks per turn", f"{dx.MODELS[model]}: 4096",
                            f"{c('ticks_per_turn')} (controller.ticks_per_turn)",
                            Verdict.OK if good else Verdict.DISAGREES,
                            hint="" if good else "set controller.ticks_per_turn = 4096 in the machine file"))
        mode = servo["Operating Mode"]
        want = dx.OperatingMode.EXTENDED_POSITION if role == "ring" else dx.OperatingMode.POSITION
        what = "4: extended position (multi-turn)" if role == "ring" else "3: position"
        rows.append(Row(f"{name} Operating Mode (11)", str(mode), what,
                        Verdict.OK if mode == want else Verdict.SET_AT_START))
        drive = servo["Drive Mode"]
        bad = drive & 0x05
        words = [w for bit, w in ((1, "Reverse Mode"), (4, "Time-based Profile")) if drive & bit]
        rows.append(Row(f"{name} Drive Mode (10)", f"{drive}" + (f" ({', '.join(words)})" if words else ""),
                        "bits 0, 2 clear (normal direction, velocity-based profile)",
                        Verdict.DISAGREES if bad else Verdict.OK,
                        fix=(f"{sid}:Drive Mode={drive & ~0x05}",) if bad else (),
                        hint="Reverse Mode turns the servo the other way than the machine file's ticks; a "
                             "time-based profile reads profile_velocity as milliseconds" if bad else ""))
        limit, profile = servo["Velocity Limit"], c("profile_velocity")
        good = profile <= limit and limit > 0
        rows.append(Row(f"{name} Velocity Limit (44)", str(limit),
                        f">= {profile} (controller.profile_velocity)" if profile else "> 0", Verdict.OK if good
                        else Verdict.DISAGREES, fix=() if good else (f"{sid}:Velocity Limit={max(profile, 1)}",),
                        hint="" if good else "the servo refuses a Profile Velocity above its Velocity Limit"))
    lo, hi = sorted((c("head_in_ticks"), c("head_out_ticks")))
    low, high = head["Min Position Limit"], head["Max Position Limit"]
    good = low <= lo and high >= hi
    fix = ([f"{head['id']}:Min Position Limit={lo}"] if low > lo else []) + \
          ([f"{head['id']}:Max Position Limit={hi}"] if high < hi else [])
    rows.append(Row(f"head (id {head['id']}) Position Limits (52, 48)", f"{low}..{high}",
                    f"{lo}..{hi} inside (controller.head_in_ticks, head_out_ticks)",
                    Verdict.OK if good else Verdict.DISAGREES, fix=tuple(fix),
                    hint="" if good else "the servo refuses a Goal Position outside its limits"))
    rows += _motion_notes(m, ring, head)
    return rows


def _motion_notes(m, ring, head):
    """What the profile, the gear ratio and the ticks give the ring and the head, against the file's
    feeds and accelerations (the estimates use those)."""
    c = lambda key: m[f"controller.{key}"]
    rows = []
    tpt, gear = c("ticks_per_turn"), c("gear_ratio")
    velocity = c("profile_velocity") or ring["Velocity Limit"]
    accel = c("profile_acceleration")
    mm_per_tick = abs(m["head.out_mm"] - m["head.in_mm"]) / abs(c("head_out_ticks") - c("head_in_ticks"))
    checks = [("ring speed", velocity * RPM_PER_UNIT * 360.0 / gear, m["ring.feed_deg_per_min"],
               "ring.feed_deg_per_min", "deg/min", "gear_ratio x Profile Velocity"),
              ("head speed", (c("profile_velocity") or head["Velocity Limit"]) * RPM_PER_UNIT * tpt * mm_per_tick,
               m["head.feed_mm_per_min"], "head.feed_mm_per_min", "mm/min", "Profile Velocity, ticks, head_*_ticks")]
    if accel:
        checks += [("ring acceleration", accel * REV_PER_MIN2_PER_UNIT / 3600.0 * 360.0 / gear,
                    m["ring.accel_deg_per_s2"], "ring.accel_deg_per_s2", "deg/s^2",
                    "gear_ratio x Profile Acceleration"),
                   ("head acceleration", accel * REV_PER_MIN2_PER_UNIT / 3600.0 * tpt * mm_per_tick,
                    m["head.accel_mm_per_s2"], "head.accel_mm_per_s2", "mm/s^2", "Profile Acceleration")]
    for what, implied, said, key, unit, source in checks:
        good = abs(implied - said) <= 0.05 * said
        rows.append(Row(f"{what} ({source})", f"{implied:.0f} {unit}", f"{_n(said)} ({key})",
                        Verdict.OK if good else Verdict.NOTE,
                        hint="" if good else f"set {key} = {implied:.0f}: the estimates use it"))
    return rows
