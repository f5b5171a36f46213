"""Planner commands: plan, render, score.

Heavy modules (numpy, scipy, PIL) are imported inside the commands: startup counts.
"""


import click

from ..errors import BadInput
from ..planner.methods import DEFAULT_METHOD, METHODS, method_help
from . import cli, log
from .plan_checks import PREVIEW_SIZE, check_plan_outputs, warn, warn_small_crop



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
@click.option("--method", type=click.Choice(list(METHODS)), default=DEFAULT_METHOD, show_default=True,
              help=method_help())
@click.option("--disconnected", is_flag=True, help="A chord set by priority queue (fitness only); cannot be wound.")
@click.option("--pins", type=int, default=None, help="Pins on the frame [default: 300, or the machine's].")
@click.option("--machine", default=None,
              help="Take the pin count, ring diameter and thread width (its calibrated effective width, if any) from "
                   "this machine (name or TOML path).")
@click.option("--diameter-mm", type=float, default=None,
              help="Diameter of the pin circle (side of a square frame) in mm [default: 500, or the machine's].")
@click.option("--thread-mm", type=float, default=None,
              help="Width of the thread in mm [default: 0.25, or the machine's].")
@click.option("--frame", type=click.Choice(["circle", "square"]), default="circle", show_default=True,
              help="Pins on a ring, or along the border of a square (a square is wound by hand: stringbot pins).")
@click.option("--crop", default=None, help="CX,CY,R in picture pixels [default: largest centred circle].")
@click.option("--fit", is_flag=True, help="Paint the whole picture, letterboxed on the board, not its centre.")
@click.option("--face", type=click.Choice(["auto", "on", "off"]), default="off", show_default=True, is_flag=False,
              flag_value="on",
              help="Keep the largest face in the crop (moved towards it only as far as needed) and weigh the face "
                   "more; --face alone: on (refuses a picture without a face); auto: when a face is found, else as off.")
@click.option("--start-pin", type=int, default=None,
              help="First pin (0 is at the top, numbered clockwise) [default: residual: an end of its best chord; "
                   "euler: an end of its thread; fitness: 0; greedy: pins / 4, ThreadTone's].")
@click.option("--size", type=int, default=None, help="Working size in pixels [default: 401; greedy: 1001, ThreadTone's].")
@click.option("--lines", type=_Lines(), default="auto", show_default=True,
              help="Chords to draw; auto: residual stops when another thread would not improve the picture as "
                   "woven (euler: as many as its relaxed optimum gives); fitness and greedy: 500 + 10 (255 - mean gray).")
@click.option("--importance", type=click.Path(path_type=str), default=None,
              help="Mask PNG of the picture's size: white = important (weight 2).")
@click.option("--gray", type=click.Choice(["decolor", "luminance"]), default=None,
              help="Colour to gray: contrast-preserving decolorization or plain luminance (0.2125 R + 0.7154 G + "
                   "0.0721 B; greedy: ThreadTone's 0.299 R + 0.587 G + 0.114 B) [default: luminance; fitness: "
                   "decolor, the paper's].")
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
@click.option("--refine", type=int, default=None,
              help="Residual: pins the pixel refinement revisits (0: none) [default: 300, or 0 when polishing].")
@click.option("--polish", type=int, default=None,
              help="Residual and euler: pins the as-woven polish revisits: each change judged by the piece as woven, seen "
                   "from a step away (0: none) [default: 1000 with --lines auto, 0 with a line count].")
@click.option("--polish-passes", "polish_passes", type=int, default=None, metavar="N",
              help="Residual and euler: N passes of inserted and deleted pins after the polish, each kept only if the piece "
                   "as woven gets better: slower, a little better (0..20; 0: none; euler deletes once after the polish anyway "
                   "with --lines auto) [default: 0].")
@click.option("--no-cache", is_flag=True, help="Do not read or write the chord cache.")
@click.option("--force", is_flag=True,
              help="Overwrite a plan even though its winding journal has steps done (the journal is kept).")
@click.option("--colors", default=None, metavar="LIST|auto:N",
              help="Thread colours: names or #rrggbb (black,crimson,#1f5bb5), or auto:N to pick N by what they "
                   "reach of the picture (auto:N:LIST: among those); plans in colour, in runs (a version 2 plan).")
@click.option("--background", default=None, metavar="white|black|#rrggbb",
              help="Colour of the board the threads are wound over [default: white]; plans in colour.")
@click.option("--spool-changes", "spool_changes", type=int, default=None, metavar="N",
              help="With --colors: at most N spool changes; the colours come back in runs within them "
                   "[default: 8].")
@click.option("--min-run", "min_run", type=int, default=None, metavar="N",
              help="With --colors: a run of one colour lays at least N lines before the spool may change "
                   "[default: 100].")
def plan_cmd(image, output, preview, method, disconnected, pins, machine, diameter_mm, thread_mm, frame, crop, fit,
             face, start_pin, size, lines, importance, gray, style, alpha, beta, gamma, T, epsilon, iterations, refine,
             polish, polish_passes, no_cache, force, colors, background, spool_changes, min_run):
    """Plan a thread painting of IMAGE: writes the plan and a preview PNG."""
    import os

    from .._files import mark_png, write_all_atomic
    from ..planner.build import plan_picture
    from ..planner.picture.read import parse_crop
    from ..planner.model.render import preview_png

    mach = None
    if machine is not None:
        from firmware_protocol.machine import load_machine

        mach = load_machine(machine)
        ring = mach.pins
        if pins is not None and pins != ring:
            raise BadInput(f"--pins {pins} differs from machine {machine!r} with {ring} pins; give one of them")
        if frame != "circle":
            raise BadInput(f"--frame {frame} with machine {machine!r}, which winds a ring; expected --frame circle "
                           "(or leave out --machine)")
        pins = ring
        width = mach.thread_width_key     # a calibrated thread (`calibrate fit`) is drawn at its effective width
        for option, given, key in (("--diameter-mm", diameter_mm, "ring.diameter_mm"), ("--thread-mm", thread_mm, width)):
            if given is not None and given != mach[key]:
                raise BadInput(f"{option} {given:g} differs from machine {machine!r} ({key} = {mach[key]:g}); "
                               "give one of them")
        diameter_mm, thread_mm = mach["ring.diameter_mm"], mach[width]
    pins = 300 if pins is None else pins
    from ..planner.knobs import thread_model

    thread_model(diameter_mm, thread_mm)  # bad sizes are refused before any work
    if colors is not None or background is not None:
        from .colour import plan_colour_cmd
        ctx = click.get_current_context()
        given = {name for name in ctx.params
                 if ctx.get_parameter_source(name) is click.core.ParameterSource.COMMANDLINE}
        return plan_colour_cmd(image=image, output=output, preview=preview, colors=colors, background=background,
                               pins=pins, mach=mach, machine=machine, frame=frame, crop=crop, start_pin=start_pin,
                               size=size, lines=lines, no_cache=no_cache, given=given,
                               model=thread_model(diameter_mm, thread_mm), force=force,
                               spool_changes=spool_changes, min_run=min_run, face=face)
    for option, given_value in (("--spool-changes", spool_changes), ("--min-run", min_run)):
        if given_value is not None:
            raise BadInput(f"{option} is a knob of the colour planner; give --colors too (e.g. --colors auto:3), "
                           "or leave it out")
    preview = preview or os.path.splitext(output)[0] + ".png"
    check_plan_outputs(output, preview, sources=((image, "picture"), (importance, "mask")), force=force,
                       lines=lines)
    if crop is None and not fit:
        warn_small_crop(image)
    from ..planner.progress import reporting
    from .progress import PlanProgress

    shown = PlanProgress().start()
    try:
        with reporting(shown):
            p = plan_picture(image, pins=pins, frame=frame, size=size, crop=parse_crop(crop) if crop else None,
                             lines=lines, start_pin=start_pin, method=method, disconnected=disconnected,
                             importance=importance, gray=gray, style=style, alpha=alpha, beta=beta, gamma=gamma,
                             T=T, epsilon=epsilon, iterations=iterations, cache=not no_cache,
                             diameter_mm=diameter_mm, thread_mm=thread_mm, fit=fit, refine=refine, polish=polish,
                             polish_passes=polish_passes, preview=PREVIEW_SIZE, face=face)
    finally:
        shown.close()
    if machine is not None:
        p.parameters["machine"] = machine
    est = None
    if mach is not None and p.connected:  # while the polish's helper processes may still be drawing the preview
        from ..motion import estimate

        est = estimate(p, mach)
    png = mark_png(preview_png(p, PREVIEW_SIZE))  # the polish's helper processes may have drawn it meanwhile
    write_all_atomic([(output, p.to_json(), "plan"), (preview, png, "preview")])   # both or neither
    s = p.stats
    kind = "disconnected " if not p.connected else ""
    style = f" ({p.parameters['style']})" if p.method == "fitness" else ""
    # the frame's size is known (--diameter-mm, the machine's, or the default): metres, chords only
    thread = f"{s['thread_diameters'] * p.diameter_mm / 1000.0:.1f} m"
    click.echo(f"{kind}{p.method}{style}: {p.pins} pins, {s['lines']} lines, thread {thread}, "
               f"{s['seconds']:.2f} s -> {output} (preview {preview})")
    from .plan_checks import face_found_line
    face_found_line(p, centred=crop is None and not fit)
    if p.stats.get("line_cap"):
        warn(f"planning stopped at the cap of {p.stats['line_cap']} lines, not because the picture was matched: "
             f"it asks for more thread than that; check the preview {preview!r}, or give --lines N")
    if mach is not None:
        if not p.connected:
            click.echo(f"machine {mach.name}: a disconnected chord set cannot be wound; no machine-time estimate")
        else:
            from ..motion import format_duration

            click.echo(f"machine {mach.name}: about {format_duration(est.seconds)} of winding, "
                       f"{est.thread_m:.1f} m of thread")


@cli.command("render")
@click.argument("plan", type=click.Path(path_type=str))
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=str), help="PNG to write.")
@click.option("--size", type=int, default=1001, show_default=True, help="Side of the drawing in pixels.")
@click.option("--binary", is_flag=True,
              help="The paper's drawing (black 1-pixel lines) instead of the threads as woven.")
def render_cmd(plan, output, size, binary):
    """Draw PLAN as woven: its threads at their real width (the plan's thread_mm on diameter_mm); a colour
    plan in its colours, layer on layer."""
    from .._files import check_not_same_file, check_ours, check_output_path, check_suffix, mark_png, write_atomic
    from ..planner.plan_file import read_plan
    from ..planner.model.render import draw, draw_woven, png_bytes

    if not 16 <= size <= 8001:
        raise BadInput(f"--size {size}; expected 16..8001 pixels")
    check_output_path(output, what="drawing")
    check_not_same_file(output, plan, what="drawing", source_what="plan")
    check_suffix(output, (".png",))
    p = read_plan(plan)
    _refuse_the_source(output, plan, p)
    check_ours(output, "png", what="drawing", instead="give another -o")
    if not p.is_mono:
        from .colour import render_colour
        if binary:
            raise BadInput(f"--binary draws one black thread, but plan {plan!r} has {len(p.colors)} colour "
                           "layer(s); expected no --binary with a colour plan (it is drawn as woven)")
        return render_colour(p, output, size)
    write_atomic(output, mark_png(png_bytes(draw(p, size=size) if binary else draw_woven(p, size=size))),
                 what="drawing")
    m = p.thread_model()
    how = "as 1-pixel lines" if binary else f"as woven ({m.thread_mm:g} mm thread on {m.diameter_mm:g} mm)"
    click.echo(f"{len(p.chord_list())} chords drawn {how} at {size} x {size} -> {output}")


def _refuse_the_source(output, plan_path, plan):
    """Refuse to draw over the picture ``plan`` was made from: by its path (as given, or beside the
    plan) or, wherever it lies, by its content (the plan's ``source.sha256``)."""
    import os

    from .._files import check_not_same_file

    source = plan.source.get("path")
    if source:
        for path in {source, os.path.join(os.path.dirname(plan_path), source)}:
            check_not_same_file(output, path, what="drawing", source_what="plan's source picture")
    sha = plan.source.get("sha256")
    if sha and os.path.isfile(output):
        from .._files import sha256_file

        try:
            same = sha256_file(output) == sha
        except OSError:
            same = False
        if same:
            raise BadInput(f"drawing path {output!r} is the plan's source picture (the same content); "
                           "expected another file")


@cli.command("score")
@click.argument("plan", type=click.Path(path_type=str))
@click.argument("image", required=False, type=click.Path(path_type=str))
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--colour", "colour", is_flag=True,
              help="Score a one-colour plan as a colour plan would be (always so for a colour plan).")
@click.option("--face", "face", is_flag=True,
              help="Also score inside the largest face in IMAGE, found as plan --face finds it: for a plan made "
                   "without --face, to compare it with one made with it (a plan made with --face is always "
                   "scored inside the face box it recorded).")
def score_cmd(plan, image, as_json, colour, face):
    """Score PLAN against IMAGE (default: the plan's source): against the picture's luminance
    (0.2125 R + 0.7154 G + 0.0721 B, as skimage's rgb2gray), and on a second line against the gray the
    plan was made against (its decolorization).

    The paper's SSIM (section 4.1: 1-pixel chords at 1001 px, both at 201 px,
    plain and blurred) with Wang et al.'s 11 x 11 Gaussian window and with
    scikit-image's default 7 x 7 window, and the as-woven error (the plan's
    reference rendering at 512 px: its thread at its real width with a sharp
    edge, converged; against the picture at 512 px, both blurred by sigma 2 px:
    RMS over the frame, gray levels 0..1, lower is better).

    A colour plan (and any plan with --colour) is scored in colour: the mean
    CIEDE2000 between the picture and the plan as woven (both at 512 px,
    blurred by sigma 2 px; lower is better) and the SSIM of their luminances.

    A plan made with --face (and any plan with --face) is also scored inside
    the face box: SSIM as woven there and over the frame.
    """
    import json
    import os

    from ..planner.plan_file import read_plan
    from ..planner.model.scoring import BLUR_SIGMA, SCORE_SIZE, WOVEN_SIZE

    p = read_plan(plan)
    if image is None:
        image = p.source.get("path")
        if not image:
            raise BadInput(f"plan {plan!r} names no source picture; expected an IMAGE argument")
        beside = os.path.join(os.path.dirname(plan), image)
        if not os.path.isabs(image) and not os.path.exists(image) and os.path.exists(beside):
            image = beside  # a relative source path, taken from the plan's folder
    box = _face_box(p, image) if face else None
    if colour or not p.is_mono:
        return _score_colour(p, plan, image, as_json, box=box)
    from ..planner.model.scoring import score_picture

    r = score_picture(p, image, target="luminance", face_box=box)
    if p.source.get("sha256") and p.source["sha256"] != r["source"]["sha256"]:
        log.warning("%s is not the picture the plan was made from (sha256 differs)", image)
    own = score_picture(p, image, target="own") if r["weights"] is not None else r  # a gray picture: one gray
    keys = ("ssim", "ssim_blurred", "ssim_uniform", "ssim_uniform_blurred", "woven_error")
    if as_json:
        click.echo(json.dumps({"plan": plan, "image": image, "method": p.method, "connected": p.connected,
                               "lines": r["lines"], "target": "luminance", **{k: round(r[k], 4) for k in keys},
                               "own_gray": {"weights": own["weights"], **{k: round(own[k], 4) for k in keys}},
                               "blur_sigma": BLUR_SIGMA,
                               **({"face": {k: v if k == "box" else round(v, 4) for k, v in r["face"].items()}}
                                  if "face" in r else {})}))
        return
    w = own["weights"]
    how = "the picture is gray" if w is None else \
        f"{p.parameters.get('gray', 'decolor')} {', '.join(f'{x:.3f}' for x in w)}"
    click.echo(f"{'plan':<10} {plan}\n{'image':<10} {image}\n{'method':<10} "
               f"{p.method}{'' if p.connected else ' (disconnected)'}\n{'lines':<10} {r['lines']}\n"
               f"{'SSIM':<10} {r['ssim']:.4f}   (1-px chords, the whole {SCORE_SIZE} px square, Gaussian 11x11 window; "
               f"scikit-image default 7x7: {r['ssim_uniform']:.4f})\n"
               f"{'blurred':<10} {r['ssim_blurred']:.4f}   (the same at {SCORE_SIZE} px, both blurred sigma "
               f"{BLUR_SIGMA:g} px; 7x7: {r['ssim_uniform_blurred']:.4f})\n"
               f"{'woven':<10} {r['woven_error']:.4f}   (as-woven RMS error at {WOVEN_SIZE} px, 0..1, lower is "
               "better)\n"
               f"{'own gray':<10} SSIM {own['ssim']:.4f} / blurred {own['ssim_blurred']:.4f}, 7x7 "
               f"{own['ssim_uniform']:.4f} / {own['ssim_uniform_blurred']:.4f}, woven {own['woven_error']:.4f}"
               f"   (against the gray the plan was made against: {how})\n"
               f"{_face_line(r, other=f' (the SSIM line: 1-px chords, the whole {SCORE_SIZE} px square)')}"
               "The figures above the last line compare the plan with the picture's luminance (0.2125 R + "
               "0.7154 G + 0.0721 B, as skimage's rgb2gray), for 'woven' the plan drawn as it will hang. "
               "SSIM compares the drawing with the picture, both 201 px (the paper's section 4.1): 1 is "
               "the picture itself, 0 nothing in common; higher is better. 'blurred' compares them after "
               "a blur (sigma 2 px), as the eye sees the painting from afar.")


def _face_box(plan, image):
    """``score --face``: the face box the plan recorded, else the largest face in IMAGE (source pixels)."""
    recorded = (plan.parameters.get("face") or {}).get("box")
    if recorded:
        return recorded
    from ..planner.picture.face import DETECT_SIDE, largest_face
    found = largest_face(image)
    if found is None:
        raise BadInput(f"--face: no face found in {image!r} (the frontal-face cascade finds faces seen from the "
                       f"front, at least {24 / DETECT_SIDE:.0%} of the picture's longer side); expected a picture "
                       "with a face, or score without --face")
    return found.to_record()["box"]


def _face_line(r, *, other=""):
    """The score's line for a plan made with --face: SSIM as woven inside the face box and over the frame,
    its size and blur said (``other``: what tells its frame figure from the ``SSIM`` line's)."""
    if "face" not in r:
        return ""
    from ..planner.model.scoring import WOVEN_SIGMA, WOVEN_SIZE

    f = r["face"]
    y, x, h, w = f["box"]
    return (f"{'face':<10} SSIM as woven at {WOVEN_SIZE} px (Gaussian 11x11 window), plain / blurred sigma "
            f"{WOVEN_SIGMA:g} px: {f['ssim_face']:.4f} / {f['ssim_face_blurred']:.4f} inside the face box "
            f"(rows {y:.0f}-{y + h:.0f}, columns {x:.0f}-{x + w:.0f}); {f['ssim_frame']:.4f} / "
            f"{f['ssim_frame_blurred']:.4f} over the frame only{other}\n")


def _score_colour(p, plan, image, as_json, *, box=None):
    import json

    from .colour import score_colour

    r = score_colour(p, plan, image, face_box=box)
    if as_json:
        face = r.pop("face", None)
        click.echo(json.dumps({"plan": plan, "image": image, "method": p.method, "colors": p.colors,
                               "background": p.background, "lines": r["lines"],
                               **{k: round(v, 4) for k, v in r.items() if k != "lines"},
                               **({"face": {k: v if k == "box" else round(v, 4) for k, v in face.items()}}
                                  if face else {})}))
        return
    click.echo(f"{'plan':<10} {plan}\n{'image':<10} {image}\n{'method':<10} {p.method}\n"
               f"{'threads':<10} {', '.join(p.colors)} on {p.background}\n{'lines':<10} {r['lines']}\n"
               f"{'colour':<10} {r['delta_e']:.2f}   (mean CIEDE2000 as woven, both blurred sigma 2 px at 512 px; "
               "lower is better)\n"
               f"{'SSIM':<10} {r['ssim']:.4f}   (luminance as woven, the whole 512 px square, Gaussian 11x11 window; "
               f"blurred sigma 2 px: {r['ssim_blurred']:.4f})")
    if "face" in r:
        click.echo(_face_line(r, other=" (the SSIM line: the whole square)").rstrip("\n")
                   + f"; colour {r['face']['delta_e_face']:.2f} inside the face box")
