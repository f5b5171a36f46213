"""Motion: plan + machine -> hooking moves -> G-code (pure; no I/O).

``hook_steps`` applies docs/design.md's physical model of hooking a pin (see
:mod:`stringbot.motion.hooking` for the wrap-direction rule), ``dialect_for``
and ``gcode_job`` write G-code for GRBL, grblHAL, FluidNC and Marlin, and ``estimate``
gives machine time, ring travel and thread length.
"""

from .estimate import Estimate, estimate, format_duration, move_seconds
from .gcode import GcodeDialect, dialect_for, gcode_job
from .hooking import HookStep, Move, check_plan_fits, hook_steps, wrap_direction

__all__ = ["hook_steps", "HookStep", "Move", "estimate", "Estimate", "gcode_job", "dialect_for",
           "GcodeDialect", "wrap_direction", "check_plan_fits", "move_seconds", "format_duration"]
