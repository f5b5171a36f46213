"""Build the simulated firmware a machine file asks for, on its own world."""

import importlib

from ..machine import load_machine
from ..settings import parse_preset
from ..world import World

__all__ = ["build_emulator", "SimulatorError"]


class SimulatorError(ValueError):
    """The simulated machine cannot be built (unknown machine, bad faults, missing emulator)."""


def build_emulator(machine, *, record=None, faults=None, world=None, settings=()):
    """(emulator, world) for ``machine`` (a Machine, a bundled name or a path).

    The dialect picks the firmware: ``grbl`` -> GRBL 1.1h, ``grblhal`` ->
    grblHAL, ``marlin`` -> Marlin; ``kind = "dynamixel"`` -> the Dynamixel bus.
    ``settings``: ``--set`` texts the firmware starts with instead of the
    machine file's values (:func:`firmware_protocol.settings.parse_preset`
    forms); a bad one raises :class:`SimulatorError` naming it.
    """
    if not hasattr(machine, "values"):
        machine = load_machine(machine)
    kind = machine["controller.dialect"] or machine["controller.kind"]
    try:
        presets = [parse_preset(kind, text) for text in settings]
    except ValueError as exc:
        raise SimulatorError(str(exc)) from None
    if world is None:
        world = World(machine, record_path=record)
    kind, dialect = machine["controller.kind"], machine["controller.dialect"]
    if kind == "dynamixel":
        try:
            module = importlib.import_module("firmware_protocol.emulators.dynamixel")
            cls = module.DynamixelEmulator
        except (ImportError, AttributeError) as exc:
            raise SimulatorError(f"machine {machine.name!r} is a Dynamixel machine but the Dynamixel "
                                 f"emulator is not available ({exc})") from None
    elif dialect == "grbl":
        from .grbl import GrblEmulator as cls
    elif dialect == "grblhal":
        from .grbl import GrblHalEmulator as cls
    elif dialect == "fluidnc":
        from .fluidnc import FluidNcEmulator as cls
    elif dialect == "marlin":
        try:
            from .marlin import MarlinEmulator as cls
        except ImportError as exc:
            raise SimulatorError(f"no Marlin emulator available ({exc})") from None
    else:  # pragma: no cover - the machine file check allows no other
        raise SimulatorError(f"no emulator for dialect {dialect!r}")
    try:
        return cls(machine, world=world, faults=faults, presets=presets), world
    except ValueError as exc:
        if presets and str(exc).startswith("--set"):
            raise SimulatorError(str(exc)) from None
        raise
