"""Colour plans on the command line: ``plan --colors``, and colour in render, score, estimate, gcode.

The commands themselves live in their own modules; this one holds what they
do differently for a plan of several thread colours.
"""

import click

from ..errors import BadInput

#: ``plan`` options that are knobs of the mono planner: refused with ``--colors``.
MONO_ONLY = ("method", "disconnected", "importance", "gray", "alpha", "style", "beta", "gamma", "T", "epsilon",
             "iterations", "refine", "polish", "polish_passes", "fit")


def colour_names(colors):
    from ..planner.colour.palette import color_name

    return ", ".join(f"{color_name(c)} {c}" if color_name(c) != c else c for c in colors)


def plan_colour_cmd(*, image, output, preview, colors, background, pins, mach, machine, frame, crop, start_pin,
                    size, lines, no_cache, given, model, force=False, spool_changes=None, min_run=None,
                    face="off"):
    """``stringbot plan IMAGE --colors ...``: the colour planner, its plan and its preview as woven."""
    import os

    from .._files import write_all_atomic
    from ..planner.colour.build import COLOUR_DEFAULTS, plan_colour
    from ..planner.colour.palette import WHITE, parse_background, parse_colors
    from ..planner.colour.render import PREVIEW_SAMPLES, plan_layers, woven_rgb
    from ..planner.picture.read import parse_crop
    from ..planner.progress import reporting
    from .plan_checks import PREVIEW_SIZE, check_plan_outputs, warn_small_crop
    from .progress import PlanProgress

    mono = [f"--{name.replace('_', '-')}" if name != "T" else "-T" for name in MONO_ONLY if name in given]
    if mono:
        raise BadInput(f"{', '.join(mono)} {'is a knob' if len(mono) == 1 else 'are knobs'} of the one-thread "
                       "planner; leave them out with --colors (the colour planner has none)")
    board = parse_background(background) if background is not None else WHITE
    palette = parse_colors(colors if colors is not None else "black", background=board)
    preview = preview or os.path.splitext(output)[0] + ".png"
    check_plan_outputs(output, preview, sources=((image, "picture"),), force=force, lines=lines)
    if crop is None:
        warn_small_crop(image, fit=False)
    shown = PlanProgress().start()
    try:
        with reporting(shown):
            p = plan_colour(image, colors=palette, background=board, pins=pins, frame=frame,
                            size=COLOUR_DEFAULTS["size"] if size is None else size,
                            crop=parse_crop(crop) if crop else None, lines=lines,
                            start_pin=start_pin, model=model, cache=not no_cache,
                            spool_changes=COLOUR_DEFAULTS["spool_changes"] if spool_changes is None else spool_changes,
                            min_run=COLOUR_DEFAULTS["min_run"] if min_run is None else min_run,
                            face=face)
    finally:
        shown.close()
    if machine is not None:
        p.parameters["machine"] = machine
    rgb = woven_rgb(plan_layers(p), p.pin_xy, background=p.background, size=PREVIEW_SIZE,
                    thread_fraction=model.fraction, samples=PREVIEW_SAMPLES)
    write_all_atomic([(output, p.to_json(), "plan"), (preview, png_rgb_bytes(rgb), "preview")])  # both or neither
    s = p.stats
    runs = {c: sum(1 for x in p.colors if x == c) for c in dict.fromkeys(p.colors)}
    per = ", ".join(f"{_short(c)} {s['colors'][c]['lines']} in {n}" for c, n in runs.items())
    # in metres on the plan's frame (--machine's ring, --diameter-mm, or 500 mm), as a one-thread plan says
    thread = f"{s['thread_diameters'] * p.thread_model().diameter_mm / 1000.0:.1f} m"
    click.echo(f"colour: {p.pins} pins, {len(runs)} thread(s) in {len(p.colors)} run(s) (lines in runs: {per}), "
               f"{s['lines']} lines, thread {thread}, {s['spool_changes']} spool change(s), {s['seconds']:.2f} s "
               f"-> {output} (preview {preview})")
    from .plan_checks import face_found_line
    face_found_line(p, centred=crop is None)
    why = s.get("palette", {}).get("why_fewer")
    if why:
        asked = p.parameters["colors_requested"].split(":")[1]
        click.echo(f"--colors auto:{asked}: {len(p.parameters['colors'])} thread(s): {why}")
    if s["unused"]:
        click.echo(f"unused: {colour_names(s['unused'])} (no run of it: it lowered the colour error nowhere, "
                   "or the spool-change budget left it no run, or its run would have been shorter than --min-run)")
    if mach is not None:
        for line in estimate_lines(p, mach):
            click.echo(line)


def _short(color):
    from ..planner.colour.palette import color_name

    return color_name(color)


def png_rgb_bytes(rgb):
    """PNG bytes of an sRGB float image in [0, 1], marked as stringbot's (:func:`~stringbot._files.mark_png`)."""
    import io

    from PIL import Image

    from .._files import mark_png
    from ..planner.colour.render import to_uint8

    buf = io.BytesIO()
    Image.fromarray(to_uint8(rgb), "RGB").save(buf, format="PNG", compress_level=3)
    return mark_png(buf.getvalue())             # stringbot's: a later plan or render may replace it


def estimate_lines(plan, machine):
    """Per-colour thread and machine time, and the total, for ``plan`` on ``machine``."""
    from ..motion import estimate, format_duration
    from ..motion.layers import colour_estimates, layer_estimates

    est = estimate(plan, machine)
    out = [f"machine {machine.name}: about {format_duration(est.seconds)} of winding, {est.thread_m:.1f} m of "
           f"thread, {len(plan.colors) - 1} spool change(s)"]
    layers = layer_estimates(plan, machine)
    for ce in colour_estimates(plan, machine, layers=layers):
        out.append(f"  {_short(ce.color)} ({ce.color}): {ce.thread_m:.1f} m of thread, {format_duration(ce.seconds)}, "
                   f"{ce.steps} pins in {ce.runs} run(s)")
    for le in layers:
        out.append(f"  layer {le.index + 1} {_short(le.color)} ({le.color}): {le.thread_m:.1f} m of thread, "
                   f"{format_duration(le.seconds)}, {le.steps} pins, tie on at pin {le.tie_on_pin}")
    return out


def render_colour(plan, output, size):
    """``stringbot render`` of a colour plan: as woven."""
    from .._files import write_atomic
    from ..planner.colour.render import plan_layers, woven_rgb

    write_atomic(output, png_rgb_bytes(woven_rgb(plan_layers(plan), plan.pin_xy, background=plan.background,
                                                 size=size, thread_fraction=plan.thread_model().fraction)),
                 what="drawing")
    click.echo(f"{len(plan.chord_list())} chords in {len(plan.colors)} layers drawn as woven at {size} x {size} "
               f"-> {output}")


def score_colour(plan, plan_path, image, *, face_box=None):
    """The colour score of any plan (a mono plan is black thread on white) against IMAGE at 512 px; inside
    ``face_box`` (source pixels) when given, else inside the face box the plan recorded, if any."""
    from ..planner.colour.render import SCORE_SIZE, colour_score, plan_layers
    from ..planner.picture.read import read_picture

    pic = read_picture(image, size=SCORE_SIZE, crop=plan.crop, gray="luminance")
    face = face_box if face_box is not None else (plan.parameters.get("face") or {}).get("box")
    return colour_score(plan_layers(plan), plan.pin_xy, pic.rgb, frame=plan.frame, background=plan.background,
                        thread_fraction=plan.thread_model().fraction, face=face, crop=plan.crop)


# == winding a colour plan: the spool changes ==

SPOOL_CHANGES = ("ask", "stop", "continue")


def spool_change_mode(option, *, yes, dry_run):
    """``wind --spool-change`` checked against ``--yes`` and the port (None: the default, see
    :func:`stringbot.winding.layers.threads_for`)."""
    if option == "ask" and yes:
        raise BadInput("--spool-change ask asks at a terminal and --yes asks nothing; give one of them")
    if option == "stop" and dry_run:
        raise BadInput("--spool-change stop: a dry run's simulated machine ends with its command, so the "
                       "winding could not be resumed after the stop; give --port (or leave it out: the "
                       "simulated operator ties each thread on)")
    return option


def simulated_hands(job):
    """A dry run's simulated operator, who ties each thread on when the host asks: the ``sim://``
    world is told (its record then has every wrap's colour).  None on a port: a person ties it on."""
    if not job.dry_run:
        return None
    from firmware_protocol.urlhandler import protocol_sim

    url = str(job.url)
    return lambda color, pin: protocol_sim.tie_on(url, color, pin)


def _word(text):
    return "-".join(str(text).strip().lower().replace("_", " ").split())


def confirm_thread(question, color, *, prompt, say):
    """Ask until the operator types the thread's name (or its ``#rrggbb``, or ``y``): True; ``n``:
    False.  There is no default: an empty answer asks again, another colour is refused."""
    from ..planner.colour.palette import color_name, describe_color

    name = color_name(color)
    yes = {_word(color), _word(name), "y", "yes"}
    hint = f"type {name} (or y) once it is tied on, n to stop"
    while True:
        answer = _word(prompt(f"{question} [{hint}]"))
        if answer in yes:
            return True
        if answer in ("n", "no"):
            return False
        if answer:
            say(f"{answer!r} is not the {describe_color(color)} thread; {hint}")


def first_thread_line(plan, mode):
    """Before a colour plan's winding with nobody to ask: the thread it starts with, and what
    happens at the spool changes."""
    from ..planner.colour.palette import describe_color

    n = len(plan.colors) - 1
    then = {"stop": f"it stops at each of the {n} spool change(s) (exit 3) for you to tie the next one on",
            "continue": f"it goes through the {n} spool change(s) without stopping (--spool-change continue)"}
    return (f"threads: layer 1 of {len(plan.colors)} is the {describe_color(plan.colors[0])} thread, tied on "
            f"at pin {plan.sequence[0]} before starting (--yes asks nothing); {then[mode]}")


def tie_on_simulator(pty_path, color, pin, *, serving):
    """``simulate --pty PATH --tie-on COLOUR``: tell the simulator serving on PATH that the operator tied
    a thread of COLOUR on (its operator socket); its record gives every later wrap that colour."""
    from firmware_protocol.pty import OPERATOR_SUFFIX, tell_operator

    from ..planner.colour.palette import describe_color, parse_color

    if color is None:
        raise BadInput("--pin goes with --tie-on COLOUR (the thread tied on at that pin)")
    record, realtime, faults, settings = serving
    if record or realtime or faults or settings:
        raise BadInput("--tie-on talks to a simulator that is already serving; leave out --record, --realtime, "
                       "--faults and --set (they are for starting one)")
    hex_color = parse_color(color, what="--tie-on")
    if not tell_operator(pty_path, {"tie_on": hex_color, "pin": pin}):
        raise BadInput(f"--pty {pty_path!r}: no simulator serves there (no operator socket "
                       f"{pty_path + OPERATOR_SUFFIX!r}); expected the path of a running "
                       "`stringbot simulate --pty PATH`")
    at = "" if pin is None else f" at pin {pin}"
    click.echo(f"tied the {describe_color(hex_color)} thread on{at} (simulator on {pty_path})")
