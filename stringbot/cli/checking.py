"""``machines check``: do the firmware's settings agree with the machine file?  And the lines
``wind`` prints when they do not."""

import shlex
import sys
from pathlib import Path

import click

from .machines import machines_cmd

__all__ = ["machines_check_cmd", "check_command", "report_lines", "refusal_lines"]


def _sim_ref(machine):
    """The simulator's ``machine=`` for ``machine``: its file's absolute path, else its name."""
    path = Path(machine.path) if machine.path else None
    return str(path.resolve()) if path is not None and path.is_file() else machine.name


def check_command(machine_name, port, *extra):
    """The command line that checks (``extra``: e.g. ``--apply``) the same machine on the same port."""
    parts = ["stringbot", "machines", "check", machine_name] + (["--port", port] if port else [])
    return " ".join(shlex.quote(p) for p in parts + list(extra))


def report_lines(report):
    """The table: setting, firmware value, what the machine file needs, verdict."""
    head = ("setting", "firmware", "machine file needs", "verdict")
    rows = [(r.setting, r.firmware, r.needs, r.verdict.value) for r in report.rows]
    widths = [max(len(x[i]) for x in [head] + rows) for i in range(3)]
    fmt = "{:<%d}  {:<%d}  {:<%d}  {}" % tuple(widths)
    return [fmt.format(*head)] + [fmt.format(*row) for row in rows]


def refusal_lines(exc, machine_name, port):
    """What ``wind`` says when the settings disagree: one line per disagreement, then what to do."""
    return list(exc.lines) + [
        "not winding: nothing was moved or wound; fix the firmware with `"
        + check_command(machine_name, port, "--apply") + "`, or wind anyway with --no-check"]


@machines_cmd.command("check")
@click.argument("name")
@click.option("--port", default=None, help="Serial port or URL of the machine (/dev/ttyUSB0, COM3, "
              "socket://h:p, sim://...); default: the simulated machine.")
@click.option("--apply", "apply_fixes_", is_flag=True,
              help="Send the lines that fix what disagrees (asks first; GRBL stores them in EEPROM).")
@click.option("--yes", "-y", is_flag=True, help="With --apply: send without asking.")
def machines_check_cmd(name, port, apply_fixes_, yes):
    """Compare the firmware's settings on PORT with machine NAME (a bundled name or a .toml path).

    Prints a table (setting, firmware value, what the machine file needs, verdict).  Exit 0 when
    all agree; 1 when the machine disagrees, with the exact lines that fix it (sent only with
    --apply); 2 for a bad machine name or port.
    """
    from firmware_protocol.machine import load_machine

    from ..links import open_link, sim_url
    from ..links.settings_check import PERSISTENCE, apply_fixes, check_link

    machine = load_machine(name)
    url = port if port is not None else sim_url(_sim_ref(machine))
    link = open_link(url, machine)
    try:
        report = check_link(link, machine)
        click.echo(f"machine {machine.name} ({machine.path}) against {report.firmware or 'the firmware'} "
                   f"on {port or 'the simulated machine'}")
        for line in report_lines(report):
            click.echo(line)
        if report.agrees:
            click.echo(_agree_line(report))
            return
        fixes = report.fixes
        _explain(report, fixes)
        if fixes:
            later = "" if apply_fixes_ else f" (or run `{check_command(name, port, '--apply')}`)"
            click.echo(f"to fix, send these lines{later}:")
            for line in fixes:
                click.echo(f"  {line}")
        if not apply_fixes_:
            _fail(f"{len(report.disagreements)} setting(s) of the firmware disagree with machine file "
                  f"{machine.name}")
        if not fixes:
            _fail("nothing to send: what disagrees is fixed in the machine file or the build (see above)")
        click.echo(f"{PERSISTENCE[report.kind]}.")
        if not yes and not _confirm(f"Send these {len(fixes)} line(s) to the machine?"):
            _fail("nothing was sent")
        apply_fixes(link, machine, fixes)
        after = check_link(link, machine, fresh=True)
        click.echo(f"sent {len(fixes)} line(s); the firmware now reports:")
        for line in report_lines(after):
            click.echo(line)
        if not after.agrees:
            _explain(after, after.fixes)
            _fail(f"{len(after.disagreements)} setting(s) still disagree after the fixes")
        click.echo(_agree_line(after))
    finally:
        link.close()


def _confirm(question):
    """The operator's yes; standard input that ended (no terminal) is bad input, not exit 130."""
    from ..errors import BadInput

    try:
        return click.confirm(question, default=False, err=True)
    except click.Abort as exc:
        if isinstance(exc.__context__, EOFError):
            click.echo("", err=True)
            raise BadInput("--apply asks before sending, but standard input ended (not a terminal); "
                           "nothing was sent: run in a terminal, or add --yes") from None
        raise


def _agree_line(report):
    """"all N settings agree", naming what was not checked (the machine file does not say)."""
    from ..links.settings_rules import Verdict

    unchecked = [r.setting for r in report.rows if r.verdict is Verdict.UNCHECKED]
    if not unchecked:
        return f"all {len(report.rows)} settings agree with the machine file"
    return (f"{len(report.rows) - len(unchecked)} of {len(report.rows)} settings agree with the machine file; "
            f"not checked (the machine file does not say): {', '.join(unchecked)}")


def _explain(report, fixes):
    for row in report.disagreements:
        if row.hint:
            click.echo(f"{row.setting}: {row.hint}")
    for note in report.notes:
        click.echo(note)


def _fail(message):
    click.echo(f"stringbot: error: {message}", err=True)
    sys.exit(1)

