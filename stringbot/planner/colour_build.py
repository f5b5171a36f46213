"""Picture -> colour Plan: threads, layer order, the joint greedy (:mod:`.colour`), the plan file's layers.

The threads are the user's (``--colors black,#b22222,...``) or picked from
the picture (``auto:N``, :func:`stringbot.planner.palette.auto_palette`).
The layers are wound in order of their contrast with the board: the thread
nearest the board's colour first (at the bottom), the one farthest from it
last (on top), where the finest dark detail of a light board's picture
should lie (see docs/planner.md, "Colour", for the measurements).  A thread
that would lower the error nowhere gets no layer (the plan says so in
``stats.unused``).
"""

import logging
import time

import numpy as np

from ..errors import BadInput
from .chords import chord_pixels, chord_space
from .image import read_picture
from .palette import WHITE, auto_palette, delta_e, hex_to_rgb, to_linear
from .plan_file import Layer, Plan
from .progress import report
from .thread import ThreadModel

log = logging.getLogger(__name__)

__all__ = ["plan_colour", "auto_colour_lines", "layer_order", "COLOUR_DEFAULTS"]

COLOUR_DEFAULTS = {"run": 25, "min_loop": 3, "sample": 2}


def auto_colour_lines(rgb, mask, background, colors):
    """The line budget for ``--lines auto`` with colours: see docs/planner.md ("Colour").

    ``k = 500 + 10 x`` where ``x`` is the picture's mean distance from the
    board in CIE L* units times 2.55 (on a white board, ``255 - mean gray`` of
    the mono rule), times the number of threads' share: ``(1 + (n - 1) / 2)``.
    """
    from skimage.color import rgb2lab

    lum = rgb2lab(np.asarray(rgb, dtype=np.float64))[..., 0][mask]
    board = rgb2lab(hex_to_rgb(background)[None, None])[0, 0, 0]
    x = 2.55 * float(np.abs(lum - board).mean())
    return int(round((500 + 10 * x) * (1 + (len(colors) - 1) / 2)))


def layer_order(colors, background):
    """Winding order: the thread nearest the board first (bottom), the farthest last (top)."""
    return sorted(colors, key=lambda c: delta_e(c, background))


def plan_colour(path, *, colors, background=WHITE, pins=300, frame="circle", size=401, crop=None,
                lines="auto", start_pin=0, model=None, cache=True, run=COLOUR_DEFAULTS["run"],
                sample=COLOUR_DEFAULTS["sample"], order="contrast", picture=None, rng=None):
    """Plan a colour thread painting.

    Parameters
    ----------
    path : str or Path
        The picture.
    colors : list of str or ("auto", int)
        Threads (``"#rrggbb"``) or ``("auto", n)`` (:func:`stringbot.planner.palette.parse_colors`).
    background : str
        The board, ``"#rrggbb"``.
    pins, frame, size, crop, lines, start_pin
        As for :func:`stringbot.planner.build.plan_picture`.
    model : ThreadModel, optional
        Frame and thread size (default 500 mm, 0.25 mm): how much of a pixel a thread covers.
    cache : bool
        Use the on-disk chord-pixel cache.
    run, sample
        Knobs of :func:`stringbot.planner.colour.joint_greedy`.
    order : {"contrast", "given"}
        Layer order: by contrast with the board, or as ``colors`` lists them.
    picture : Picture, optional
        An already read picture (with ``rgb``).
    rng : None, int or numpy Generator
        Seeds the pixel sample of ``auto`` colours (None: a fixed seed).

    Returns
    -------
    Plan
        A version 2 plan (unless one black layer on white).
    """
    from .build import auto_lines, check_knobs, thread_length
    from .colour import ColourModel, chord_weights_px, joint_greedy, linear_colors
    from .fitness import frame_mask

    t0 = time.perf_counter()
    check_knobs(pins=pins, frame=frame, size=size, lines=lines, start_pin=start_pin, method="fitness",
                alpha=0.0, beta=None, gamma=None, T=None, epsilon=0, iterations=1, style=None)
    if order not in ("contrast", "given"):
        raise ValueError(f"order {order!r}; expected 'contrast' or 'given'")
    model = model or ThreadModel()
    report("reading the picture")
    pic = picture or read_picture(path, size=size, crop=crop, gray="luminance", rng=rng)
    mask = frame_mask(size, frame)
    requested = colors
    if isinstance(colors, tuple) and colors[0] == "auto":
        report("picking threads")
        colors = auto_palette(pic.rgb, colors[1], background=background, mask=mask, rng=rng)
    colors = list(colors)
    if order == "contrast":
        colors = layer_order(colors, background)
    k = (auto_colour_lines(pic.rgb, mask, background, colors) if lines == "auto" else int(lines))
    space = chord_space(pins, frame)
    report("chords")
    indptr, indices = chord_pixels(space, size, cache=cache)
    t_setup = time.perf_counter()
    weights = chord_weights_px(space, size, model.width_px(size))
    cm = ColourModel(to_linear(pic.rgb.reshape(-1, 3)), mask.ravel().astype(np.float32),
                     to_linear(hex_to_rgb(background)), linear_colors(colors))
    start_err = cm.error()
    report("colour")
    seqs = joint_greedy(space, indptr, indices, cm, weights, k, run=run, start_pins=[start_pin] * len(colors),
                        sample=sample)
    layers = [Layer(c, s) for c, s in zip(colors, seqs) if len(s) >= 2]
    unused = [c for c, s in zip(colors, seqs) if len(s) < 2]
    if not layers:
        raise BadInput("no thread of --colors lowers the colour error anywhere: the picture looks like the "
                       f"board ({background}) already; expected a picture that differs from the board")
    drawn = sum(len(lay.sequence) - 1 for lay in layers)
    if drawn < k:
        log.info("colour: stopped after %d of %d lines (no chord lowers the error)", drawn, k)
    params = {"pins": pins, "frame": frame, "size": size, "crop": pic.crop, "lines": lines, "lines_target": k,
              "start_pin": start_pin, "method": "colour",
              "colors_requested": (f"auto:{requested[1]}" if isinstance(requested, tuple) else list(requested)),
              "colors": colors, "background": background, "order": order, "run": run, "sample": sample,
              "min_loop": COLOUR_DEFAULTS["min_loop"], "diameter_mm": model.diameter_mm,
              "thread_mm": model.thread_mm, "mono_lines_rule": auto_lines(pic.gray, mask)}
    stats = {"lines": drawn, "thread_diameters": round(thread_length(space.pin_xy, [c for lay in layers
                                                                                        for c in lay.chords()]), 3),
             "layers": [{"color": lay.color, "lines": len(lay.sequence) - 1,
                         "thread_diameters": round(thread_length(space.pin_xy, lay.chords()), 3)}
                        for lay in layers],
             "unused": unused, "spool_changes": len(layers) - 1,
             "model_error_start": round(start_err, 1), "model_error": round(cm.error(), 1),
             "setup_seconds": round(t_setup - t0, 3), "seconds": round(time.perf_counter() - t0, 3)}
    return Plan.from_layers(layers, background=background, pins=pins, frame=frame, pin_xy=space.pin_xy,
                            crop=pic.crop, method="colour", parameters=params, source=pic.source, stats=stats)
