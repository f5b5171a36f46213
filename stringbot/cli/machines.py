"""Machine commands: machines, machines show, gcode, estimate."""


import click

from ..errors import BadInput
from . import cli


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


def _plan_and_machine(plan, machine, force):
    from ..motion import check_plan_fits
    from ..planner.plan_file import read_plan
    from .plan_machine import check_thread, plan_machine

    p = read_plan(plan)
    m = plan_machine(p, plan, machine)
    check_plan_fits(p, m)                   # pins and frame first: a plan for another ring is that first
    if not force:
        check_thread(p, plan, m)
    return p, m


MACHINE_HELP = "Machine name (see `stringbot machines`) or a .toml path [default: the plan's, from plan --machine]."
FORCE_HELP = ("Use the plan even though it was made for another thread-to-diameter ratio than the machine's "
              "(the piece then comes out darker or lighter than its preview).")


def _estimate_lines(est):
    from ..motion import format_duration

    return [f"{'machine time':<14} {format_duration(est.seconds)} ({est.seconds:.0f} s)",
            f"{'ring travel':<14} {est.ring_travel_deg:.0f} deg = {est.travel_ratio:.4f} x the "
            f"shortest-arc lower bound {est.lower_bound_deg:.0f} deg",
            f"{'thread':<14} {est.thread_m:.1f} m (wraps round pins {est.wrap_m:.2f} m)",
            f"{'steps':<14} {est.steps} pins hooked, {est.moves} moves"]


@cli.command("gcode")
@click.argument("plan", type=click.Path(path_type=str))
@click.option("--machine", default=None, help=MACHINE_HELP)
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=str, allow_dash=True),
              help="G-code file to write (for UGS, bCNC, OctoPrint...), or - for standard output.")
@click.option("--force", is_flag=True, help=FORCE_HELP)
def gcode_cmd(plan, machine, output, force):
    """Write the whole winding of PLAN on MACHINE as one G-code program."""
    import os
    import sys

    from .._files import check_not_same_file, check_ours, check_output_path, write_atomic
    from ..motion import dialect_for, format_duration, gcode_job

    check_output_path(output, what="G-code", allow_stdout=True)
    check_not_same_file(output, plan, what="G-code", source_what="plan")
    check_ours(output, "gcode", what="G-code", instead="give a new file")  # never someone's own program
    p, m = _plan_and_machine(plan, machine, force)
    dialect_for(m)
    text = gcode_job(p, m, plan_name=os.path.basename(plan))
    if output == "-":
        sys.stdout.write(text)
        sys.stdout.flush()
    else:
        write_atomic(output, text, what="G-code")
    from ..motion import estimate
    est = estimate(p, m)
    changes = f", {len(p.colors) - 1} spool change(s) (M0)" if len(p.colors) > 1 else ""
    click.echo(f"{len(p.sequence)} pins, {text.count(chr(10))} lines, about {format_duration(est.seconds)}, "
               f"{est.thread_m:.1f} m of thread{changes} -> {output}", err=output == "-")


@cli.command("estimate")
@click.argument("plan", type=click.Path(path_type=str))
@click.option("--machine", default=None, help=MACHINE_HELP)
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--force", is_flag=True, help=FORCE_HELP)
def estimate_cmd(plan, machine, as_json, force):
    """Machine time, ring travel and thread length of winding PLAN on MACHINE."""
    import json

    from ..motion import estimate, format_duration

    p, m = _plan_and_machine(plan, machine, force)
    est = estimate(p, m)
    layers = colours = None
    if not p.is_mono:
        from ..motion.layers import colour_estimates, layer_estimates
        layers = layer_estimates(p, m)
        colours = colour_estimates(p, m, layers=layers)
    if as_json:
        extra = {"colors": [vars(ce) for ce in colours], "layers": [vars(le) for le in layers]} if layers else {}
        click.echo(json.dumps({"plan": plan, "machine": m.name, **est.as_dict(), **extra}))
    else:
        click.echo(f"{'plan':<14} {plan}\n{'machine':<14} {m.name} ({m.path})")
        for line in _estimate_lines(est):
            click.echo(line)
        for ce in colours or []:
            click.echo(f"{'colour':<14} {ce.color}: {ce.thread_m:.1f} m of thread, {format_duration(ce.seconds)}, "
                       f"{ce.steps} pins in {ce.runs} run(s)")
        for le in layers or []:
            click.echo(f"{'layer ' + str(le.index + 1):<14} {le.color}: {le.thread_m:.1f} m of thread, "
                       f"{format_duration(le.seconds)}, {le.steps} pins, tie on at pin {le.tie_on_pin}")
