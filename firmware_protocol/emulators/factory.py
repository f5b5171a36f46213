"""Build the simulated firmware a machine file asks for, on its own world."""

from ..kinds import kind_of
from ..machine import load_machine
from ..settings import parse_preset
from ..world import World

__all__ = ["build_emulator", "SimulatorError"]


class SimulatorError(ValueError):
    """The simulated machine cannot be built (unknown machine, bad faults, missing emulator)."""


def build_emulator(machine, *, record=None, faults=None, world=None, settings=()):
    """(emulator, world) for ``machine`` (a Machine, a bundled name or a path).

    The machine's kind of firmware (:mod:`firmware_protocol.kinds`) names the emulator: ``grbl``
    -> GRBL 1.1h, ``grblhal`` -> grblHAL, ``fluidnc`` -> FluidNC, ``marlin`` -> Marlin,
    ``kind = "dynamixel"`` -> the Dynamixel bus.  ``settings``: ``--set`` texts the firmware
    starts with instead of the machine file's values (:func:`firmware_protocol.settings.parse_preset`
    forms); a bad one raises :class:`SimulatorError` naming it.
    """
    if not hasattr(machine, "values"):
        machine = load_machine(machine)
    try:
        kind = kind_of(machine)
        presets = [parse_preset(kind.name, text) for text in settings]
    except ValueError as exc:
        raise SimulatorError(str(exc)) from None
    try:
        cls = kind.emulator_class()
    except (ImportError, AttributeError) as exc:
        raise SimulatorError(f"machine {machine.name!r} is a {kind.title} machine but its emulator is not "
                             f"available ({exc})") from None
    if world is None:
        world = World(machine, record_path=record)
    try:
        return cls(machine, world=world, faults=faults, presets=presets), world
    except ValueError as exc:
        if presets and str(exc).startswith("--set"):
            raise SimulatorError(str(exc)) from None
        raise
