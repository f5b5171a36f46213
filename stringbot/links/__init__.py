"""Links: moves -> bytes on a port (pyserial, dynamixel-sdk); the only code that opens ports.

``open_port(url)`` opens a port (one clear line when it cannot); a link takes
the open port object and speaks one firmware's protocol over it:

- :class:`GrblLink` (GRBL 1.1, grblHAL, FluidNC): character counting against the
  receive buffer, ``G4 P0`` syncs, ``?`` status, ``!`` feed hold.
- :class:`MarlinLink`: line numbers, checksums, resends, ``M400`` syncs.

The wind loop (``stringbot.winding``) drives any link through the interface
documented there; :func:`gcode_link` picks the G-code link for a machine.
"""

from ..errors import BadInput
from .base import FirmwareInfo, LinkState, Status, Where, strip_comment
from .grbl import GrblLink, parse_status
from .marlin import MarlinLink
from .kinds import gcode_link, machine_kind
from .job import GcodeMachineLink, gcode_machine_link
from .ports import open_port, sim_url

__all__ = ["open_port", "sim_url", "gcode_link", "open_link", "GcodeMachineLink", "gcode_machine_link", "GrblLink",
           "MarlinLink", "LinkState", "FirmwareInfo", "Status", "Where", "strip_comment", "parse_status",
           "machine_kind"]


def open_link(url, machine, **options):
    """Open ``url`` and return the step-level link for ``machine`` (see ``stringbot.winding``).

    G-code machines get a :class:`GcodeMachineLink`; a ``kind = "dynamixel"``
    machine gets the servo link of ``stringbot.links.dynamixel`` when present.
    """
    if not machine_kind(machine).gcode:
        try:
            from . import dynamixel
        except ImportError as exc:
            raise BadInput(f"machine {machine.name!r} is a Dynamixel machine, but the Dynamixel link cannot "
                           f"be loaded ({exc}); expected the dynamixel-sdk package (pip install "
                           "dynamixel-sdk)") from None
        return dynamixel.open_dynamixel_link(url, machine, **options)
    port = open_port(url, baudrate=machine["controller.baud"])
    try:
        return gcode_machine_link(port, machine, **options)
    except BaseException:
        port.close()
        raise
