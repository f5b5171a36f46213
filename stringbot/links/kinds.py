"""The host's side of each kind of firmware (the records: :mod:`firmware_protocol.kinds`).

:func:`machine_kind` is the one place that refuses a kind the records do not hold;
:data:`LINKS` is the line link each G-code family speaks.
"""

from firmware_protocol.kinds import UnknownKind, gcode_kinds, kind_of

from ..errors import BadInput
from .grbl import GrblLink
from .marlin import MarlinLink

__all__ = ["LINKS", "machine_kind", "gcode_link"]

#: The G-code families -> the link that speaks each (character counting, or numbered lines).
LINKS = {"grbl": GrblLink, "marlin": MarlinLink}


def machine_kind(machine):
    """The :class:`~firmware_protocol.kinds.FirmwareKind` of ``machine``; BadInput for one the
    records do not hold."""
    try:
        return kind_of(machine)
    except UnknownKind as exc:
        raise BadInput(f"machine {machine.name!r}: {exc}") from None


def gcode_link(port, machine, **options):
    """The G-code link for ``machine``'s kind over an open ``port``."""
    kind = machine_kind(machine)
    if kind.family not in LINKS:
        raise BadInput(f"machine {machine.name!r} has controller.kind {machine['controller.kind']!r}; "
                       f"expected a G-code firmware (controller.dialect one of {', '.join(gcode_kinds())}) "
                       "for a G-code link")
    return LINKS[kind.family](port, kind.name, **options)
