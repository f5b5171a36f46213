"""Simulated FluidNC: GRBL's protocol as FluidNC speaks it (an ESP32 firmware, often over telnet).

From FluidNC's own sources (``Report.cpp``, ``SettingsDefinitions.cpp``):

* the start message ``Grbl \\V [FluidNC \\B (\\R) \\H]``, i.e.
  ``Grbl 3.7 [FluidNC v3.7.8 (noradio) '$' for help]``, after the ``[MSG:INFO: ...]``
  log lines of its boot;
* ``$I``: ``[VER:3.7 FluidNC v3.7.8:]``, ``[OPT:PHSEW]`` (no buffer sizes: "included for
  backwards compatibility"), ``[MSG:Machine: NAME]``, ``ok``;
* status reports in GRBL 1.1's form with ``$10`` (``Report/Status``) = 1 by default:
  ``<Idle|MPos:0.000,0.000,0.000,0.000|FS:0,0>`` plus the periodic ``WCO:`` and ``Ov:``;
  rotary A, B, C axes in degrees.

Everything else (ok/error per line, realtime bytes, alarms, homing, the planner)
is the GRBL emulator's.
"""

from .gcode_base import Power
from .grbl import GrblEmulator
from .grbl_system import Variant

__all__ = ["FluidNcEmulator", "FLUIDNC", "FLUIDNC_VERSION", "FLUIDNC_BANNER"]

FLUIDNC_VERSION = "v3.7.8"
GRBL_VERSION = "3.7"
FLUIDNC_BANNER = f"Grbl {GRBL_VERSION} [FluidNC {FLUIDNC_VERSION} (noradio) '$' for help]"


class _FluidNcVariant(Variant):
    def build_info(self, axes, user_string):
        return [f"[VER:{GRBL_VERSION} FluidNC {FLUIDNC_VERSION}:{user_string}]", f"[OPT:{self.options}]",
                f"[MSG:Machine: {self.machine_name}]"]


FLUIDNC = _FluidNcVariant("fluidnc", FLUIDNC_BANNER, GRBL_VERSION, "", 128, 16, "XYZ", 1, "PHSEW")
FLUIDNC.machine_name = "stringbot simulator"


class FluidNcEmulator(GrblEmulator):
    """FluidNC: its boot log and start message, its ``$I``; GRBL's protocol otherwise."""

    variant = FLUIDNC

    def _emit_banner(self):
        if self.power is Power.ON and self.port_up:
            self._out += (f"\r\n[MSG:INFO: FluidNC {FLUIDNC_VERSION} https://github.com/bdring/FluidNC]\r\n"
                          f"[MSG:INFO: Machine {self.machine.name}]\r\n").encode("ascii")
        super()._emit_banner()
