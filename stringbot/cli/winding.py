"""Winding commands: wind, simulate."""

import sys

import click

from ..errors import BadInput, Interrupted, MachineFailure
from . import cli


def _resume_command(plan, machine_name, port, journal):
    import shlex
    parts = ["stringbot", "wind", plan, "--machine", machine_name]
    if port:
        parts += ["--port", port]
    if journal:
        parts += ["--journal", journal]
    return " ".join(shlex.quote(p) for p in parts + ["--resume"])


@cli.command()
@click.argument("plan", type=click.Path(dir_okay=True))
@click.option("--machine", "machine_name", required=True, help="Machine name (bundled) or machine file path.")
@click.option("--port", default=None, help="Serial port or URL (/dev/ttyUSB0, COM3, socket://h:p, sim://...); "
              "default: the simulated machine.")
@click.option("--record", default=None, type=click.Path(dir_okay=False),
              help="Dry run: write the simulated world's record (wraps, collisions) to this file.")
@click.option("--journal", default=None, type=click.Path(dir_okay=False),
              help="Journal file (default: beside the plan, PLAN.journal; dry runs PLAN.dry-run.journal).")
@click.option("--yes", "-y", is_flag=True, help="Do not ask the operator anything.")
@click.option("--resume", is_flag=True, help="Continue an interrupted winding from its journal.")
@click.option("--from-step", type=click.IntRange(min=1), default=None,
              help="Restart from step N (numbered from 1) after fixing something by hand.")
@click.option("--head-side", type=click.Choice(["in", "out"]), default=None,
              help="On resume, where the thread head is when the journal cannot know.")
@click.option("--status", "show_status", is_flag=True,
              help="Show the journal's state and exit (without --port: the real winding's journal if any).")
@click.option("--faults", default=None, help="Dry run: faults for the simulated machine (kind@N,...).")
@click.option("--realtime", is_flag=True, help="Dry run: the simulated machine moves at real speed.")
def wind(plan, machine_name, port, record, journal, yes, resume, from_step, head_side, show_status,
         faults, realtime):
    """Wind PLAN on a machine (no --port: a dry run on the simulated machine)."""
    from ..winding import dry_run_problem, load_job, wind_plan
    from ..winding import resume as resuming

    if show_status and port is None and journal is None:
        from ..winding.journal import journal_path_for

        real = journal_path_for(plan)  # the machine's winding, not a dry run, is what --status is for
        if real.exists():
            journal = str(real)
    job = load_job(plan, machine_name, port=port, record=record, journal=journal,
                   realtime=realtime, faults=faults)
    if show_status:
        for line in resuming.status_lines(job):
            click.echo(line)
        return
    again = _resume_command(plan, machine_name, port, journal)

    def confirm(question):
        return click.confirm(question, default=True, err=True)

    bar = None
    state = {"last": 0}

    def progress(p):
        nonlocal bar
        if bar is None:
            bar = click.progressbar(length=p.total, label="winding", show_eta=False, show_pos=True,
                                    item_show_func=lambda _x: state.get("text"), file=sys.stderr)
            bar.__enter__()
            bar.update(p.done - 1)
            state["last"] = p.done - 1
        eta = _fmt_s(p.eta_s) if p.eta_s is not None else "?"
        state["text"] = f"pin {p.pin}  ETA {eta}  (machine time left {_fmt_s(p.machine_s)})"
        bar.update(p.done - state["last"])
        state["last"] = p.done

    try:
        if resume or from_step is not None:
            def choose(question, choices):
                return click.prompt(question, type=click.Choice(choices), err=True)
            result = resuming.resume_plan(job, from_step=from_step, head_side=head_side,
                                          confirm=None if yes else confirm,
                                          choose=None if yes else choose, progress=progress)
        else:
            result = wind_plan(job, confirm=None if yes else confirm, progress=progress)
    except (Interrupted, MachineFailure) as exc:
        if bar is not None:
            bar.__exit__(None, None, None)
        if port is None:
            raise  # a dry run cannot be resumed (its simulated machine ends with the command)
        raise type(exc)(f"{exc}; resume with: {again}") from None
    if bar is not None:
        bar.__exit__(None, None, None)
    problem = dry_run_problem(job)
    if problem:
        raise MachineFailure(problem)
    wound = result.steps_done - (result.first_step - 1)
    click.echo(f"wound {wound} pins (steps {result.first_step}-{result.steps_done} of {result.total}) "
               f"in {_fmt_s(result.wall_s)} ({result.pins_per_second:.1f} pins/s); "
               f"model machine time {_fmt_s(result.machine_s)}; firmware {result.firmware}; "
               f"{result.lines_sent} lines sent; journal {result.journal}")


def _fmt_s(seconds):
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"

# == simulate command ==


@cli.command("simulate")
@click.option("--machine", "machine_name", default="grbl-ring", show_default=True,
              help="Machine name (bundled) or machine file path: its dialect picks the firmware.")
@click.option("--pty", "pty_path", required=True, type=click.Path(dir_okay=False),
              help="Path of the symlink to the pseudo-terminal; open it as a serial port.")
@click.option("--record", default=None, type=click.Path(dir_okay=False),
              help="Write the world's record (wraps, collisions) to this JSON file.")
@click.option("--realtime", is_flag=True, help="Move at real speed (default: as fast as possible).")
@click.option("--faults", default=None, help="Faults to inject, a comma list: kind@N (as line N arrives), "
                                             "kind@N+F (F of line N's move done), kind@t=SECONDS, kind@N..M; "
                                             "kinds reset, reboot, power, disconnect, garble, drop-ok, error, "
                                             "ignore (docs/simulator.md).")
def simulate(machine_name, pty_path, record, realtime, faults):
    """Serve the simulated machine on a pseudo-terminal until Ctrl-C."""
    from firmware_protocol.emulators.factory import build_emulator
    from firmware_protocol.machine import load_machine
    from firmware_protocol.pty import PtyPathError, PtyServer, check_pty_path
    machine = load_machine(machine_name)
    try:
        check_pty_path(pty_path)            # before the record file is written
    except PtyPathError as exc:
        raise BadInput(f"--pty: {exc}") from None
    try:
        emulator, _world = build_emulator(machine, record=record, faults=faults)
    except ValueError as exc:
        raise BadInput(f"--faults {faults!r}: {exc}") from None
    except OSError as exc:
        raise BadInput(f"--record {record!r}: {exc.strerror or exc}") from None
    import signal
    import threading

    def terminate(signum, frame):
        raise SystemExit(128 + signum)      # unwinds through the finally below: the symlink goes

    server = PtyServer(emulator, pty_path, realtime=realtime)
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, terminate) if in_main else None
    try:
        try:
            server.start()
        except PtyPathError as exc:
            raise BadInput(f"--pty: {exc}") from None
        except OSError as exc:
            raise BadInput(f"--pty {pty_path!r}: {exc.strerror or exc}; expected a path in a writable "
                           "folder") from None
        click.echo(f"simulating {machine.name} on {pty_path} (-> {server.slave_name}); Ctrl-C to stop")
        try:
            server.serve()
        except PtyPathError as exc:     # a file was put at the path while the port was down
            raise BadInput(f"--pty: {exc}") from None
    finally:
        server.close()
        if in_main:
            signal.signal(signal.SIGTERM, previous)
