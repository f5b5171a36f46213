"""What a planning command checks before it works, shared by ``plan`` (one thread or colour) and ``calibrate``:
the outputs it may write, and a default crop that keeps little of the picture."""

import click

from ..errors import BadInput

__all__ = ["warn", "warn_small_crop", "check_plan_outputs", "refuse_a_wound_plan", "MIN_CROP_SHARE"]


#: The default crop (the largest centred square) warns when it keeps less than this share of the picture.
MIN_CROP_SHARE = 0.5


def warn(text):
    """One warning line on standard error: the command goes on."""
    click.echo(f"stringbot: warning: {text}", err=True)


#: side of the preview `plan` writes (as woven; a colour plan's too)
PREVIEW_SIZE = 1001


def warn_small_crop(image, *, fit=True):
    """Warn when the default crop keeps less than :data:`MIN_CROP_SHARE` of ``image`` (a panorama or a
    strip: its centre only), naming ``--fit`` (where the command has it) and ``--crop``."""
    from ..planner.picture.read import default_crop_share

    share, (w, h) = default_crop_share(image)
    if share >= MIN_CROP_SHARE:
        return
    side = min(w, h)
    other = "--fit paints all of it (letterboxed), --crop CX,CY,R another part" if fit else \
        "--crop CX,CY,R picks another part"
    warn(f"the frame takes only the centre of the picture: {side} x {side} of its {w} x {h} pixels "
         f"({100 * share:.0f} %); {other}")


def check_plan_outputs(output, preview, *, sources, force, lines):
    """Refuse, before any work, outputs that cannot be written or would destroy something: a
    plan or preview path that is not a regular file, one that is a ``sources`` file
    (``(path, name)`` pairs), a preview that is the plan, a preview not named .png, a file
    stringbot did not write as a plan (preview) there, a plan that a journal is winding
    (unless ``force``), and a non-positive ``lines``."""
    import os

    from .._files import check_not_same_file, check_ours, check_output_path, check_suffix

    check_output_path(output, what="plan")
    check_output_path(preview, what="preview")
    for out, what in ((output, "plan"), (preview, "preview")):
        for src, name in sources:
            if src:
                check_not_same_file(out, src, what=what, source_what=name)
    check_not_same_file(preview, output, what="preview", source_what="plan")
    default = preview == os.path.splitext(output)[0] + ".png"
    if not default:
        check_suffix(preview, (".png",), option="--preview")
    check_ours(output, "plan", what="plan", instead="give another -o")
    check_ours(preview, "png", what="preview",
               instead="it is the preview's default path (the plan's name with .png): give --preview OTHER.png"
               if default else "give another --preview")
    if not force:
        refuse_a_wound_plan(output)
    if lines != "auto" and lines <= 0:
        raise BadInput(f"--lines {lines}; expected a positive number or auto")


def refuse_a_wound_plan(output):
    """A plan whose journal has steps done is what a machine is (or was) winding: keep it; and one
    whose by-hand position has steps done, what a maker is (or was) winding by hand."""
    from ..winding.by_hand import position_path_for, read_position
    from ..winding.journal import journal_path_for, read_journal

    position = position_path_for(output)
    try:
        saved = read_position(position)
    except BadInput:
        saved = None                   # not a position we can read: nothing of ours to protect
    if saved is not None and saved.done:
        where = "finished" if saved.done >= saved.steps else f"{saved.done} of {saved.steps} steps done"
        raise BadInput(f"plan {output!r} has a by-hand position {position!r} ({where}); overwriting the plan "
                       "would orphan it: give another -o, or --force")

    journal = journal_path_for(output)
    if not journal.is_file():
        return
    try:
        state = read_journal(journal)
    except BadInput:
        return                         # not a journal we can read: nothing of ours to protect
    if state.done:
        where = "finished" if state.finished else f"{len(state.done)} of {state.steps_total} steps done"
        raise BadInput(f"plan {output!r} has a winding journal {str(journal)!r} ({where}); overwriting the plan "
                       "would orphan it: give another -o, or --force")


def face_found_line(p, *, centred):
    """Say where the face of a plan made with ``--face`` was found (nothing without one)."""
    if p.parameters.get("face"):
        r, c, h, w = p.parameters["face"]["box"]
        weighed = ("greedy weighs every pixel alike (the face is only kept in the crop)"
                   if getattr(p, "method", None) == "greedy" else "the face weighs three times as much in the planner's error")
        click.echo(f"face: found at rows {r:.0f}-{r + h:.0f}, columns {c:.0f}-{c + w:.0f} of the picture; "
                   f"{'the crop holds it, ' if centred else ''}{weighed}")
