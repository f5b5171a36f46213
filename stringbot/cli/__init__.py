"""The ``stringbot`` command: parses, builds objects, calls the layers.

The only package that talks to the terminal; each area's commands live in a
module of their own (planning, machines, winding) and register on :data:`cli`.  Errors become one line and an
exit code: :class:`~stringbot.errors.BadInput` and bad options -> 2,
:class:`~stringbot.errors.MachineFailure` -> 1, a stop for a spool change
(:class:`~stringbot.errors.SpoolChange`) -> 3, Ctrl-C -> 130.
"""

import logging
import os
import sys

import click

# The planner's linear algebra is small: one BLAS thread.  More only spin between calls, taking the
# second core from the polish's twin process (stringbot.planner.methods.woven_helper).  A setting of the
# user's own wins; numpy is not imported yet here.
if not any(os.environ.get(v) for v in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")):
    os.environ["OPENBLAS_NUM_THREADS"] = "1"

from .. import __version__
from ..errors import BadInput, Interrupted, MachineFailure, SpoolChange

log = logging.getLogger("stringbot")


def _bad_input_types():
    from firmware_protocol.machine import MachineFileError
    return (BadInput, MachineFileError)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="stringbot")
@click.option("-v", "--verbose", count=True, help="More log output (-vv for debug).")
def cli(verbose):
    """Plan a thread painting from a picture and wind it on a string-art machine.

    Each command has its own --help with its options and examples.
    """
    level = logging.WARNING - 10 * min(verbose, 2)
    root = logging.getLogger()
    if not root.handlers:  # (a host that set up logging, e.g. a test runner, keeps its own)
        handler = logging.StreamHandler(sys.stderr)
        # a user sees a library's warning as one line of the command; -v shows where it came from
        handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s") if verbose
                             else _UserFormatter())
        root.addHandler(handler)
        root.setLevel(level)


class _UserFormatter(logging.Formatter):
    """``warning: MESSAGE`` (the level in lower case, no logger name): a log line as a command's line."""

    def format(self, record):
        return f"{record.levelname.lower()}: {record.getMessage()}"


def fail(message, code=2):
    """Print one error line and exit with ``code``."""
    click.echo(f"stringbot: error: {message}", err=True)
    sys.exit(code)


def main(argv=None):
    """Entry point: run the command group, turning every failure into one line and an exit code."""
    try:
        cli.main(args=argv, prog_name="stringbot", standalone_mode=False)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except click.Abort:
        click.echo("stringbot: stopped", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        # usage errors: one line, naming the option and what was expected
        fail(exc.format_message(), exc.exit_code if exc.exit_code else 2)
    except _bad_input_types() as exc:
        fail(str(exc), 2)
    except MachineFailure as exc:
        fail(str(exc), 1)
    except SpoolChange as exc:      # not an error: the winding waits for a person
        click.echo(f"stringbot: {exc}", err=True)
        sys.exit(SpoolChange.exit_code)
    except Interrupted as exc:
        fail(str(exc), 130)
    except KeyboardInterrupt:
        click.echo("stringbot: interrupted", err=True)
        sys.exit(130)
    sys.exit(0)


# each area's commands register themselves on `cli` when imported
from . import machines, planning, winding  # noqa: E402,F401
from . import maker  # noqa: E402,F401  (template, pins, animate)
from . import by_hand  # noqa: E402,F401  (by-hand)
from . import checking  # noqa: E402,F401  (machines check)
from . import calibrate  # noqa: E402,F401  (calibrate sheet, calibrate fit)
from . import serve  # noqa: E402,F401  (the workshop page)
from . import examples  # noqa: E402,F401  (each command's examples, at the foot of its --help)
