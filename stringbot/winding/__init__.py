"""Winding: the wind loop, the journal, resume.

The link interface
------------------
The wind loop drives a machine through a *step-level link*; the G-code link
(:class:`stringbot.links.GcodeMachineLink`) is one, a servo link (e.g. a
``DynamixelLink`` in ``stringbot/links/dynamixel.py``, returned by its
``open_dynamixel_link(url, machine)``) is another.  A link offers:

``identify() -> FirmwareInfo``
    Talk to the device, find out what it is; raise ``MachineFailure`` for no
    answer, garbage, or a device that is not what the machine file says.
``prepare(*, home: bool) -> None``
    Check for alarms (refuse or clear them), home if ``home``, set modal state.
``execute(steps, on_executed) -> None``
    Run the motion steps (``stringbot.motion.HookStep``) in order; call
    ``on_executed(step)`` for each one *only once the machine has executed it*
    (G-code: its sync line answered; a servo: its position read back).  The
    link may keep later steps flowing meanwhile.  Returns when all are executed.
``execute_lines(step, lines, on_executed)``
    G-code links only: run ``lines`` as the rest of ``step`` (resume mid-step).
``finish() -> None``
    End the job cleanly and wait until the machine is done.
``hold() -> Status``
    Stop motion now, in a controlled way (feed hold, or goal = present
    position); return once the machine stands still.
``take_executed() -> list``
    The steps confirmed executed that ``on_executed`` has not yet been given
    (those confirmed while stopping).
``position() -> (ring_deg, head_mm) | None``
    Where the machine believes it is, in the job's coordinates (None: lost).
``home()``, ``set_position(ring_deg, head_mm)``, ``unlock()``, ``flush()``
    For resume: re-home; declare a known position; clear an alarm without
    moving; drop queued motion once stopped.
``close()``; attributes ``info`` (FirmwareInfo), ``lines_sent`` (int).

Errors: ``MachineFailure`` naming the step and pin (steps numbered from 1),
never a bare port exception.

The rest
--------
:class:`Winder` is the loop (states :class:`WindState`), :mod:`.journal` the
append-only journal, :mod:`.session` a whole ``stringbot wind`` run and
:mod:`.resume` the ``--resume`` / ``--from-step`` / ``--status`` logic.
"""

from .journal import Journal, JournalState, journal_path_for, read_journal
from .loop import Progress, Winder, WindResult, WindState, step_seconds
from .session import Job, load_job, wind_plan

__all__ = ["Winder", "WindState", "WindResult", "Progress", "step_seconds", "Journal",
           "JournalState", "read_journal", "journal_path_for", "Job", "load_job", "wind_plan"]
