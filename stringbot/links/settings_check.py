"""Do the firmware's settings agree with the machine file?  Read them, compare, fix on request.

Over a link that is open (and identified here if it is not yet):

- GRBL / grblHAL / FluidNC: ``$$`` (identification reads it, after ``$I``);
- Marlin: ``M503``;
- Dynamixel: the control-table items of both servos (Operating Mode, Drive
  Mode, Velocity Limit, Position Limits) and their model numbers.

:func:`check_link` returns the :class:`~.settings_rules.Report`;
:func:`require_agreement` raises :class:`SettingsDisagree` (exit 1, nothing
moved, nothing wound) when the firmware disagrees; :func:`apply_fixes` sends
the report's fix lines, never unasked: the command line asks first.
"""

import logging

from firmware_protocol import settings as fs
from firmware_protocol.kinds import kind_of

from ..errors import MachineFailure
from .settings_rules import PERSISTENCE, Report, Row, Verdict, compare

__all__ = ["SettingsDisagree", "check_link", "require_agreement", "apply_fixes", "read_firmware",
           "Report", "Row", "Verdict", "PERSISTENCE"]

log = logging.getLogger(__name__)

SERVO_ITEMS = ("Operating Mode", "Drive Mode", "Velocity Limit", "Min Position Limit", "Max Position Limit")


class SettingsDisagree(MachineFailure):
    """The firmware's settings disagree with the machine file: nothing was moved or wound.

    ``lines``: one line per disagreement (the setting, its value, what the machine file needs
    and the line that fixes it); ``report``: the whole comparison.
    """

    def __init__(self, report):
        self.report = report
        self.lines = [_disagreement(row) for row in report.disagreements]
        super().__init__("the firmware's settings disagree with the machine file: " + "; ".join(self.lines))


def _disagreement(row):
    fix = f"; send {' then '.join(row.fix)}" if row.fix else ""
    hint = f" ({row.hint})" if row.hint else ""
    return f"{row.setting} is {row.firmware}, the machine file needs {row.needs}{fix}{hint}"


def _rules(machine):
    """Which settings rules the machine's kind of firmware follows (firmware_protocol.kinds)."""
    return kind_of(machine).settings


def read_firmware(link, machine, *, fresh=False):
    """The settings as the firmware reports them (see :func:`settings_rules.compare` for the forms).

    GRBL's ``$$`` as identification read it, unless ``fresh`` (after sending fixes).
    """
    if link.info is None:
        link.identify()
    rules = _rules(machine)
    if rules == "dynamixel":
        out = {}
        for role, servo_id in link.ids.items():
            servo = {"id": servo_id, "model": getattr(link.servos.get(servo_id), "model", None)}
            for item in SERVO_ITEMS:
                servo[item] = link.bus.read(servo_id, item, alert_ok=True)
            out[role] = servo
        return out
    proto = link.proto
    if rules == "marlin":
        return fs.parse_m503(proto.query("M503"))
    if proto.settings is None or fresh:
        proto.read_settings()
    return dict(proto.settings)


def check_link(link, machine, *, fresh=False):
    """Identify (if not yet), read the settings, compare them with ``machine``; -> Report."""
    report = compare(machine, read_firmware(link, machine, fresh=fresh))
    report.firmware = f"{link.info.name} {link.info.version}".strip() if link.info else "?"
    log.info("firmware settings: %d compared with the machine file, %d disagree", len(report.rows),
             len(report.disagreements))
    for row in report.disagreements:
        log.info("settings: %s", _disagreement(row))
    return report


def require_agreement(link, machine):
    """:func:`check_link`, raising :class:`SettingsDisagree` when any setting disagrees."""
    report = check_link(link, machine)
    if not report.agrees:
        raise SettingsDisagree(report)
    return report


def apply_fixes(link, machine, lines):
    """Send ``lines`` (a report's :attr:`~Report.fixes`): G-code settings as lines the firmware
    answers ``ok``; Dynamixel ``ID:ITEM=VALUE`` as writes with that servo's torque off."""
    if _rules(machine) != "dynamixel":
        for line in lines:
            link.proto.command(line)
        return
    for line in lines:
        setting = fs.parse_servo_setting(line)
        link.bus.write(setting.who, "Torque Enable", 0)
        link.bus.write(setting.who, setting.item, setting.value)
