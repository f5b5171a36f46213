"""Exceptions that the command line turns into exit codes.

Every layer raises these (or a subclass); the ``stringbot.cli`` package prints their message as
one line and exits with the code named here.  Any layer may import this module.
"""

__all__ = ["BadInput", "MachineFailure", "Interrupted", "SpoolChange"]


class BadInput(ValueError):
    """The user gave us something wrong: a file, an option, a definition.  Exit 2.

    The message names what is wrong and the expected form, in one line.
    """

    exit_code = 2


class MachineFailure(RuntimeError):
    """The machine or the link to it failed.  Exit 1; the journal says where to resume.

    Parameters
    ----------
    message : str
        What happened, in one line.
    step : int, optional
        Index in the plan's sequence of the step that was running.
    pin : int, optional
        The pin of that step.
    """

    exit_code = 1

    def __init__(self, message, *, step=None, pin=None):
        where = []
        if pin is not None:
            where.append(f"pin {pin}")
        if step is not None:
            where.append(f"step {step}")
        super().__init__(f"{message} (at {', '.join(where)})" if where else message)
        self.step = step
        self.pin = pin


class Interrupted(RuntimeError):
    """The user stopped the job (Ctrl-C); the machine is stopped.  Exit 130."""

    exit_code = 130


class SpoolChange(Interrupted):
    """A colour plan's winding stopped at a spool change for a person to make it (``--yes`` on a
    port: nobody to ask).  Exit 3.

    The machine has executed every step before and holds with the head IN; the journal has the
    stop.  The message says which thread to cut and which to tie on at which pin; the command
    line adds the resume command.

    Parameters
    ----------
    message : str
    layer : int
        The layer (from 0) whose thread is to be tied on.
    """

    exit_code = 3
    reason = "spool change"

    def __init__(self, message, *, layer):
        super().__init__(message)
        self.layer = layer
