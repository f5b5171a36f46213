"""The step-level link: what the wind loop (``stringbot.winding``) needs of a link, as a type.

:class:`StepLink` is a :class:`typing.Protocol`: any object with these methods and attributes is
one (the G-code :class:`~stringbot.links.job.GcodeMachineLink`, the servo
:class:`~stringbot.links.dynamixel.DynamixelLink`); nothing inherits from it.  The meaning of
each member is written in ``stringbot/winding/__init__.py``; mypy checks this module (and the
records and dataclasses the layers hand each other) in ``tests/test_types.py``, and the test
checks that both links have every member.
"""

from typing import Any, Callable, Iterable, Protocol, runtime_checkable

from ..motion.hooking import HookStep
from .base import FirmwareInfo, Status

__all__ = ["StepLink", "OnExecuted", "StopPoint", "Position"]

#: Called with each step once the machine has executed it.
OnExecuted = Callable[[HookStep], None]
#: ``(ring_deg, head_mm)`` in the job's coordinates.
Position = tuple[float, float]
#: ``{"step_index": int, "move": int | None[, "position": Position]}`` for the journal's stop record.
StopPoint = dict[str, Any]


@runtime_checkable
class StepLink(Protocol):
    """A machine as the wind loop drives it, step by step (see the module notes)."""

    info: FirmwareInfo | None
    lines_sent: int
    position_lost: bool
    position_tolerance: tuple[float, float]
    on_move: Callable[[HookStep, int], None] | None

    def identify(self) -> FirmwareInfo:
        """Find out what answers; MachineFailure when it is not what the machine file says."""
        ...

    def prepare(self, *, home: bool = False) -> Any:
        """Check for alarms, home if asked, set the modal state."""
        ...

    def execute(self, steps: Iterable[HookStep], on_executed: OnExecuted | None = None) -> None:
        """Run ``steps``; ``on_executed(step)`` once each is executed where it was meant to be."""
        ...

    def finish(self) -> None:
        """End the job cleanly; return once the machine is done."""
        ...

    def hold(self) -> Status:
        """Stop motion now, in a controlled way; return once the machine stands still."""
        ...

    def take_executed(self) -> list[HookStep]:
        """The steps confirmed executed that ``on_executed`` was not yet given."""
        ...

    def position(self) -> Position | None:
        """Where the machine believes it is (None: lost)."""
        ...

    def stop_point(self) -> StopPoint:
        """The step not yet handed over and the move of it that ran (no I/O)."""
        ...

    def close(self) -> None:
        """Let go of the port."""
        ...
