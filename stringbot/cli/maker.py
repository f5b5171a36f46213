"""The maker's commands: template (drill the ring), pins (wind by hand), animate (watch it grow)."""

import os
import sys

import click

from ..errors import BadInput
from . import cli


def _emit(output, data, *, what, source=None):
    """Write ``data`` to ``output`` (``-``: standard output), durably, never over the input."""
    from .._files import check_not_same_file, check_output_path, write_atomic

    if output == "-":
        out = sys.stdout.buffer
        out.write(data.encode("utf-8") if isinstance(data, str) else data)
        out.flush()
        return
    check_output_path(output, what=what)
    if source is not None:
        check_not_same_file(output, source, what=what, source_what="plan")
    write_atomic(output, data, what=what)


def frame_size_options(what):
    """``--diameter-mm``, ``--machine`` and ``--force`` of a command that reads a plan's frame size
    (:func:`_frame_size`); ``what`` says what the size is for."""
    def add(f):
        f = click.option("--force", is_flag=True, help="Use the plan even though it was made for another "
                         "thread-to-diameter ratio than the machine's.")(f)
        f = click.option("--machine", default=None, help="Take the ring diameter from this machine (name or "
                         ".toml) [default: the plan's, from plan --machine].")(f)
        return click.option("--diameter-mm", type=float, default=None,
                            help=f"Ring diameter (a square frame's side), mm: {what}.")(f)
    return add


def _frame_size(plan, diameter_mm, machine, *, plan_path, force=False):
    """(size_mm, where it came from, Machine or None): --diameter-mm, --machine, the plan's machine
    (``parameters.machine``), or the plan's own frame."""
    from .plan_machine import check_thread, plan_machine

    if diameter_mm is not None and machine is not None:
        raise BadInput("--diameter-mm and --machine both give the frame size; give one of them")
    if diameter_mm is not None:
        if not 10 <= diameter_mm <= 5000:
            raise BadInput(f"--diameter-mm {diameter_mm:g}; expected 10..5000 mm")
        return diameter_mm, "--diameter-mm", None
    if machine is not None or plan.parameters.get("machine"):
        m = plan_machine(plan, plan_path, machine)
        if m.pins != plan.pins:
            raise BadInput(f"plan has {plan.pins} pins but machine {m.name!r} has ring.pins = {m.pins}; "
                           "expected the same pin count")
        if plan.frame != "circle":
            raise BadInput(f"plan is for a {plan.frame} frame but machine {m.name!r} winds a ring; "
                           "expected a plan made with --frame circle")
        if not force:
            check_thread(plan, plan_path, m)
        return m["ring.diameter_mm"], f"machine {m.name}", m
    size = getattr(plan, "diameter_mm", None)           # the plan's frame (500 mm when it names none)
    if size:
        return float(size), "the plan", None
    return None, "", None


@cli.command("template", epilog="""\b
Examples:
  stringbot template --machine grbl-ring -o ring.svg
  stringbot template --machine grbl-ring -o ring.pdf --paper letter
  stringbot template --pins 200 --diameter-mm 400 --pin-diameter-mm 1.2 -o ring.pdf
""")
@click.option("--machine", default=None, help="Take pins, diameter and pin size from this machine (name or .toml).")
@click.option("--pins", type=int, default=None, help="Pins on the ring (without --machine).")
@click.option("--diameter-mm", type=float, default=None,
              help="Diameter of the circle through the pin centres, mm (without --machine).")
@click.option("--pin-diameter-mm", type=float, default=None,
              help="Pin (nail) diameter, mm, drawn round each centre [default: the machine's, or 1.5].")
@click.option("-o", "--output", "output", required=True, type=click.Path(dir_okay=False, path_type=str),
              help="File to write: .svg (one sheet, in mm) or .pdf (tiled on pages).")
@click.option("--paper", type=click.Choice(["a4", "letter"]), default="a4", show_default=True,
              help="PDF page size; larger rings are tiled with 10 mm overlap and alignment marks.")
def template_cmd(machine, pins, diameter_mm, pin_diameter_mm, output, paper):
    """Write a 1:1 drilling template of the ring: every pin centre, numbered."""
    from ..motion.template import template_pdf, template_svg

    ext = os.path.splitext(output)[1].lower()
    if output == "-" or ext not in (".svg", ".pdf"):
        raise BadInput(f"-o {output!r}; expected a file name ending in .svg or .pdf")
    name = ""
    if machine is not None:
        from firmware_protocol.machine import load_machine

        if pins is not None or diameter_mm is not None:
            raise BadInput("--machine gives pins and diameter; leave out --pins and --diameter-mm")
        m = load_machine(machine)
        pins, diameter_mm, name = m.pins, m["ring.diameter_mm"], m.name
        pin_diameter_mm = m["ring.pin_diameter_mm"] if pin_diameter_mm is None else pin_diameter_mm
    elif pins is None or diameter_mm is None:
        raise BadInput("expected --machine NAME, or both --pins N and --diameter-mm D")
    pin_diameter_mm = 1.5 if pin_diameter_mm is None else pin_diameter_mm
    kw = dict(pins=pins, diameter_mm=diameter_mm, pin_diameter_mm=pin_diameter_mm, name=name)
    from .._files import check_ours, check_output_path
    check_output_path(output, what="template")
    check_ours(output, "template", what="template", instead="give another -o")   # never someone's own drawing
    data = template_svg(**kw) if ext == ".svg" else template_pdf(paper=paper, **kw)
    _emit(output, data, what="template")
    pages = ""
    if ext == ".pdf":
        pages = f", {data.count(b'/Type /Page ')} {paper} page(s)"
    click.echo(f"template: {pins} pins on a {diameter_mm:g} mm circle{pages} -> {output}; "
               "print at 100 % and check the 100 mm ruler", err=output == "-")


@cli.command("pins", epilog="""\b
Examples:
  stringbot pins camera.json -o camera-pins.txt --machine grbl-ring
  stringbot pins camera.json -o camera-pins.csv --diameter-mm 500
  stringbot pins camera.json | less
""")
@click.argument("plan", type=click.Path(dir_okay=True, path_type=str))
@click.option("-o", "--output", "output", default="-", show_default=True,
              type=click.Path(dir_okay=False, allow_dash=True, path_type=str),
              help="Pin list to write: .txt (pages of 100 steps), .csv, or - for standard output (text).")
@frame_size_options("the thread length in metres")
def pins_cmd(plan, output, diameter_mm, machine, force):
    """Write the pin list of PLAN for winding by hand: step, pin, wrap direction.

    A colour plan's list goes thread by thread, saying before each which colour to tie on at
    which pin (the CSV has a color column).
    """
    from ..motion.pins import format_csv, format_txt, pin_list
    from ..planner.plan_file import read_plan

    from .._files import check_not_same_file, check_ours, check_output_path

    ext = os.path.splitext(output)[1].lower() if output != "-" else ".txt"
    if ext not in (".txt", ".csv"):
        raise BadInput(f"-o {output!r}; expected a file name ending in .txt or .csv, or - for standard output")
    check_output_path(output, what="pin list", allow_stdout=True)      # before the work
    check_ours(output, "pins", what="pin list", instead="give another -o")     # never someone's notes
    check_not_same_file(output, plan, what="pin list", source_what="plan")
    p = read_plan(plan)
    size, size_from, mach = _frame_size(p, diameter_mm, machine, plan_path=plan, force=force)
    thread_m = None
    if mach is not None:
        from ..motion import estimate
        thread_m = estimate(p, mach).thread_m
    pl = pin_list(p, plan_name=os.path.basename(plan), size_mm=size, size_from=size_from, thread_m=thread_m)
    text = format_csv(pl) if ext == ".csv" else format_txt(pl)
    _emit(output, text, what="pin list", source=plan)
    click.echo(f"{len(pl.rows)} steps -> {output}" + (f"; thread {dict(pl.header)['thread']}" if size else ""),
               err=output == "-")


@cli.command("animate", epilog="""\b
Examples:
  stringbot animate camera.json -o camera-wind.gif
  stringbot animate camera.json -o camera-wind.gif --frames 200 --size 600 --fps 20
  stringbot animate camera.json -o camera-wind.mp4      (needs: pip install imageio-ffmpeg)
""")
@click.argument("plan", type=click.Path(dir_okay=True, path_type=str))
@click.option("-o", "--output", "output", required=True, type=click.Path(dir_okay=False, path_type=str),
              help="Animation to write: .gif (Pillow) or .mp4 (imageio's ffmpeg plugin).")
@click.option("--frames", type=click.IntRange(1, 2000), default=100, show_default=True,
              help="Frames, the painting growing evenly from the first chord to the last.")
@click.option("--size", type=click.IntRange(64, 2000), default=400, show_default=True, help="Side in pixels.")
@click.option("--fps", type=click.FloatRange(1, 60), default=10.0, show_default=True, help="Frames per second.")
def animate_cmd(plan, output, frames, size, fps):
    """Animate PLAN: the painting growing in winding order, newest thread in red (a colour plan:
    each thread in its colour over the board, the newest in the opposite colour)."""
    from ..planner.model.frames import Mp4Unavailable, gif_bytes, growth_frames, mp4_bytes
    from ..planner.plan_file import read_plan

    ext = os.path.splitext(output)[1].lower()
    if output == "-" or ext not in (".gif", ".mp4"):
        raise BadInput(f"-o {output!r}; expected a file name ending in .gif or .mp4")
    if ext == ".mp4" and size % 2:
        raise BadInput(f"--size {size}; expected an even number of pixels for MP4")
    from .._files import check_not_same_file, check_ours, check_output_path
    check_output_path(output, what="animation")
    check_ours(output, "animation", what="animation", instead="give another -o")  # never someone's video
    check_not_same_file(output, plan, what="animation", source_what="plan")
    p = read_plan(plan)
    if p.is_mono:
        images = [f for f, _ in growth_frames(p, frames=frames, size=size)]
    else:                                   # a colour plan: each layer in its colour, later ones on top
        from ..planner.colour.frames import colour_growth_frames
        images = [f for f, _ in colour_growth_frames(p, frames=frames, size=size)]
    try:
        data = gif_bytes(images, fps=fps) if ext == ".gif" else mp4_bytes(images, fps=fps)
    except Mp4Unavailable as exc:
        raise BadInput(str(exc)) from None
    _emit(output, data, what="animation", source=plan)
    click.echo(f"{len(images)} frames of {len(p.chord_list())} chords, {len(images) / fps:.1f} s at {fps:g} fps "
               f"-> {output}")
