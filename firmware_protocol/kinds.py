"""Kinds of firmware: one record each, read by the host and by the simulator alike.

A machine file names its kind with ``controller.dialect`` (G-code firmware) or
``controller.kind = "dynamixel"``; :func:`kind_of` finds the record, and refuses a kind that
is not here (the one place that does).  What the record holds:

- who it is: ``name`` (the machine file's word), ``title`` (as people write it), ``axes``;
- its ``family``: the protocol it speaks, which picks the host's link, the G-code flavour
  (``stringbot.motion.gcode``), the settings rules (``stringbot.links.settings_rules``) and
  the status parser.  The GRBL family (GRBL, grblHAL, FluidNC) shares one parser and one
  banner detector (:mod:`firmware_protocol.grbl`): the link, resume's recovery and the
  emulator all use them;
- how to tell it apart: ``banner`` (a regular expression matching the line it prints at
  start-up and after a reset) and ``marker`` (one that matches what it says on connect or to
  ``$I`` / ``M115``, naming it among its family; its first group is the version);
- how to stream to it: ``rx_buffer`` (the receive buffer when the firmware does not report
  it), ``rx_reserve`` (bytes of a reported buffer kept free), ``sync_line`` (the line whose
  answer means every earlier motion is done);
- its settings: ``settings`` (which rules: ``grbl``, ``grblhal`` adds the rotary axes,
  ``marlin``, ``dynamixel``), ``set_form`` / ``set_example`` (what ``--set`` takes),
  ``persistence`` (what becomes of a setting once sent);
- its simulator: ``emulator`` (``"module:Class"``, imported when a machine is built) and
  ``faults`` (``gcode``: :data:`firmware_protocol.faults.FAULT_KINDS`; ``dynamixel``: the
  bus's own).

Adding a kind (docs/extending.md): a record here, a machine file in ``machines/``, and an
emulator when its bytes differ from its family's.
"""

import re
from dataclasses import dataclass

__all__ = ["FirmwareKind", "KINDS", "UnknownKind", "get_kind", "kind_of", "family", "gcode_kinds"]


class UnknownKind(ValueError):
    """A firmware kind that is not in :data:`KINDS`."""


@dataclass(frozen=True)
class FirmwareKind:
    """One kind of firmware (see the module notes)."""

    name: str
    title: str
    family: str
    axes: str
    emulator: str
    set_form: str
    set_example: str
    persistence: str
    settings: str
    banner: str = ""
    marker: str = ""
    rx_buffer: int = 0
    rx_reserve: int = 0
    sync_line: str = ""
    faults: str = "gcode"
    controller: str = "gcode"

    @property
    def gcode(self):
        """It speaks G-code (``controller.kind = "gcode"``)."""
        return self.controller == "gcode"

    def is_banner(self, line):
        """``line`` is this firmware's start-up line (printed again after every reset)."""
        return bool(self.banner) and re.search(self.banner, line.strip()) is not None

    def found_in(self, lines):
        """The version if ``lines`` (what it said on connect and to its identification query)
        name this kind, ``""`` if they name it without a version; None if they do not."""
        if not self.marker:
            return None
        for line in lines:
            m = re.search(self.marker, line.strip())
            if m:
                return next((g for g in m.groups() if g), "")
        return None

    def status_axes(self, ring, head):
        """The axes its position reports list, in order: X, Y, Z, then those of A, B, C that the
        machine's ``ring`` or ``head`` axis uses (what the firmware's build has)."""
        return "XYZ" + "".join(a for a in "ABC" if a in (ring, head) and a in self.axes)

    def emulator_class(self):
        """The simulated firmware's class (imported now)."""
        import importlib

        module, _, name = self.emulator.partition(":")
        return getattr(importlib.import_module(module), name)


_GRBL_PERSISTENCE = "writes each setting to its {} at once: it stays after a reset or a power cycle"

#: Every kind, by name.  A family's own kind (GRBL for the GRBL family) is what answers when no
#: other kind of the family names itself (:func:`family` tries it last).
KINDS = {k.name: k for k in (
    FirmwareKind(
        "grbl", "GRBL", "grbl", "XYZ", "firmware_protocol.emulators.grbl:GrblEmulator",
        set_form="'$N=VALUE'", set_example="$100=40", persistence="GRBL " + _GRBL_PERSISTENCE.format("EEPROM"),
        settings="grbl", banner=r"^Grbl\s+\S+", marker=r"^(?:Grbl\s+(\S+)|\[VER:([^:\]]*))",
        rx_buffer=128, rx_reserve=1, sync_line="G4 P0"),
    FirmwareKind(
        "grblhal", "grblHAL", "grbl", "XYZABC", "firmware_protocol.emulators.grbl:GrblHalEmulator",
        set_form="'$N=VALUE'", set_example="$103=80",
        persistence="grblHAL " + _GRBL_PERSISTENCE.format("non-volatile storage"),
        settings="grblhal", banner=r"(?i)^grblhal\s+\S+", marker=r"(?i)^(?:grblhal\s+(\S+)|\[FIRMWARE:grblHAL)",
        rx_buffer=1024, sync_line="G4 P0"),
    FirmwareKind(
        "fluidnc", "FluidNC", "grbl", "XYZABC", "firmware_protocol.emulators.fluidnc:FluidNcEmulator",
        set_form="'$N=VALUE' (GRBL's numbers for the items of config.yaml)", set_example="$100=40",
        persistence="FluidNC applies a numbered $ setting to the configuration it runs (the matching item of "
                    "config.yaml, e.g. axes/a/steps_per_mm): put the same value in config.yaml to keep it after "
                    "a restart",
        settings="grbl", banner=r"^Grbl\s+\S+\s+\[FluidNC\b", marker=r"FluidNC\s+(v?[\w.\-]+)",
        rx_buffer=128, sync_line="G4 P0"),
    FirmwareKind(
        "marlin", "Marlin", "marlin", "XYZABC", "firmware_protocol.emulators.marlin:MarlinEmulator",
        set_form="'M92|M203|M201|M204|M211 WORDS'", set_example="M92 A40",
        persistence="Marlin keeps M92/M203/M201/M204 in RAM until M500 (sent last) stores them in EEPROM; "
                    "M211 S0 lasts until the next reset",
        settings="marlin", banner=r"^start$", marker=r"FIRMWARE_NAME:\s*Marlin\s*([^\s(]*)", sync_line="M400"),
    FirmwareKind(
        "dynamixel", "Dynamixel", "dynamixel", "", "firmware_protocol.emulators.dynamixel:DynamixelEmulator",
        set_form="'ID:ITEM=VALUE' (ID a servo id, 'ring' or 'head'; ITEM a control-table name or address)",
        set_example="ring:Drive Mode=1",
        persistence="Drive Mode, Velocity Limit and the Position Limits are EEPROM items the servo keeps "
                    "after power off; torque is turned off to write them (wind turns it on again)",
        settings="dynamixel", faults="dynamixel", controller="dynamixel"),
)}


def get_kind(name):
    """The record called ``name``; :class:`UnknownKind` naming every kind there is."""
    if name not in KINDS:
        raise UnknownKind(f"unknown firmware {name!r}; expected one of {', '.join(gcode_kinds())} "
                          "(controller.dialect) or controller.kind = 'dynamixel'")
    return KINDS[name]


def kind_of(machine):
    """The record of a machine (a :class:`firmware_protocol.machine.Machine`)."""
    if machine["controller.kind"] != "gcode":
        return get_kind(machine["controller.kind"])
    return get_kind(machine["controller.dialect"])


def gcode_kinds():
    """The names a machine file's ``controller.dialect`` takes."""
    return [k.name for k in KINDS.values() if k.gcode]


def family(name):
    """The kinds of a family, the family's own kind last (the others name themselves apart)."""
    return sorted((k for k in KINDS.values() if k.family == name), key=lambda k: k.name == name)
