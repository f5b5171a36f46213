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
    ``on_executed(step)`` for each one *only once the machine has executed it
    and reports standing where it was meant to* (G-code: its sync line
    answered, then ``?`` / ``M114`` compared with the plan after every move; a
    servo: its position read back).  A machine anywhere else raises
    ``MachineFailure``.  Returns when all are executed.
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
``stop_point() -> {"step_index", "move"[, "position"]}``
    The step not yet handed over and the move of it that was running, for the
    journal's stop record; no I/O.  A link that knows its last trusted
    ``position`` without asking the device adds it: a G-code link the
    position it measured at rest with nothing sent since (the held position
    after Ctrl-C, the reported one after a failed check), a servo link its
    last reading with torque on.  The stop record keeps it; a resume takes it
    as the truth after a reboot (see ``position_tolerance`` below).
``position_tolerance``
    Attribute ``(ring_deg, head_mm)``: how far ``position()`` may be from a
    planned point the machine arrived at (G-code: one step of each axis plus
    rounding; a servo: its arrival tolerance); the checks after every move and
    resume's search of the journal's path use it.
``on_move``
    Attribute: ``callable(step, move_index)`` set by the wind loop, called once a
    move has been executed (the journal records moves that leave the head OUT).
``position_lost``
    True once the device reset, lost power or alarmed: its position is not to
    be trusted.

For resume, a G-code link also offers ``reconnect() -> Reconnected`` (settle,
identify, unlock; what it learned: banner, alarm, machine position),
``restore_modal()``, ``move_to(ring, head, axis=)`` (one axis, verified),
``home(axes=None)``, ``jog(ring=, head=)`` and ``set_position(ring_deg,
head_mm)`` (declared, then read back); a servo link offers
``prepare(home=False, resume_at=(ring_deg, head_mm))`` (re-base the ring's turn
count from the journal) and returns the position read back.
``close()``; attributes ``info`` (FirmwareInfo), ``lines_sent`` (int).

The interface as a type: :class:`stringbot.links.contract.StepLink` (a ``typing.Protocol``; mypy
checks it, tests/test_types.py that every machine's link has each member).

Errors: ``MachineFailure`` naming the step and pin (steps numbered from 1),
never a bare port exception.

The rest
--------
:class:`Winder` is the loop (states :class:`WindState`), :mod:`.journal` the
append-only journal, :mod:`.session` a whole ``stringbot wind`` run and
:mod:`.resume` the ``--resume`` / ``--from-step`` / ``--status`` logic.
"""

from .journal import Journal, JournalState, journal_path_for, read_journal

# the loop and the session (the machine links, serial ports) are imported when first named: a command that
# reads a journal or a by-hand position only (`stringbot plan` checking its output) does not load them
_LATER = {"Progress": "loop", "Winder": "loop", "WindResult": "loop", "WindState": "loop", "step_seconds": "loop",
          "Job": "session", "dry_run_problem": "session", "load_job": "session", "wind_plan": "session"}


def __getattr__(name):
    if name in _LATER:
        import importlib

        return getattr(importlib.import_module(f".{_LATER[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["Winder", "WindState", "WindResult", "Progress", "step_seconds", "Journal",
           "JournalState", "read_journal", "journal_path_for", "Job", "load_job", "wind_plan",
           "dry_run_problem"]
