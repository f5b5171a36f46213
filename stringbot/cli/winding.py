"""Winding commands: wind, simulate."""

import sys

import click
from firmware_protocol.faults import FAULT_KINDS, FAULTS_HELP
from firmware_protocol.kinds import KINDS

from ..errors import BadInput, Interrupted, MachineFailure, SpoolChange
from . import cli
from .progress import fmt_s as _fmt_s


def _resume_command(plan, machine_name, port, journal, *extra):
    import shlex
    parts = ["stringbot", "wind", plan] + (["--machine", machine_name] if machine_name else [])
    if port:
        parts += ["--port", port]
    if journal:
        parts += ["--journal", journal]
    return " ".join(shlex.quote(p) for p in parts + ["--resume", *extra])


@cli.command()
@click.argument("plan", type=click.Path(dir_okay=True))
@click.option("--machine", "machine_name", default=None,
              help="Machine name (bundled) or machine file path [default: the plan's, from plan --machine].")
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
              help="Where the thread head is when the host cannot know (on --resume or --from-step; before "
                   "homing a machine whose firmware cannot say): fully IN or fully OUT (part way: run "
                   "without --yes to be guided).")
@click.option("--status", "show_status", is_flag=True,
              help="Show the journal's state and exit (without --port: the real winding's journal if any).")
@click.option("--faults", default=None, help="Dry run: faults for the simulated machine (kind@N,...; kinds "
              + ", ".join(FAULT_KINDS) + ": see stringbot simulate --help).")
@click.option("--realtime", is_flag=True, help="Dry run: the simulated machine moves at real speed.")
@click.option("--progress-every", type=click.FloatRange(min=0.1), default=None, metavar="SECONDS",
              help="Print a progress line (step, pin, elapsed, ETA) this often instead of the bar "
                   "[default: the bar on a terminal, otherwise a line every 30 s].")
@click.option("--no-check", "no_check", is_flag=True,
              help="Do not compare the firmware's settings with the machine file before the first move.")
@click.option("--spool-change", "spool_change", type=click.Choice(["ask", "stop", "continue"]), default=None,
              help="A colour plan's spool changes: ask (type the colour; the default at a terminal), stop "
                   "(exit 3 with what to tie on and the resume command; the default of --yes on a port), "
                   "continue (a machine that changes thread itself; the default of a dry run).")
@click.option("--force", is_flag=True,
              help="Wind a plan made for another thread-to-diameter ratio than the machine's (the piece then "
                   "comes out darker or lighter than its preview).")
@click.option("--questions", type=click.Choice(["terminal", "json"]), default="terminal", show_default=True,
              help="Where the operator is asked: at the terminal, or as JSON lines (questions and progress on "
                   "standard output, answers on standard input; for a front end such as stringbot serve: "
                   "standard input's end stops the winding as Ctrl-C does).")
def wind(plan, machine_name, port, record, journal, yes, resume, from_step, head_side, show_status,
         faults, realtime, progress_every, no_check, spool_change, force, questions):
    """Wind PLAN on a machine (no --port: a dry run on the simulated machine)."""
    from ..winding import Job, dry_run_problem, wind_plan
    from ..winding import resume as resuming
    from ..winding.operator import Operator
    from ..winding.session import UnfinishedJournal, moved
    from .plan_machine import check_thread, machine_for

    if show_status and port is None and journal is None:
        from ..winding.journal import journal_path_for

        real = journal_path_for(plan)  # the machine's winding, not a dry run, is what --status is for
        if real.exists():
            journal = str(real)
    job = Job(plan, machine_for(plan, machine_name), port=port, record=record, journal=journal,
              realtime=realtime, faults=faults)
    if not (force or show_status):      # --status only reads the journal
        check_thread(job.plan, plan, job.machine)
    if show_status:
        for line in resuming.status_lines(job):
            click.echo(line)
        return
    homes = job.machine["controller.homing"] or bool(job.machine.values.get("controller.head_homing"))
    if head_side is not None and not resume and from_step is None and not homes:
        raise BadInput("--head-side says where the thread head is when the host cannot know; it goes "
                       "with --resume or --from-step (or a start that homes), so leave it out here")
    if resume and from_step is not None:
        raise BadInput("--resume continues where the winding stopped, --from-step N restarts at step N; "
                       "give one of them, not both")
    from .colour import simulated_hands, spool_change_mode
    spool_change = spool_change_mode(spool_change, yes=yes, dry_run=job.dry_run)
    again = _resume_command(plan, machine_name, port, journal, *(["--force"] if force else []))
    if questions == "json" and (yes or progress_every is not None):
        raise BadInput("--questions json asks a front end and shows no progress line; leave out --yes and "
                       "--progress-every with it")
    ask = _Asking()
    if questions == "json":
        from .questions import JsonQuestions
        ask = JsonQuestions()
    threads = dict(spool_change=spool_change, ask_thread=None if yes else ask.thread, hands=simulated_hands(job))
    eyes = _simulated_eyes(job)
    if not job.plan.is_mono and yes and not resume and from_step is None:
        from .colour import first_thread_line
        click.echo(first_thread_line(job.plan, spool_change or ("continue" if job.dry_run else "stop")),
                   err=True)

    # the settings check is imported here, not at the top: `stringbot plan` does not need it
    from ..links.settings_check import SettingsDisagree
    from .progress import WindProgress

    progress = ask if questions == "json" else WindProgress(every=progress_every).start()
    try:
        if resume or from_step is not None:
            result = resuming.resume_plan(job, from_step=from_step, head_side=head_side,
                                          confirm=None if yes else ask.confirm,
                                          choose=None if yes else ask.choose,
                                          jog=None if yes else ask.jog,
                                          say=None if yes else ask.say, progress=progress,
                                          check=not no_check, eyes=eyes, **threads)
        else:
            operator = Operator(head_side=head_side, confirm=None if yes else ask.confirm,
                                choose=None if yes else ask.choose, jog=None if yes else ask.jog,
                                say=None if yes else ask.say, look=eyes)
            result = wind_plan(job, confirm=operator.confirm, progress=progress, check=not no_check,
                               operator=operator, **threads)
    except UnfinishedJournal as exc:
        raise BadInput(f"{exc}: {again}") from None
    except SettingsDisagree as exc:     # nothing moved: no resume to offer
        from .checking import refusal_lines
        for line in refusal_lines(exc, machine_name or job.plan.parameters.get("machine"), port):
            click.echo(f"stringbot: error: {line}", err=True)
        sys.exit(1)
    except SpoolChange as exc:          # the machine holds with the head in, the journal has the stop
        extra = [*(["--yes"] if yes else []), *(["--spool-change", spool_change] if spool_change else []),
                 *(["--force"] if force else [])]
        raise SpoolChange(f"{exc}; then resume with: {_resume_command(plan, machine_name, port, journal, *extra)}",
                          layer=exc.layer) from None
    except (Interrupted, MachineFailure) as exc:
        if port is None:         # a dry run cannot be resumed (its simulated machine ends with the command)
            raise type(exc)(f"{exc}; a dry run cannot be resumed: run it again to wind from step 1 (to rehearse "
                            "resuming, wind on `stringbot simulate --pty PATH` with --port PATH)") from None
        if not moved(job):
            # nothing moved: a new start finds the machine as this one did
            raise type(exc)(f"{exc}; nothing was wound yet (nothing moved): once that is fixed, run the "
                            "same command again") from None
        # something moved: only --resume knows where the machine may be now (a new start would
        # trust a position the stop may have wiped)
        raise type(exc)(f"{exc}; resume with: {again}") from None
    finally:
        progress.close()
    problem = dry_run_problem(job)
    if problem:
        raise MachineFailure(problem)
    click.echo(_summary(result, job.machine))


def _simulated_eyes(job):
    """A dry run's simulated operator, who looks at the machine when the host must ask where the
    head stands (before homing, where the firmware cannot say): the ``sim://`` world's physical
    ``(ring_deg, head_mm)``.  None on a port: a person looks."""
    if not job.dry_run:
        return None
    from firmware_protocol.urlhandler import protocol_sim

    url = str(job.url)
    return lambda: protocol_sim.look(url)


class _Asking:
    """The operator at the terminal; a question that meets the end of standard input (no
    terminal, nothing piped) is one line saying so, not a bare exit 130."""

    def _prompt(self, call):
        try:
            return call()
        except click.Abort as exc:
            if isinstance(exc.__context__, EOFError):
                click.echo("", err=True)          # end the question's line
                raise BadInput("a question needs an answer but standard input ended (not a terminal): "
                               "run in a terminal, or answer with --yes (and --head-side in|out after "
                               "looking at the machine, where it is asked: a resume, a start that homes)") from None
            raise

    def confirm(self, question):
        return self._prompt(lambda: click.confirm(question, default=True, err=True))

    def thread(self, question, color):
        """A spool change: the thread's colour typed (no default)."""
        from .colour import confirm_thread
        return confirm_thread(question, color, say=self.say, prompt=lambda text: self._prompt(
            lambda: click.prompt(text, default="", show_default=False, err=True)))

    def choose(self, question, choices):
        return self._prompt(lambda: click.prompt(question, type=click.Choice(choices), err=True))

    def jog(self, prompt):
        return self._prompt(lambda: click.prompt(prompt.rstrip("> "), default="", show_default=False,
                                                 prompt_suffix="> ", err=True))

    def say(self, text):
        click.echo(text, err=True)


def _summary(result, machine):
    """What this run wound (a step the resume finished included), in one line."""
    wound = max(0, result.steps_done - (result.first_step - 1))
    steps = (f"steps {result.first_step}-{result.steps_done} of {result.total}" if wound
             else f"all {result.total} steps were already done")
    sent = "commands" if machine["controller.kind"] == "dynamixel" else "lines"
    return (f"wound {wound} pins ({steps}) in {_fmt_s(result.wall_s)} ({result.pins_per_second:.1f} pins/s); "
            f"model machine time {_fmt_s(result.machine_s)}; firmware {result.firmware}; "
            f"{result.lines_sent} {sent} sent; journal {result.journal}")

# == simulate command ==


@cli.command("simulate")
@click.option("--machine", "machine_name", default="grbl-ring", show_default=True,
              help="Machine name (bundled) or machine file path: its dialect picks the firmware.")
@click.option("--pty", "pty_path", required=True, type=click.Path(dir_okay=False),
              help="Path of the symlink to the pseudo-terminal; open it as a serial port.")
@click.option("--record", default=None, type=click.Path(dir_okay=False),
              help="Write the world's record (wraps, collisions) to this JSON file.")
@click.option("--realtime", is_flag=True, help="Move at real speed (default: as fast as possible).")
@click.option("--faults", default=None, help=FAULTS_HELP)
@click.option("--set", "settings", multiple=True, metavar="SETTING",
              help="Start the firmware with this setting instead of the machine file's (repeatable), e.g. "
                   + ", ".join(f"'{k.set_example}' ({k.title})" for k in KINDS.values()) + ".")
@click.option("--tie-on", "tie_on", default=None, metavar="COLOUR",
              help="Do not serve: be the operator's hands at the simulator already serving on --pty, tying "
                   "a thread of COLOUR (a name or #rrggbb) on, then exit (a colour plan's spool change).")
@click.option("--pin", "tie_pin", type=click.IntRange(min=0), default=None, help="With --tie-on: at this pin.")
def simulate(machine_name, pty_path, record, realtime, faults, settings, tie_on, tie_pin):
    """Serve the simulated machine on a pseudo-terminal until Ctrl-C."""
    if tie_on is not None or tie_pin is not None:
        from .colour import tie_on_simulator
        return tie_on_simulator(pty_path, tie_on, tie_pin, serving=(record, realtime, faults, settings))
    from firmware_protocol.emulators.factory import build_emulator
    from firmware_protocol.machine import load_machine
    from firmware_protocol.pty import PtyPathError, PtyServer, check_pty_path
    machine = load_machine(machine_name)
    if record is not None:
        from .._files import check_ours, check_output_path
        check_output_path(record, what="--record")
        check_ours(record, "record", what="--record", instead="give a new file")
    try:
        check_pty_path(pty_path)            # before the record file is written
    except PtyPathError as exc:
        raise BadInput(f"--pty: {exc}") from None
    try:
        emulator, _world = build_emulator(machine, record=record, faults=faults, settings=settings)
    except ValueError as exc:
        if str(exc).startswith("--set "):
            raise BadInput(str(exc)) from None
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
