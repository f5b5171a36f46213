"""Picture -> colour Plan: the threads, the runs (:mod:`.runs`) on the woven piece (:mod:`.model`), the plan's layers.

The threads are the user's (``--colors black,#b22222,...``) or picked from
the picture by what their mixes can reach (``auto:N``,
:func:`stringbot.planner.colour.palette.auto_palette`).  The planner lays
them in runs, a colour coming back as often as the spool-change budget
allows (:func:`stringbot.planner.colour.runs.plan_runs`); each run is a
layer of the plan file, in winding order.  A thread that never lowered the
error gets no run (the plan says so in ``stats.unused``).
"""

import logging
import time

import numpy as np

from ...errors import BadInput
from ..picture.read import LUMINANCE, read_picture
from ..plan_file import Layer, Plan
from ..progress import report
from ..model.thread import ThreadModel
from .palette import WHITE, hex_to_rgb, to_linear
from .reach import auto_palette, bare_share
from .model import FINE, SHARPEN, TEXTURE
from .runs import RUN_DEFAULTS
from .faces import FACE_SHARPEN

log = logging.getLogger(__name__)

__all__ = ["plan_colour", "auto_colour_lines", "COLOUR_DEFAULTS"]

COLOUR_DEFAULTS = {"spool_changes": RUN_DEFAULTS["spool_changes"], "min_run": RUN_DEFAULTS["min_run"], "size": 256,
                   "sharpen": SHARPEN[0], "texture": TEXTURE, "fine": FINE}
#: the draft's fine canvas: samples across a thread (about half a sample: it only orders the colours)
DRAFT_SAMPLES = 0.5
#: the draft's thread is this many times as wide, each of its chords standing for as many of the plan's: a
#: fifth less CPU (chelsea 4.7 -> 3.8 s, coffee 6.8 -> 5.4 s at Prem-Dharshan's counts), the same quality
DRAFT_THICKER = 2.0


def draft_size(size):
    """The draft's grid for a working grid of ``size`` px: half of it, at least 64 px (and at most ``size``)."""
    return min(int(size), max(64, int(size) // 2))
#: most spool changes a plan may be given
MAX_SPOOL_CHANGES = 500


def auto_colour_lines(gray, mask, background, colors):
    """The line budget of ``--lines auto`` with colours: the mono rule times the threads, at most 3.

    The mono rule ``500 + 10 (255 - mean gray)`` (section 3.3 of the paper)
    measured from the board: ``500 + 10 x``, ``x`` the mean distance of the
    picture's gray from the board's.  Colour threads are lighter than black and
    each covers only its share of the picture, so a colour plan needs more
    (docs/planner.md, "Colour").
    """
    board = float(np.dot(hex_to_rgb(background), (0.299, 0.587, 0.114))) * 255.0
    x = float(np.abs(np.asarray(gray, dtype=np.float64)[mask] - board).mean())
    return int(round((500 + 10 * x) * min(len(colors), 3)))


def plan_colour(path, *, colors, background=WHITE, pins=300, frame="circle", size=COLOUR_DEFAULTS["size"], crop=None,
                lines="auto", start_pin=None, model=None, cache=True, spool_changes=COLOUR_DEFAULTS["spool_changes"],
                min_run=COLOUR_DEFAULTS["min_run"], weight=None, picture=None, rng=None, face="off",
                sharpen=COLOUR_DEFAULTS["sharpen"], texture=COLOUR_DEFAULTS["texture"], fine=COLOUR_DEFAULTS["fine"]):
    """Plan a colour thread painting.

    Parameters
    ----------
    path : str or Path
        The picture.
    colors : list of str or ("auto", int)
        Threads (``"#rrggbb"``) or ``("auto", n)`` (:func:`stringbot.planner.colour.palette.parse_colors`).
    background : str
        The board, ``"#rrggbb"``.
    pins, frame, size, crop, lines
        As for :func:`stringbot.planner.build.plan_picture` (``size``: the working grid).
    start_pin : int, optional
        First pin of the first run; None (default): where its best chord is.
    model : ThreadModel, optional
        Frame and thread size (default 500 mm, 0.25 mm): how much of a pixel a thread covers.
    cache : bool
        Use the on-disk chord-pixel cache.
    spool_changes : int
        Most spool changes (runs - 1); the colours come back in runs within it.
    min_run : int
        Fewest chords of a run before the spool may change.
    weight : ndarray of float, shape (size, size), optional
        Importance of each pixel (1: as any; 0 outside the frame is applied anyway).
    picture : Picture, optional
        An already read picture (with ``rgb``).
    rng : None, int or numpy Generator
        Seeds the pixel sample of ``auto`` colours (None: a fixed seed).
    face : {"off", "auto", "on"}
        Keep the largest face in the crop (unless ``crop`` is given) and weigh it more, as for a
        one-thread plan (:func:`stringbot.planner.build.read_for_plan`); ``on`` refuses a picture
        without a face.
    sharpen : float
        The threads are laid against the picture sharpened by this much (:func:`.model.sharpened`; 0: as
        it is); the threads are picked from the picture as it is.
    texture : float
        The weight of each pixel's texture (its variance of luminance over its samples) in the plan's
        error (:class:`.model.Piece`; 0: the mean colour alone); the draft orders the colours without it,
        and on a dark board (luminance under a half) the plan too.
    fine : float
        The weight of the fine luminance (:class:`.model.Fine`: the picture's luminance matched on a grid
        twice as fine as ``size``; 0: none); in the plan only, and not on a dark board.

    Returns
    -------
    Plan
        A version 2 plan (unless one black layer on white).
    """
    from ..knobs import auto_lines, check_knobs
    from ..model.chords import chord_pixels, chord_space, frame_mask, thread_length
    from ..picture.resample import resize_square
    from .model import Fine, Piece, chord_weights_px, linear_colors, luminance, sharpened
    from .runs import Runner, plan_runs

    t0 = time.perf_counter()
    check_knobs(pins=pins, frame=frame, size=size, lines=lines, start_pin=start_pin or 0, method="fitness",
                alpha=0.0, beta=None, gamma=None, T=None, epsilon=0, iterations=1, style=None)
    if not (isinstance(spool_changes, int) and 0 <= spool_changes <= MAX_SPOOL_CHANGES):
        raise BadInput(f"--spool-changes {spool_changes!r}; expected 0..{MAX_SPOOL_CHANGES}")
    if not (isinstance(min_run, int) and min_run >= 1):
        raise BadInput(f"--min-run {min_run!r}; expected a number of lines >= 1")
    model = model or ThreadModel()
    report("reading the picture")
    found = None
    if picture is None and face != "off":
        from ..picture.face import crop_on_face, face_for_plan

        found = face_for_plan(path, face=face)
        if found is not None and crop is None:
            crop = crop_on_face(path, found)
    pic = picture or read_picture(path, size=size, crop=crop, gray="luminance", rng=rng)
    plain = weight              # the draft's weights: without the face's (the colours' order and shares by the frame)
    if found is not None:       # --face: the face weighs more (times any weight given)
        from ..picture.face import face_weights

        weight = face_weights(found, crop=pic.crop, size=size, gray=pic.gray, times=weight)
    mask = frame_mask(size, frame)
    requested = colors
    space = chord_space(pins, frame)
    picked = None
    if isinstance(colors, tuple) and colors[0] == "auto":
        report("picking threads")
        k = (auto_colour_lines(pic.gray, mask, background, range(colors[1])) if lines == "auto" else int(lines))
        mean_chord = float(np.linalg.norm(space.pin_xy[space.ends[:, 0]] - space.pin_xy[space.ends[:, 1]],
                                          axis=1).mean())
        picked = auto_palette(pic.rgb, colors[1], background=background, mask=mask, rng=rng,
                              candidates=colors[2] if len(colors) > 2 else None,
                              bare=bare_share(k, mean_chord, model.fraction, frame))
        colors = picked.colors
    colors = list(colors)
    k = (auto_colour_lines(pic.gray, mask, background, colors) if lines == "auto" else int(lines))
    report("chords")
    board, lin = to_linear(hex_to_rgb(background)), linear_colors(colors)

    def weights_at(grid, weight):
        """The pixel weights on a ``grid``-px grid: the frame, times ``weight`` if given."""
        w = frame_mask(grid, frame).astype(np.float64)
        if weight is not None:
            w = w * (np.asarray(weight, dtype=np.float64) if grid == size else
                     resize_square(np.asarray(weight, dtype=np.float64), grid))
        return w

    memo = {}

    def runner(grid, rgb, *, samples=1.0, thicker=1.0, texture=None, fine=0.0, weight=weight, share=False):
        """A :class:`Runner` on a ``grid``-px working grid (the picture ``rgb`` read at that size, ``weight``
        the pixel weights: the face's too by default; ``share``: the chords, the fine grid's picture and the
        fans of the runner made before with ``share`` on the same grid)."""
        key = (grid, thicker, bool(fine))
        if share and key in memo:
            indptr, indices, weights, chords2, gray2, like = memo[key]
        else:
            like = gray2 = chords2 = None
            indptr, indices = chord_pixels(space, grid, cache=cache)
            weights = chord_weights_px(space, grid, model.width_px(grid) * thicker)
            if fine:             # the picture's luminance on a grid twice as fine, and the chords there
                two = 2 * grid
                chords2 = (*chord_pixels(space, two, cache=cache),
                           chord_weights_px(space, two, model.width_px(two) * thicker))
                rgb2 = read_picture(path, size=two, crop=pic.crop, gray="luminance").rgb if picture is None else \
                    np.stack([resize_square(pic.rgb[..., c], two) for c in range(3)], axis=-1)
                gray2 = rgb2.reshape(-1, 3) @ np.asarray(LUMINANCE, dtype=np.float64)
        fine_grid = None if not fine else Fine(gray2, (weights_at(2 * grid, weight) * fine).ravel(),
                                               float(np.median(chords2[2])))
        piece = Piece(to_linear(rgb.reshape(-1, 3)), weights_at(grid, weight).ravel(), board, lin, space.pin_xy,
                      model.width_px(grid) * thicker, nominal=float(np.median(weights)), samples=samples,
                      texture=texture, fine=fine_grid)
        out = Runner(space, indptr, indices, weights, piece, fine=chords2, like=like)
        if share and key not in memo:
            memo[key] = (indptr, indices, weights, chords2, gray2, out)
        return out

    if not (isinstance(sharpen, (int, float)) and 0 <= sharpen <= 10):
        raise BadInput(f"sharpen {sharpen!r}; expected 0..10")
    for what, v in (("texture", texture), ("fine", fine)):
        if not (isinstance(v, (int, float)) and 0 <= v <= 1e6):
            raise BadInput(f"{what} {v!r}; expected 0..1000000")
    target = sharpened(pic.rgb, amount=float(sharpen), sigma=SHARPEN[1])
    grid = draft_size(size)
    # the texture term is measured on light boards; on a dark one it stopped a light thread's moon at night after
    # 8 lines (tests/test_outputs_ours.py): there the mean colour alone (and the plan records the weight used)
    light = float(luminance(board)) >= 0.5
    texture, fine = (float(texture), float(fine)) if light else (0.0, 0.0)
    face_target = None
    if found is not None and FACE_SHARPEN:  # --face: the plan's target (not the draft's) sharpened more over the face
        from .faces import face_share

        face_target = sharpened(pic.rgb, amount=float(sharpen) + FACE_SHARPEN * face_share(weight, plain),
                                sigma=SHARPEN[1])
    # --face: the plan without the face and the plans with it laid on the draft's schedule, one kept by the
    # planner's estimate of the score (.faces; it needs the fine luminance's cells)
    with_face, face_plan = found is not None and grid != size and fine > 0, None
    if with_face:
        from .faces import lay_with_face
        from .runs import draft_schedule, follow
        from ..picture.face import face_weights

        def lay(strength, n, schedule):
            """The runs of ``schedule`` laid for ``n`` lines, the face's extra weight ``strength`` (None: none)."""
            if strength is None:
                r = runner(size, target, texture=texture, fine=fine, weight=plain, share=True)
            else:
                w = face_weights(found, crop=pic.crop, size=size, gray=pic.gray, times=plain, strength=strength)
                r = runner(size, target if face_target is None else face_target, texture=texture, fine=fine,
                           weight=w, share=True)
            r.start_error = r.piece.error()
            r.runs = follow(r, n, schedule, first=start_pin)
            return r
    else:
        work = runner(size, target if face_target is None else face_target, texture=texture, fine=fine)
        start_err = work.piece.error()
    t_setup = time.perf_counter()
    report("colour")
    if grid == size:
        runs = plan_runs(work, None, k, spool_changes=spool_changes, min_run=min_run, first=start_pin)
    else:
        rgb = np.stack([resize_square(target[..., c], grid) for c in range(3)], axis=-1)
        # the draft orders the colours by their mean alone (the texture there changed the order, not the SSIM),
        # and without the face's weights (--face: the schedule they gave cost the frame, Grace Hopper's blurred
        # SSIM -0.034 -> +0.005 against the plan without --face; docs/planner.md, "Faces", "In colour")
        draft = runner(grid, rgb, samples=DRAFT_SAMPLES, thicker=DRAFT_THICKER, texture=0.0, weight=plain)
        if with_face:
            _, schedule = draft_schedule(draft, k, spool_changes=spool_changes, min_run=min_run,
                                         thicker=DRAFT_THICKER)
            work, face_plan = lay_with_face(lay, k, schedule, box=found.to_record()["box"], crop=pic.crop,
                                            frame=frame, auto_lines=lines == "auto")
            runs = work.runs
            start_err = work.start_error
        else:
            runs = plan_runs(draft, lambda: work, k, spool_changes=spool_changes, thicker=DRAFT_THICKER,
                             min_run=min_run, first=start_pin)
    layers = [Layer(colors[c], seq) for c, seq in runs if len(seq) >= 2]
    used = {lay.color for lay in layers}
    unused = [c for c in colors if c not in used]
    if not layers:
        raise BadInput("no thread of --colors lowers the colour error anywhere: the picture looks like the "
                       f"board ({background}) already; expected a picture that differs from the board")
    drawn = sum(len(lay.sequence) - 1 for lay in layers)
    if drawn < k:
        log.info("colour: stopped after %d of %d lines (no chord lowers the error)", drawn, k)
    params = {"pins": pins, "frame": frame, "size": size, "crop": pic.crop, "lines": lines, "lines_target": k,
              "start_pin": start_pin, "method": "colour",
              "colors_requested": (f"auto:{requested[1]}" + (":" + ",".join(requested[2]) if len(requested) > 2 else "")
                                   if isinstance(requested, tuple) else list(requested)),
              "colors": colors, "background": background, "spool_changes": spool_changes, "min_run": min_run,
              "draft_size": draft_size(size), "sharpen": float(sharpen),
              "texture": texture, "fine": fine, "face": found and found.to_record(),
              **({"face_sharpen": FACE_SHARPEN} if found is not None else {}),
              **({"face_plan": face_plan} if face_plan is not None else {}),
              "mono_lines_rule": auto_lines(pic.gray, mask)}
    per_colour = {c: {"lines": sum(len(lay.sequence) - 1 for lay in layers if lay.color == c),
                      "thread_diameters": round(thread_length(space.pin_xy, [ch for lay in layers if lay.color == c
                                                                             for ch in lay.chords()]), 3)}
                  for c in colors if c in used}
    stats = {"lines": drawn, "thread_diameters": round(thread_length(space.pin_xy, [c for lay in layers
                                                                                        for c in lay.chords()]), 3),
             "layers": [{"color": lay.color, "lines": len(lay.sequence) - 1,
                         "thread_diameters": round(thread_length(space.pin_xy, lay.chords()), 3)}
                        for lay in layers],
             "colors": per_colour, "unused": unused,
             **({"palette": {"reach": picked.reach, "bare": round(picked.bare, 3), "why_fewer": picked.why_fewer}}
                if picked is not None else {}), "runs": len(layers), "spool_changes": len(layers) - 1,
             "model_error_start": round(start_err, 1), "model_error": round(work.piece.error(), 1),
             "setup_seconds": round(t_setup - t0, 3), "seconds": round(time.perf_counter() - t0, 3)}
    # pin_xy as the plan file holds it (6 decimals): the preview drawn from this plan is the one any reader draws
    return Plan.from_layers(layers, background=background, pins=pins, frame=frame, pin_xy=np.round(space.pin_xy, 6),
                            crop=pic.crop, method="colour", parameters=params, source=pic.source, stats=stats,
                            diameter_mm=model.diameter_mm, thread_mm=model.thread_mm)
