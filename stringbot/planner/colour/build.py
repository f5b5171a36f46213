"""Picture -> colour Plan: threads, layer order, the joint greedy (:mod:`.model`), the plan file's layers.

The threads are the user's (``--colors black,#b22222,...``) or picked from
the picture (``auto:N``, :func:`stringbot.planner.colour.palette.auto_palette`).
The layers are wound in order of their lightness contrast with the board (CIE
L*): the thread nearest the board's lightness first (at the bottom), the one
farthest from it last (on top), where the darkest detail of a picture on a
light board lies;
of the six orders of three threads it was the best or within 0.1 CIEDE2000
of the best on four test pictures (docs/planner.md, "Colour").  A thread
that would lower the error nowhere gets no layer (the plan says so in
``stats.unused``).
"""

import logging
import time

import numpy as np

from ...errors import BadInput
from ..chords import chord_pixels, chord_space
from ..image import read_picture
from .palette import WHITE, auto_palette, hex_to_rgb, to_linear
from ..plan_file import Layer, Plan
from ..progress import report
from ..thread import ThreadModel

log = logging.getLogger(__name__)

__all__ = ["plan_colour", "auto_colour_lines", "layer_order", "COLOUR_DEFAULTS"]

COLOUR_DEFAULTS = {"run": 25, "min_loop": 3, "sample": 1}


def auto_colour_lines(gray, mask, background, colors):
    """The line budget of ``--lines auto`` with colours: the mono rule times the threads, at most 3.

    The mono rule ``500 + 10 (255 - mean gray)`` (section 3.3 of the paper)
    measured from the board: ``500 + 10 x``, ``x`` the mean distance of the
    picture's gray from the board's.  Colour threads are lighter than black and
    each covers only its share of the picture, so a colour plan needs more
    (docs/planner.md, "Colour": the error stops falling near 3 times the mono
    rule on the test pictures).
    """
    board = float(np.dot(hex_to_rgb(background), (0.299, 0.587, 0.114))) * 255.0
    x = float(np.abs(np.asarray(gray, dtype=np.float64)[mask] - board).mean())
    return int(round((500 + 10 * x) * min(len(colors), 3)))


def layer_order(colors, background):
    """Winding order: by lightness contrast with the board (CIE L*), the nearest first (at the bottom)."""
    from .palette import lab

    def contrast(c):
        both = lab(to_linear(np.stack([hex_to_rgb(c), hex_to_rgb(background)])))
        return abs(float(both[0, 0] - both[1, 0]))

    return sorted(colors, key=contrast)


def plan_colour(path, *, colors, background=WHITE, pins=300, frame="circle", size=401, crop=None,
                lines="auto", start_pin=None, model=None, cache=True, run=COLOUR_DEFAULTS["run"],
                sample=COLOUR_DEFAULTS["sample"], order="contrast", picture=None, rng=None):
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
        As for :func:`stringbot.planner.build.plan_picture`.
    start_pin : int, optional
        First pin of the first layer; None (default): each layer starts where
        its best chord does (:func:`stringbot.planner.colour.model.first_pin`).
    model : ThreadModel, optional
        Frame and thread size (default 500 mm, 0.25 mm): how much of a pixel a thread covers.
    cache : bool
        Use the on-disk chord-pixel cache.
    run, sample
        Knobs of :func:`stringbot.planner.colour.model.joint_greedy`.
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
    from ..build import auto_lines, check_knobs, thread_length
    from .model import ColourModel, chord_weights_px, joint_greedy, linear_colors
    from ..fitness import frame_mask

    t0 = time.perf_counter()
    check_knobs(pins=pins, frame=frame, size=size, lines=lines, start_pin=start_pin or 0, method="fitness",
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
    k = (auto_colour_lines(pic.gray, mask, background, colors) if lines == "auto" else int(lines))
    space = chord_space(pins, frame)
    report("chords")
    indptr, indices = chord_pixels(space, size, cache=cache)
    t_setup = time.perf_counter()
    weights = chord_weights_px(space, size, model.width_px(size))
    cm = ColourModel(to_linear(pic.rgb.reshape(-1, 3)), mask.ravel().astype(np.float32),
                     to_linear(hex_to_rgb(background)), linear_colors(colors), nominal=float(np.median(weights)))
    start_err = cm.error()
    report("colour")
    seqs = joint_greedy(space, indptr, indices, cm, weights, k, run=run, sample=sample,
                        start_pins=None if start_pin is None else [start_pin] + [None] * (len(colors) - 1))
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
              "min_loop": COLOUR_DEFAULTS["min_loop"], "mono_lines_rule": auto_lines(pic.gray, mask)}
    stats = {"lines": drawn, "thread_diameters": round(thread_length(space.pin_xy, [c for lay in layers
                                                                                        for c in lay.chords()]), 3),
             "layers": [{"color": lay.color, "lines": len(lay.sequence) - 1,
                         "thread_diameters": round(thread_length(space.pin_xy, lay.chords()), 3)}
                        for lay in layers],
             "unused": unused, "spool_changes": len(layers) - 1,
             "model_error_start": round(start_err, 1), "model_error": round(cm.error(), 1),
             "setup_seconds": round(t_setup - t0, 3), "seconds": round(time.perf_counter() - t0, 3)}
    return Plan.from_layers(layers, background=background, pins=pins, frame=frame, pin_xy=space.pin_xy,
                            crop=pic.crop, method="colour", parameters=params, source=pic.source, stats=stats,
                            diameter_mm=model.diameter_mm, thread_mm=model.thread_mm)
