"""GRBL's states, its EEPROM settings (``$$``, ``$x=val``) and the text of its reports.

The settings table follows GRBL 1.1's ``settings.md`` (and grblHAL's
``$376`` rotary axes, ``$538`` rotary wrap); the simulated machine fills in
what its machine file knows (steps per unit, axis rates and accelerations,
homing, the rotary ring axis) and keeps GRBL's defaults for the rest.  Settings survive resets and power
cycles, as GRBL's EEPROM does.
"""

import enum

from .grbl_parser import fmt

__all__ = ["GrblState", "Variant", "GRBL", "GRBLHAL", "default_settings", "format_settings", "store_setting", "build_steps"]


class GrblState(enum.Enum):
    """What ``?`` reports the machine doing."""

    IDLE = "Idle"
    RUN = "Run"
    HOLD = "Hold"
    JOG = "Jog"
    ALARM = "Alarm"
    HOME = "Home"
    CHECK = "Check"
    SLEEP = "Sleep"


class Variant:
    """What differs between stock GRBL 1.1h and grblHAL: banner, buffers, axes, ``$I``."""

    def __init__(self, name, banner, version, build, rx_size, planner_blocks, base_axes,
                 status_mask, options):
        self.name, self.banner, self.version, self.build = name, banner, version, build
        self.rx_size, self.planner_blocks, self.base_axes = rx_size, planner_blocks, base_axes
        self.status_mask, self.options = status_mask, options

    def build_info(self, axes, user_string):
        """The lines of ``$I`` (without ``ok``)."""
        lines = [f"[VER:{self.version}.{self.build}:{user_string}]"]
        if self.name == "grbl":
            lines.append(f"[OPT:{self.options},{self.planner_blocks},{self.rx_size}]")
        else:
            lines.append(f"[OPT:{self.options},{self.planner_blocks},{self.rx_size},{len(axes)},0]")
            lines.append(f"[AXS:{len(axes)}:{axes}]")
            lines.append("[NEWOPT:ENUMS,RT+,HOME]")
            lines.append("[FIRMWARE:grblHAL]")
            lines.append("[DRIVER:stringbot simulator]")
        return lines


GRBL = Variant("grbl", "Grbl 1.1h ['$' for help]", "1.1h", "20190830", 128, 15, "XYZ", 1, "V")
GRBLHAL = Variant("grblhal", "GrblHAL 1.1f ['$' or '$HELP' for help]", "1.1f", "20240101", 1024, 100,
                  "XYZ", 511, "VNMSL")

_INT_SETTINGS = {0, 1, 2, 3, 4, 5, 6, 10, 13, 20, 21, 22, 23, 26, 32, 376, 538}
_GLOBAL = [0, 1, 2, 3, 4, 5, 6, 10, 11, 12, 13, 20, 21, 22, 23, 24, 25, 26, 27, 30, 31, 32]
_GLOBAL_DEFAULTS = {0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002, 13: 0,
                    20: 0, 21: 0, 22: 0, 23: 0, 24: 25.0, 25: 500.0, 26: 250, 27: 1.0, 30: 1000.0,
                    31: 0.0, 32: 0}
#: grblHAL's rotary axes ($376) and rotary wrap ($538): bit 0 = A, 1 = B, 2 = C.
_HAL_DEFAULTS = {376: 0, 538: 0}


def build_steps(machine):
    """Steps per unit of the simulated build's (ring, head) axes: the machine file's
    ``ring.steps_per_deg`` and ``head.steps_per_mm`` (80 where it gives none)."""
    v = machine.values
    return v.get("ring.steps_per_deg") or 80.0, v.get("head.steps_per_mm") or 80.0


def default_settings(variant, axes, machine):
    """The EEPROM settings of a controller configured as ``machine`` says (its steps per unit,
    rates, accelerations, homing, rotary axis), GRBL's defaults for the rest."""
    s = dict(_GLOBAL_DEFAULTS)
    s[10] = variant.status_mask
    s[22] = 1 if machine["controller.homing"] else 0
    ring, head = machine["controller.ring_axis"], machine["controller.head_axis"]
    ring_steps, head_steps = build_steps(machine)
    for i, axis in enumerate(axes):
        steps, rate, accel, travel = 250.0, 500.0, 10.0, 200.0
        if axis == ring:
            steps, rate = ring_steps, machine["ring.feed_deg_per_min"]
            accel, travel = machine["ring.accel_deg_per_s2"], 2 * machine["ring.travel_deg"]
        elif axis == head:
            steps, rate = head_steps, machine["head.feed_mm_per_min"]
            accel = machine["head.accel_mm_per_s2"]
            travel = abs(machine["head.out_mm"] - machine["head.in_mm"]) * 2
        s[100 + i], s[110 + i], s[120 + i], s[130 + i] = steps, rate, accel, travel
    if variant.name == "grblhal":
        s.update(_HAL_DEFAULTS)
        if ring in "ABC":
            s[376] = 1 << "ABC".index(ring)
    return s


def _value(key, value):
    if key in _INT_SETTINGS:
        return str(int(value))
    if key in (30, 31):
        return fmt(value, 0)
    return fmt(value, 3)


def format_settings(settings):
    """The lines of ``$$`` (without ``ok``), in GRBL's order."""
    keys = [k for k in _GLOBAL if k in settings] + sorted(k for k in settings if k >= 100)
    return [f"${k}={_value(k, settings[k])}" for k in keys]


def store_setting(settings, key, value, n_axes):
    """``$key=value``: returns 0 (ok) or a GRBL error code, applying the change on success."""
    if 100 <= key < 140:
        base, axis = divmod(key - 100, 10)
        if axis >= n_axes or base > 3:
            return 3
        if value < 0:
            return 4
        settings[key] = float(value)
        return 0
    if key not in settings:
        return 3
    if value < 0:
        return 4
    if key == 0 and value < 3:
        return 6
    if key == 20 and value and not settings[22]:
        return 10
    settings[key] = int(value) if key in _INT_SETTINGS else float(value)
    return 0
