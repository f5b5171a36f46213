"""The ``stringbot`` command: parses, builds objects, calls the layers.

The only module that talks to the terminal.  Errors become one line and an
exit code: :class:`~stringbot.errors.BadInput` and bad options -> 2,
:class:`~stringbot.errors.MachineFailure` -> 1, Ctrl-C -> 130.
"""

import logging
import sys

import click

from . import __version__
from .errors import BadInput, Interrupted, MachineFailure

log = logging.getLogger("stringbot")


def _bad_input_types():
    from firmware_protocol.machine import MachineFileError
    return (BadInput, MachineFileError)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="stringbot")
@click.option("-v", "--verbose", count=True, help="More log output (-vv for debug).")
def cli(verbose):
    """Plan a thread painting from a picture and wind it on a string-art machine."""
    level = logging.WARNING - 10 * min(verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)


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
    except Interrupted as exc:
        fail(str(exc), 130)
    except KeyboardInterrupt:
        click.echo("stringbot: interrupted", err=True)
        sys.exit(130)
    sys.exit(0)


# ---- commands -------------------------------------------------------------------------------
# Each area adds its commands below its own marker; keep each command thin.

# == planner commands (plan, render, score) ==
# Heavy modules (numpy, scipy, PIL) are imported inside the commands: startup counts.

class _Lines(click.ParamType):
    name = "N|auto"

    def convert(self, value, param, ctx):
        if isinstance(value, int) or str(value).strip().lower() == "auto":
            return value if isinstance(value, int) else "auto"
        try:
            return int(value)
        except ValueError:
            self.fail(f"{value!r} is not a whole number or 'auto'", param, ctx)


@cli.command("plan")
@click.argument("image", type=click.Path(dir_okay=True, path_type=str))
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=str),
              help="Plan file to write (JSON).")
@click.option("--preview", type=click.Path(path_type=str), default=None,
              help="Preview PNG to write [default: the plan's path with .png].")
@click.option("--method", type=click.Choice(["fitness", "greedy"]), default="fitness", show_default=True,
              help="fitness: the paper's method; greedy: the ThreadTone baseline.")
@click.option("--disconnected", is_flag=True, help="A chord set by priority queue (fitness only); cannot be wound.")
@click.option("--pins", type=int, default=None, help="Pins on the frame [default: 300, or the machine's].")
@click.option("--machine", default=None, help="Take the pin count from this machine (name or TOML path).")
@click.option("--frame", type=click.Choice(["circle", "square"]), default="circle", show_default=True)
@click.option("--crop", default=None, help="CX,CY,R in picture pixels [default: largest centred circle].")
@click.option("--start-pin", type=int, default=0, show_default=True)
@click.option("--size", type=int, default=401, show_default=True, help="Working size in pixels.")
@click.option("--lines", type=_Lines(), default="auto", show_default=True,
              help="Chords to draw; auto: 500 + 10 (255 - mean gray).")
@click.option("--importance", type=click.Path(path_type=str), default=None,
              help="Mask PNG of the picture's size: white = important (weight 2).")
@click.option("--gray", type=click.Choice(["decolor", "luminance"]), default="decolor", show_default=True,
              help="Colour to gray: contrast-preserving decolorization or plain luminance.")
@click.option("--alpha", type=float, default=0.0, show_default=True, help="Edge weight in b (0..1).")
@click.option("--style", type=click.Choice(["auto", "detail", "fill"]), default=None,
              help="Fitness knobs: detail (the paper's beta 5, gamma 10, T 30), fill (150, 300, 1: fills flat dark "
                   "areas), or auto: plan both, keep the higher SSIM [default: auto].")
@click.option("--beta", type=float, default=None, help="Short-chord penalty [detail: 5].")
@click.option("--gamma", type=float, default=None, help="Edge-direction penalty [detail: 10].")
@click.option("-T", "--sharpness", "T", type=float, default=None,
              help="T of tanh(f / T): larger spreads chords out [detail: 30].")
@click.option("--epsilon", type=int, default=2, show_default=True, help="Error-diffusion radius in pins.")
@click.option("--iterations", type=int, default=25, show_default=True, help="Iteration limit of the least-squares solve (LSQR).")
@click.option("--no-cache", is_flag=True, help="Do not read or write the chord cache.")
def plan_cmd(image, output, preview, method, disconnected, pins, machine, frame, crop, start_pin, size, lines,
             importance, gray, style, alpha, beta, gamma, T, epsilon, iterations, no_cache):
    """Plan a thread painting of IMAGE: writes the plan and a preview PNG."""
    import os

    from ._files import check_not_same_file, check_output_path, write_atomic
    from .planner.build import plan_picture
    from .planner.image import parse_crop
    from .planner.plan_file import write_plan
    from .planner.render import draw, png_bytes

    mach = None
    if machine is not None:
        from firmware_protocol.machine import load_machine

        mach = load_machine(machine)
        ring = mach.pins
        if pins is not None and pins != ring:
            raise BadInput(f"--pins {pins} differs from machine {machine!r} with {ring} pins; give one of them")
        pins = ring
    pins = 300 if pins is None else pins
    preview = preview or os.path.splitext(output)[0] + ".png"
    check_output_path(output, what="plan")
    check_output_path(preview, what="preview")
    for out, what in ((output, "plan"), (preview, "preview")):
        for src, name in ((image, "picture"), (importance, "mask")):
            if src:
                check_not_same_file(out, src, what=what, source_what=name)
    check_not_same_file(preview, output, what="preview", source_what="plan")
    if lines != "auto" and lines <= 0:
        raise BadInput(f"--lines {lines}; expected a positive number or auto")
    p = plan_picture(image, pins=pins, frame=frame, size=size, crop=parse_crop(crop) if crop else None,
                     lines=lines, start_pin=start_pin, method=method, disconnected=disconnected,
                     importance=importance, gray=gray, style=style, alpha=alpha, beta=beta, gamma=gamma, T=T,
                     epsilon=epsilon, iterations=iterations, cache=not no_cache)
    if machine is not None:
        p.parameters["machine"] = machine
    png = png_bytes(draw(p, size=1001))
    write_plan(p, output)
    write_atomic(preview, png)
    s = p.stats
    kind = "disconnected " if not p.connected else ""
    style = f" ({p.parameters['style']})" if p.method == "fitness" else ""
    click.echo(f"{kind}{p.method}{style}: {p.pins} pins, {s['lines']} lines, thread {s['thread_diameters']:.1f} "
               f"diameters, {s['seconds']:.2f} s -> {output} (preview {preview})")
    if mach is not None:
        if not p.connected:
            click.echo(f"machine {mach.name}: a disconnected chord set cannot be wound; no machine-time estimate")
        else:
            from .motion import estimate, format_duration

            est = estimate(p, mach)
            click.echo(f"machine {mach.name}: about {format_duration(est.seconds)} of winding, "
                       f"{est.thread_m:.1f} m of thread")


@cli.command("render")
@click.argument("plan", type=click.Path(path_type=str))
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=str), help="PNG to write.")
@click.option("--size", type=int, default=1001, show_default=True, help="Side of the drawing in pixels.")
def render_cmd(plan, output, size):
    """Draw PLAN as black 1-pixel threads on white."""
    from ._files import check_not_same_file, check_output_path, write_atomic
    from .planner.plan_file import read_plan
    from .planner.render import draw, png_bytes

    if not 16 <= size <= 8001:
        raise BadInput(f"--size {size}; expected 16..8001 pixels")
    check_output_path(output, what="drawing")
    check_not_same_file(output, plan, what="drawing", source_what="plan")
    p = read_plan(plan)
    write_atomic(output, png_bytes(draw(p, size=size)))
    click.echo(f"{len(p.chord_list())} chords drawn at {size} x {size} -> {output}")


@cli.command("score")
@click.argument("plan", type=click.Path(path_type=str))
@click.argument("image", required=False, type=click.Path(path_type=str))
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
def score_cmd(plan, image, as_json):
    """SSIM of PLAN against IMAGE (default: the plan's source), as in the paper's section 4.1."""
    import json
    import os

    from .planner.image import read_picture, sha256_file
    from .planner.plan_file import read_plan
    from .planner.render import BLUR_SIGMA, SCORE_SIZE, score

    p = read_plan(plan)
    if image is None:
        image = p.source.get("path")
        if not image:
            raise BadInput(f"plan {plan!r} names no source picture; expected an IMAGE argument")
        beside = os.path.join(os.path.dirname(plan), image)
        if not os.path.isabs(image) and not os.path.exists(image) and os.path.exists(beside):
            image = beside  # a relative source path, taken from the plan's folder
    gray = p.parameters.get("gray_requested", "decolor")
    weights = p.parameters.get("gray_weights")
    if not (isinstance(weights, list) and len(weights) == 3 and all(isinstance(x, (int, float)) for x in weights)):
        weights = None
    pic = read_picture(image, size=SCORE_SIZE, crop=p.crop, weights=weights,
                       gray=gray if gray in ("decolor", "luminance") else "decolor")
    if p.source.get("sha256") and p.source["sha256"] != pic.source["sha256"]:
        log.warning("%s is not the picture the plan was made from (sha256 differs)", image)
    r = score(p, pic.gray)
    if as_json:
        click.echo(json.dumps({"plan": plan, "image": image, "method": p.method, "connected": p.connected,
                               "lines": r["lines"], "ssim": round(r["ssim"], 4),
                               "ssim_blurred": round(r["ssim_blurred"], 4), "blur_sigma": BLUR_SIGMA}))
    else:
        click.echo(f"{'plan':<10} {plan}\n{'image':<10} {image}\n{'method':<10} "
                   f"{p.method}{'' if p.connected else ' (disconnected)'}\n{'lines':<10} {r['lines']}\n"
                   f"{'SSIM':<10} {r['ssim']:.4f}\n{'blurred':<10} {r['ssim_blurred']:.4f}")


# == machine commands (machines, gcode, estimate) ==

@cli.group("machines", invoke_without_command=True)
@click.pass_context
def machines_cmd(ctx):
    """List the bundled machines (`machines show NAME` prints one with derived figures)."""
    if ctx.invoked_subcommand is not None:
        return
    from firmware_protocol.machine import bundled_machines, load_machine

    for name in bundled_machines():
        m = load_machine(name)
        kind = m["controller.dialect"] or m["controller.kind"]
        click.echo(f"{name:<16} {kind:<10} {m.pins:>5} pins  {m['description']}")


@machines_cmd.command("show")
@click.argument("name")
def machines_show_cmd(name):
    """Print machine NAME (a bundled name or a .toml path), checked, with derived figures."""
    from firmware_protocol.machine import load_machine

    m = load_machine(name)
    click.echo(f"# {m.path}")
    click.echo(m.to_toml().rstrip("\n"))
    click.echo("\n# derived")
    for label, text in m.derived():
        click.echo(f"# {label + ':':<15} {text}")


def _plan_and_machine(plan, machine):
    from firmware_protocol.machine import load_machine

    from .motion import check_plan_fits
    from .planner.plan_file import read_plan

    m = load_machine(machine)
    p = read_plan(plan)
    check_plan_fits(p, m)
    return p, m


def _estimate_lines(est):
    from .motion import format_duration

    return [f"{'machine time':<14} {format_duration(est.seconds)} ({est.seconds:.0f} s)",
            f"{'ring travel':<14} {est.ring_travel_deg:.0f} deg = {est.travel_ratio:.4f} x the "
            f"shortest-arc lower bound {est.lower_bound_deg:.0f} deg",
            f"{'thread':<14} {est.thread_m:.1f} m (wraps round pins {est.wrap_m:.2f} m)",
            f"{'steps':<14} {est.steps} pins hooked, {est.moves} moves"]


@cli.command("gcode")
@click.argument("plan", type=click.Path(path_type=str))
@click.option("--machine", required=True, help="Machine name (see `stringbot machines`) or a .toml path.")
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=str),
              help="G-code file to write (for UGS, bCNC, OctoPrint...).")
def gcode_cmd(plan, machine, output):
    """Write the whole winding of PLAN on MACHINE as one G-code program."""
    import os

    from ._files import check_not_same_file, check_output_path, write_atomic
    from .motion import dialect_for, format_duration, gcode_job

    check_output_path(output, what="G-code")
    check_not_same_file(output, plan, what="G-code", source_what="plan")
    p, m = _plan_and_machine(plan, machine)
    dialect_for(m)
    text = gcode_job(p, m, plan_name=os.path.basename(plan))
    write_atomic(output, text)
    from .motion import estimate
    est = estimate(p, m)
    click.echo(f"{len(p.sequence)} pins, {text.count(chr(10))} lines, about {format_duration(est.seconds)}, "
               f"{est.thread_m:.1f} m of thread -> {output}")


@cli.command("estimate")
@click.argument("plan", type=click.Path(path_type=str))
@click.option("--machine", required=True, help="Machine name (see `stringbot machines`) or a .toml path.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
def estimate_cmd(plan, machine, as_json):
    """Machine time, ring travel and thread length of winding PLAN on MACHINE."""
    import json

    from .motion import estimate

    p, m = _plan_and_machine(plan, machine)
    est = estimate(p, m)
    if as_json:
        click.echo(json.dumps({"plan": plan, "machine": m.name, **est.as_dict()}))
    else:
        click.echo(f"{'plan':<14} {plan}\n{'machine':<14} {m.name} ({m.path})")
        for line in _estimate_lines(est):
            click.echo(line)

# == winding commands (wind, simulate) ==


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
    from .winding import dry_run_problem, load_job, wind_plan
    from .winding import resume as resuming

    if show_status and port is None and journal is None:
        from .winding.journal import journal_path_for

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
@click.option("--faults", default=None, help="Faults to inject: kind@N,... (disconnect, reset, power, "
                                             "garble, drop-ok, error; N counts received lines).")
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


if __name__ == "__main__":
    main()
