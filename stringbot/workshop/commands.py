"""The command lines the workshop runs: every action of the page is a ``stringbot`` command.

The page plans with ``stringbot plan``, checks with ``stringbot machines check``, winds and
resumes with ``stringbot wind`` (its operator asked through ``--questions json``), serves the
simulator with ``stringbot simulate --pty`` and ties a thread on there with ``simulate
--tie-on``: the same commands, in the plans folder, that a person types.  :class:`Command`
holds one, with what the page shows of it (without ``--questions json``: at a terminal, the
same questions are asked there).
"""

import enum
import re
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadInput

__all__ = ["Command", "Target", "CLI", "SIMULATOR_DIR", "PICTURES_DIR", "plan_command", "wind_command",
           "check_command", "simulate_command", "tie_on_command", "check_name", "journal_for", "record_for"]

#: How the workshop runs the command line: this Python, so the same installation.
CLI = (sys.executable, "-m", "stringbot.cli")
#: Inside the plans folder: the simulators' ptys and records, and the uploaded pictures.
SIMULATOR_DIR = "simulator"
PICTURES_DIR = "pictures"
_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]{0,99}$")


class Target(enum.Enum):
    """Where a winding goes."""

    SIMULATOR = "simulator"     # `stringbot simulate --pty`, served by the workshop: resumable
    DRY_RUN = "dry-run"         # no --port: a simulated machine that lives as long as the command
    PORT = "port"               # a real machine: a serial device or a URL


@dataclass(frozen=True)
class Command:
    """One ``stringbot`` command line, run in ``cwd`` (the plans folder)."""

    args: tuple
    cwd: Path
    hidden: tuple = ()          # options for the workshop's pipe, left out of what the page shows

    def argv(self):
        return [*CLI, *self.args, *self.hidden]

    def shown(self):
        """As typed in the plans folder."""
        return "stringbot " + shlex.join([str(a) for a in self.args])


def check_name(name, what="plan name"):
    """A plan's name (its file without ``.json``) or a picture's file name: letters, digits, ``_.-``."""
    name = str(name or "").strip()
    if not _NAME.match(name) or ".." in name:
        raise BadInput(f"{what} {name!r}; expected letters, digits, '_', '-' or '.' (not first), e.g. camera")
    return name


def _flag(value):
    return str(value).lower() in ("1", "on", "true", "yes")


def plan_command(folder, form, picture):
    """``stringbot plan`` for the page's plan form (a dict of strings) and a picture path inside
    ``folder``; the values go to the command line as they are, so it says what is wrong with them."""
    name = check_name(form.get("name") or Path(picture).stem)
    args = ["plan", str(picture), "-o", f"{name}.json"]
    for key, option in (("machine", "--machine"), ("pins", "--pins"), ("lines", "--lines"),
                        ("colors", "--colors"), ("background", "--background"),
                        ("spool_changes", "--spool-changes"), ("min_run", "--min-run")):
        value = str(form.get(key) or "").strip()
        if value:
            args += [option, value]
    face = str(form.get("face") or "off").strip()
    if face != "off":
        args += ["--face", face]
    if _flag(form.get("fit")):
        args.append("--fit")
    if _flag(form.get("force")):
        args.append("--force")
    return Command(tuple(args), Path(folder)), name


def journal_for(plan_name, target):
    """The journal of ``plan_name`` wound on ``target``, relative to the plans folder (a real
    machine's and a dry run's where the command line puts them; the workshop's simulator's apart)."""
    suffix = {Target.PORT: ".journal", Target.DRY_RUN: ".dry-run.journal",
              Target.SIMULATOR: ".simulator.journal"}[target]
    return f"{plan_name}.json{suffix}"


def record_for(plan_name, machine, target):
    """The simulated world's record of a winding, relative to the plans folder (None: a real machine)."""
    if target is Target.DRY_RUN:
        return f"{plan_name}.dry-run-record.json"
    if target is Target.SIMULATOR:
        return f"{SIMULATOR_DIR}/{machine}-record.json"
    return None


def pty_for(machine):
    return f"{SIMULATOR_DIR}/{machine}.pty"


def wind_command(folder, *, plan_name, machine, target, port=None, faults=None, realtime=False,
                 resume=False, check=True):
    """``stringbot wind`` for the page's wind form."""
    args = ["wind", f"{plan_name}.json", "--machine", machine]
    if target is Target.PORT:
        if not port:
            raise BadInput("port is empty; expected a serial device (e.g. /dev/ttyUSB0, COM3) or a URL "
                           "(socket://host:port), or choose the simulator")
        args += ["--port", str(port)]
    elif target is Target.SIMULATOR:
        args += ["--port", pty_for(machine), "--journal", journal_for(plan_name, target)]
    else:
        if not resume:
            args += ["--record", record_for(plan_name, machine, target)]
            if faults:
                args += ["--faults", str(faults)]
            if realtime:
                args.append("--realtime")
    if resume:
        args.append("--resume")
    if not check:
        args.append("--no-check")
    return Command(tuple(args), Path(folder), hidden=("--questions", "json"))


def check_command(folder, *, machine, target, port=None):
    """``stringbot machines check`` on the chosen target (the workshop's simulator when it serves one)."""
    args = ["machines", "check", machine]
    if target is Target.PORT:
        if not port:
            raise BadInput("port is empty; expected a serial device (e.g. /dev/ttyUSB0, COM3) or a URL "
                           "(socket://host:port), or choose the simulator")
        args += ["--port", str(port)]
    elif target is Target.SIMULATOR and port:
        args += ["--port", str(port)]
    return Command(tuple(args), Path(folder))


def simulate_command(folder, *, machine, faults=None, realtime=False):
    """``stringbot simulate --pty`` for the workshop's simulator of ``machine``."""
    args = ["simulate", "--machine", machine, "--pty", pty_for(machine),
            "--record", f"{SIMULATOR_DIR}/{machine}-record.json"]
    if faults:
        args += ["--faults", str(faults)]
    if realtime:
        args.append("--realtime")
    return Command(tuple(args), Path(folder))


def tie_on_command(folder, *, machine, color, pin):
    """The operator's hands at the workshop's simulator: a thread of ``color`` tied on at ``pin``."""
    return Command(("simulate", "--pty", pty_for(machine), "--tie-on", str(color), "--pin", str(int(pin))),
                   Path(folder))


def parse_target(text):
    try:
        return Target(str(text or "simulator"))
    except ValueError:
        raise BadInput(f"target {text!r}; expected one of " + ", ".join(t.value for t in Target)) from None
