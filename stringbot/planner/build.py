"""Picture -> Plan: checks the knobs, runs the chosen method, records everything.

Methods (the registry: :mod:`stringbot.planner.methods`)
-------
``residual`` (default)
    Chords chosen by what the picture as woven still lacks, refined, then
    polished against the piece as the eye sees it (docs/planner.md).
``fitness``
    The paper's method: chord space, regularised least-squares fitness,
    connected sampling with error diffusion (or, ``disconnected=True``, the
    priority-queue chord set).  Its knobs beta, gamma and T come in two
    *styles*: ``detail`` (the paper's defaults, 5 / 10 / 30) and ``fill``
    (regularisation 30 times stronger and a sharp mapping, T = 1: a chord's
    fitness is then close to its weighted mean darkness and next to no error
    is diffused, so large flat dark areas are filled).  ``auto`` (the
    default) plans both and keeps the drawing that scores higher by the
    paper's own measure (section 4.1: SSIM plain plus blurred, with both the
    Gaussian and the uniform window, summed, so that no one variant decides;
    see :mod:`stringbot.planner.model.scoring`).  Giving beta, gamma or T
    means ``detail`` with those values.
``greedy``
    The ThreadTone baseline (see :mod:`stringbot.planner.methods.greedy`).
"""

import logging
import math
import time

import numpy as np

from ..errors import BadInput
from .model.chords import chord_space, pixel_chords
from .picture.read import read_mask, read_picture
from .methods import DEFAULT_METHOD, Job, get_method, methods_taking
from .plan_file import Plan
from .progress import report

log = logging.getLogger(__name__)

__all__ = ["plan_picture", "auto_lines", "check_knobs", "style_candidates", "thread_model", "DEFAULTS", "FILL", "STYLES",
           "MAX_PINS"]

#: The paper's defaults (section 4); alpha: see docs/planner.md ("alpha").  beta, gamma and T are
#: those of the ``detail`` style; ``fill`` uses :data:`FILL`.
DEFAULTS = {"pins": 300, "size": 401, "alpha": 0.0, "beta": 5.0, "gamma": 10.0, "T": 30.0, "epsilon": 2,
            "iterations": 25, "refine": 300, "polish": 1000, "greedy_weight": 15.0, "greedy_width": 3, "greedy_min_loop": 3,
            "greedy_reference_radius": 500.0}
MAX_PINS = 2000
MIN_SIZE, MAX_SIZE = 32, 2001
MAX_LINES = 100_000
STYLES = ("auto", "detail", "fill")
#: Points per frame side at which the residual choice samples each chord: a plan with a line count is
#: judged pixel by pixel at the working size (every pixel at 401 px); the first draft of a plan to be
#: polished needs half as many (the polish reworks it against the piece as woven, scoring chords every
#: 1/128 of the frame): 0.1-0.2 s less, as-woven error within 1 % (docs/planner.md, "Speed").
CHOOSE_POINTS, CHOOSE_POINTS_POLISHED = 400, 200
#: The ``fill`` style: the paper's regularisation weights times 30 and a sharp tanh.
FILL = {"beta": 150.0, "gamma": 300.0, "T": 1.0}
#: Mean gray (0..255) inside the frame below which a picture is too dark for black thread on a white
#: board: the thread would have to cover more than 90 % of it (a black disc; all-black runs to the line
#: cap, 60000 lines, 13 km).  The sample pictures' means are 103-148, a night photo at 15 % of the
#: camera's 19; at 30 % (37) it plans in 3600 lines.
MIN_MEAN_GRAY = 25.5


def auto_lines(gray, mask):
    """``k = 500 + 10 (255 - mean gray)`` over the pixels of the frame (section 3.3)."""
    return int(round(500 + 10 * (255.0 - float(np.asarray(gray)[mask].mean()))))


def check_knobs(*, pins, frame, size, lines, start_pin, method, alpha, beta, gamma, T, epsilon, iterations,
                style="auto"):
    """Raise BadInput naming the first knob out of range (None: a knob not given)."""
    if frame not in ("circle", "square"):
        raise BadInput(f"--frame {frame!r}; expected circle or square")
    get_method(method)
    if style is not None and style not in STYLES:
        raise BadInput(f"--style {style!r}; expected one of {', '.join(STYLES)}")
    if not MIN_SIZE <= size <= MAX_SIZE:
        raise BadInput(f"--size {size}; expected {MIN_SIZE}..{MAX_SIZE} pixels")
    top = min(MAX_PINS, 2 * size)
    if not 3 <= pins <= top:
        raise BadInput(f"--pins {pins}; expected 3..{top} (at --size {size})")
    if lines != "auto" and not 1 <= lines <= MAX_LINES:
        raise BadInput(f"--lines {lines}; expected 1..{MAX_LINES} or auto")
    if not 0 <= start_pin < pins:
        raise BadInput(f"--start-pin {start_pin}; expected 0..{pins - 1}")
    for name, value, ok, expected in (
            ("--alpha", alpha, lambda x: 0 <= x <= 1, "0..1"),
            ("--beta", beta, lambda x: x >= 0, ">= 0"),
            ("--gamma", gamma, lambda x: x >= 0, ">= 0"),
            ("-T/--sharpness", T, lambda x: x > 0, "> 0"),
            ("--epsilon", epsilon, lambda x: 0 <= x <= 1000, "0..1000 pins"),
            ("--iterations", iterations, lambda x: 1 <= x <= 10_000, "1..10000")):
        if value is not None and not (math.isfinite(value) and ok(value)):
            raise BadInput(f"{name} {value}; expected {expected}")
    given = [name for name, value in (("--beta", beta), ("--gamma", gamma), ("-T", T)) if value is not None]
    if style == "fill" and given:
        raise BadInput(f"--style fill sets beta, gamma and T itself, but {', '.join(given)} was given; "
                       "expected --style detail (or no --style) with them")


def thread_model(diameter_mm=None, thread_mm=None):
    """The :class:`~stringbot.planner.model.thread.ThreadModel` of the options; BadInput naming the one out of range."""
    from .model.thread import DEFAULT_DIAMETER_MM, DEFAULT_THREAD_MM, ThreadModel

    d = DEFAULT_DIAMETER_MM if diameter_mm is None else diameter_mm
    t = DEFAULT_THREAD_MM if thread_mm is None else thread_mm
    for name, v, top in (("--diameter-mm", d, 100_000.0), ("--thread-mm", t, 100.0)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= top):
            raise BadInput(f"{name} {v:g}; expected millimetres, a number > 0 and <= {top:g}")
    if t * 20 > d:
        raise BadInput(f"--thread-mm {t:g} is more than a 20th of --diameter-mm {d:g}; "
                       "expected a thread much thinner than the frame")
    return ThreadModel(diameter_mm=float(d), thread_mm=float(t))


def style_candidates(style, *, beta=None, gamma=None, T=None):
    """The fitness knob settings to try.

    Parameters
    ----------
    style : {"auto", "detail", "fill"} or None
        None is ``auto``.
    beta, gamma, T : float or None
        Knobs given by the user (None: not given).

    Returns
    -------
    list of (str, dict)
        ``[(style name, {"beta": float, "gamma": float, "T": float}), ...]``:
        both styles for ``auto``, unless beta, gamma or T is given (then
        ``detail`` with those values and the paper's defaults for the rest).
    """
    given = {k: v for k, v in (("beta", beta), ("gamma", gamma), ("T", T)) if v is not None}
    detail = {k: float(given.get(k, DEFAULTS[k])) for k in ("beta", "gamma", "T")}
    if style == "fill":
        return [("fill", dict(FILL))]
    if style == "detail" or given:
        return [("detail", detail)]
    if style not in (None, "auto"):
        raise ValueError(f"style {style!r}; expected one of {STYLES}")
    return [("detail", detail), ("fill", dict(FILL))]


def check_not_too_dark(gray, mask):
    """Refuse a picture too dark for black thread on white (mean gray below :data:`MIN_MEAN_GRAY`
    inside the frame ``mask``), as a blank one is refused: one line, naming light thread on a dark board.

    Parameters
    ----------
    gray : ndarray, shape (size, size)
        The picture at the working size, 0 (black) .. 255.
    mask : ndarray of bool, shape (size, size)
    """
    mean = float(np.asarray(gray)[mask].mean()) if mask.any() else 255.0
    if mean < MIN_MEAN_GRAY:
        raise BadInput(f"the picture is too dark to plan in black thread on white: its mean gray inside the "
                       f"frame is {mean:.0f} of 255, so the thread would cover {100 * (1 - mean / 255):.0f} % "
                       "of the board; expected a lighter picture, or light thread on a dark board: "
                       "--colors white --background black")


def thread_length(pin_xy, chords):
    """Total chord length in ring diameters (the side for a square frame)."""
    if not len(chords):
        return 0.0
    c = np.asarray(chords)
    return float(np.linalg.norm(pin_xy[c[:, 0]] - pin_xy[c[:, 1]], axis=1).sum())


def plan_picture(path, *, pins=300, frame="circle", size=None, crop=None, lines="auto", start_pin=None,
                 method=DEFAULT_METHOD, disconnected=False, importance=None, gray=None, style=None,
                 alpha=DEFAULTS["alpha"], beta=None, gamma=None, T=None,
                 epsilon=DEFAULTS["epsilon"], iterations=DEFAULTS["iterations"], cache=True, rng=None,
                 picture=None, reference=None, greedy_reference_radius=DEFAULTS["greedy_reference_radius"],
                 diameter_mm=None, thread_mm=None, fit=False, refine=None, polish=None, preview=None):
    """Plan a thread painting of a picture.

    Parameters
    ----------
    path : str or Path
        The picture.
    pins, frame, size, crop, lines, start_pin, method, disconnected, importance, gray,
    alpha, epsilon, iterations
        The knobs (see ``stringbot plan --help`` and docs/planner.md).  ``size``
        None: 1001 for greedy (ThreadTone's own), else 401; ``gray`` None:
        decolor for fitness (the paper's), else luminance (greedy: with
        ThreadTone's weights, ``cv2.COLOR_BGR2GRAY``'s).  ``start_pin`` None:
        ``pins // 4`` for greedy (ThreadTone's pin 0 faces right), the pin of
        the best chord for residual (recorded in the plan), else 0;
        greedy's default crop is ThreadTone's square (whole-pixel offsets).
    style : {"auto", "detail", "fill"} or None
        Fitness only: which setting of beta, gamma and T (see the module
        notes); None is ``auto``.
    beta, gamma, T : float or None
        Fitness only: None for the style's values; any given means ``detail``.
    cache : bool
        Use the on-disk chord-pixel cache.
    rng : None, int or numpy Generator
        Randomness of the decolorization (None: a fixed seed).
    picture : Picture, optional
        An already read picture (skips reading ``path``).
    reference : Picture, optional
        With ``picture``: the picture as ``stringbot score`` reads it (at
        201 px), to compare the styles against; without it they are compared
        against ``picture`` itself.  Without ``picture`` it is read from ``path``.
    greedy_reference_radius : float or None
        Greedy only: the picture radius at which its weight of 15 holds
        (ThreadTone's 500); None applies 15 at the working size as it is.
    diameter_mm, thread_mm : float or None
        The frame's diameter and the thread's width (None: 500 mm and
        0.25 mm), recorded in the plan; the default method plans with them.
    fit : bool
        Crop the whole picture, letterboxed (white around it), instead of the
        largest centred circle; conflicts with ``crop``.
    refine : int or None
        Residual only: pins the pixel refinement revisits (0: none); None:
        300 when there is no polish, else 0 (the polish does it better).
    polish : int or None
        Residual only: pins the as-woven polish revisits
        (:mod:`stringbot.planner.methods.polish`; 0: none); None: 1000 with
        ``lines="auto"``, 0 with a line count (the paper's SSIM at a given
        line count rewards the pixel-level drawing, which the polish trades
        for the piece as seen).
    preview : int or None
        The side of the drawing as woven the caller will make
        (:func:`~stringbot.planner.model.render.draw_woven`, black on white): a
        polish on two cores draws it meanwhile (the plan's ``woven_drawings``).

    Returns
    -------
    Plan
        ``stats`` holds ``lines``, ``thread_diameters``, ``seconds`` and the
        method's own figures.
    """
    t0 = time.perf_counter()
    how = get_method(method)
    if size is None:  # ThreadTone works on a 1001-px picture (imgRadius 500), the paper on 401 px
        size = how.size or DEFAULTS["size"]
    if gray is None:  # the paper grays by decolorization; the piece as woven is seen by its luminance
        gray = how.gray
    auto_start = start_pin is None and method == "residual"  # residual: the pin of the best chord
    if start_pin is None:  # ThreadTone starts at its pin 0, which faces right: our pin pins / 4
        start_pin = pins // 4 if how.start_quarter else 0
    if crop is None and not fit and picture is None:
        crop = how.default_crop(path)
    check_knobs(pins=pins, frame=frame, size=size, lines=lines, start_pin=start_pin, method=method,
                alpha=alpha, beta=beta, gamma=gamma, T=T, epsilon=epsilon, iterations=iterations, style=style)
    model = thread_model(diameter_mm, thread_mm)
    if disconnected and "disconnected" not in how.knobs:
        raise BadInput(f"--disconnected works with --method {' or '.join(methods_taking('disconnected'))} only")
    if "style" not in how.knobs and (style is not None or any(x is not None for x in (beta, gamma, T))):
        raise BadInput(f"--style, --beta, --gamma and -T are knobs of --method {' or '.join(methods_taking('style'))}; "
                       f"{method} has none of them")
    if fit and crop is not None:
        raise BadInput("--fit and --crop both choose the part of the picture to paint; give one of them")
    if "polish" not in how.knobs and (refine is not None or polish is not None):
        given = " and ".join(f"--{n}" for n, v in (("refine", refine), ("polish", polish)) if v is not None)
        raise BadInput(f"{given} {'are knobs' if ' and ' in given else 'is a knob'} of --method "
                       f"{' or '.join(methods_taking('polish'))} only "
                       f"(not of {method}); leave {'them' if ' and ' in given else 'it'} out")
    if polish is None:
        polish = DEFAULTS["polish"] if lines == "auto" else 0
    if refine is None:
        refine = 0 if polish else DEFAULTS["refine"]
    for name, v in (("refine", refine), ("polish", polish)):
        if not (isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 1_000_000):
            raise BadInput(f"--{name} {v}; expected 0..1000000 pins")
    if fit and picture is None:
        from .picture.read import fit_crop

        crop = fit_crop(path, frame)
    report("reading the picture")
    # greedy reads the picture as ThreadTone does: cv2.resize, bilinear
    pic = picture or read_picture(path, size=size, crop=crop, gray=gray, rng=rng, resample=how.resample,
                                  weights=how.weights_for(gray))
    weights = None
    if importance is not None:
        weights = read_mask(importance, size=size, crop=pic.crop,
                            source_size=(pic.source["width"], pic.source["height"]))
    from .methods.fitness import frame_mask

    mask = frame_mask(size, frame)
    check_not_too_dark(pic.gray, mask)
    k = (None if how.stops_itself else auto_lines(pic.gray, mask)) if lines == "auto" else int(lines)
    space = chord_space(pins, frame)
    report("chords")
    stats = {"mean_gray": round(float(pic.gray[mask].mean()), 3), "chords": int(space.m)}
    if method == "fitness":
        rowptr, chords_of_pixel = pixel_chords(space, size, cache=cache)
        stats["pixels_per_chord"] = round(float(len(chords_of_pixel) / max(space.m, 1)), 2)
    t_chords = time.perf_counter()
    params = {"pins": pins, "frame": frame, "size": size, "crop": pic.crop, "lines": lines, "lines_target": k,
              "start_pin": start_pin, "method": method, "disconnected": bool(disconnected),
              "gray": pic.gray_method, "gray_requested": gray, "gray_weights": pic.weights,
              "importance": str(importance) if importance is not None else None}
    chords = woven_drawings = None
    if method == "residual":
        seq, extra, woven_drawings = _residual_run(
            space, pic, mask, weights, lines if lines == "auto" else k, model,
            start_pin=None if auto_start else start_pin, refine=refine, polish=polish, preview=preview)
        params["start_pin"] = int(seq[0])
        params.update(refine=refine, polish=polish, thread_px=round(model.width_px(size), 4))
        stats.update(extra)
    elif how.run:  # a method behind the registry's contract (stringbot.planner.methods)
        knobs = dict(DEFAULTS, size=size, alpha=alpha, epsilon=epsilon, iterations=iterations,
                     greedy_reference_radius=greedy_reference_radius, rng=rng)
        job = Job(space, pic, mask, weights, lines if how.stops_itself and lines == "auto" else k, start_pin,
                  model, knobs=knobs)
        seq, used, figures = how.runner()(job)
        seq = [int(p) for p in seq]
        params.update(used)
        stats.update(figures)
    else:
        params.update(alpha=alpha, epsilon=epsilon, iterations=iterations, style_requested=style or "auto")
        candidates = style_candidates(style, beta=beta, gamma=gamma, T=T)
        ref = None
        if len(candidates) > 1:
            from .model.scoring import SCORE_SIZE

            ref = (reference.gray if reference is not None else pic.gray if picture is not None else
                   read_picture(path, size=SCORE_SIZE, crop=pic.crop, gray=gray, weights=pic.weights).gray)
        runs = _fitness_runs(space, pic, mask, weights, rowptr, chords_of_pixel, k, alpha=alpha, epsilon=epsilon,
                             iterations=iterations, start_pin=start_pin, disconnected=disconnected,
                             candidates=candidates, reference=ref)
        del rowptr, chords_of_pixel
        best = max(runs, key=lambda r: r["rank"])
        params.update(style=best["style"], **best["knobs"])
        stats.update(best["stats"])
        if len(runs) > 1:
            stats["styles"] = {r["style"]: dict(r["scores"], solve_seconds=r["stats"]["solve_seconds"]) for r in runs}
        seq, chords = best["seq"], best["chords"]
    if chords is None:
        chord_list = list(zip(seq[:-1], seq[1:]))
    else:
        chord_list = chords
    if not chord_list:
        raise BadInput(f"{method} found nothing to draw: the picture is blank inside the frame; "
                       "expected a picture with some dark parts")
    stats.update(lines=len(chord_list), thread_diameters=round(thread_length(space.pin_xy, chord_list), 3),
                 setup_seconds=round(t_chords - t0, 3), seconds=round(time.perf_counter() - t0, 3))
    if k is not None and len(chord_list) < k:
        log.warning("%s stopped after %d of %d lines", method, len(chord_list), k)
    return Plan(diameter_mm=model.diameter_mm, thread_mm=model.thread_mm,
                pins=pins, frame=frame, pin_xy=space.pin_xy, crop=pic.crop, sequence=[int(p) for p in seq],
                method=method, parameters=params, source=pic.source, stats=stats,
                connected=chords is None, chords=[(int(a), int(b)) for a, b in (chords or [])],
                woven_drawings=woven_drawings)


def _residual_run(space, pic, mask, weights, lines, model, *, start_pin, refine, polish, preview=None):
    """The default method: residual choice under the thread model, then refinement and polish."""
    from .methods.greedy import _PinLines
    from .methods.polish import polish_plan
    from .methods.refine import refine_sequence
    from .methods.residual import Canvas, residual_sequence

    size = pic.gray.shape[0]
    target = np.where(mask, 1.0 - pic.gray / 255.0, 0.0)
    if float(target.max(initial=0.0)) < 1.0 / 255:
        raise BadInput("residual found nothing to draw: the picture is blank inside the frame; "
                       "expected a picture with some dark parts")
    w = mask.astype(np.float64) if weights is None else np.where(mask, weights, 0.0)
    canvas = Canvas(target, w, space.pin_xy, model.width_px(size), eye=lines == "auto")
    # points about every 1/400 of the frame along each chord (at 801 px every other pixel: the mean
    # residual along a chord needs no more, and this halves the work of large sizes); every 1/200 for
    # a plan to be polished (see CHOOSE_POINTS_POLISHED)
    points = CHOOSE_POINTS_POLISHED if polish else CHOOSE_POINTS
    pin_lines = _PinLines(space, size, nearest=True, spacing=max(1.0, (size - 1) / points))
    helper = None
    if polish:
        from .methods.woven_helper import WovenHelper, two_cores

        if two_cores():  # a helper process draws the polish's canvas while the threads are chosen
            from .methods.woven_helper import TwinDrawing

            drawing = None if preview is None else TwinDrawing(preview, model)
            helper = WovenHelper(lambda: _woven_canvas(target, w, space, model), space, drawing=drawing)
    try:
        t = time.perf_counter()
        seq = residual_sequence(canvas, space, lines, start_pin=start_pin, pin_lines=pin_lines,
                                on_chord=None if helper is None else helper.add)
        t_choose = time.perf_counter() - t
        from .methods import residual

        # more lines than a run that stopped itself can keep (it keeps PATIENCE fewer than it chose)
        capped = lines == "auto" and len(seq) - 1 > residual.MAX_AUTO - residual.PATIENCE
        err = canvas.error()
        eye, canvas.eye = canvas.eye, None  # the stop is made: the refinement needs the pixel error only
        report("refining")
        seq, rs = refine_sequence(canvas, seq, pin_lines, budget=refine, remove=lines == "auto")
        area = float(w.sum())
        out = {"choose_seconds": round(t_choose, 3), "refine_seconds": round(time.perf_counter() - t - t_choose, 3),
               "refine": rs, "model_rms_before_refine": round(float(np.sqrt(err / area)), 5),
               "model_rms": round(float(np.sqrt(canvas.error() / area)), 5)}
        if eye is not None:  # the stop's figure: the error as the eye sees it, before the polish
            out["eye_rms"] = round(float(np.sqrt(eye.error() / max(float(np.sum(eye.s ** 2)), 1e-12))), 5)
        if capped:
            out["line_cap"] = residual.MAX_AUTO
            log.info("residual: stopped at the line cap of %d lines, not because the picture was matched",
                     residual.MAX_AUTO)
        del canvas, pin_lines  # their chord caches (hundreds of MB at 600 pins) are not needed any more
        if not polish:
            return seq, out, None
        t = time.perf_counter()
        report("polishing")
        done = None if helper is None else helper.finish(seq, polish)
        out["polish_processes"] = 1 if done is None else 2
        drawings = None if done is None else helper.drawing
        if done is None:
            woven = _woven_canvas(target, w, space, model)
            woven.build(list(zip(seq[:-1], seq[1:])))
            done = polish_plan(woven, seq, space, budget=polish)
        seq, ps = done
        out.update(polish=ps, polish_seconds=round(time.perf_counter() - t, 3))
        return seq, out, drawings
    finally:
        if helper is not None:
            helper.close()


def _woven_canvas(target, w, space, model):
    """The polish's canvas for a picture at the working size: the error on a grid of
    :data:`~stringbot.planner.methods.woven.GRID` px at most (the eye's blur is 1 px there)."""
    from .methods.fitness import frame_mask
    from .methods.woven import GRID, WovenCanvas

    size = target.shape[0]
    m = min(GRID, size)
    if m != size:
        from .picture.resample import resize_square

        target = resize_square(target, m)
        w = resize_square(w, m)
    inside = frame_mask(m, space.frame)
    return WovenCanvas(np.where(inside, target, 0.0), np.where(inside, w, 0.0), space.pin_xy, model.width_px(m))


def _fitness_runs(space, pic, mask, weights, rowptr, chords_of_pixel, k, *, alpha, epsilon, iterations, start_pin,
                  disconnected, candidates, reference=None):
    """Solve and sample once per candidate knob setting; score each drawing when there are several.

    ``reference`` (a gray array, any square size) is what the drawings are
    scored against; plain SSIM, with every pixel weighted alike as in the
    paper's section 4.1 (an importance mask weighs the solve, not the choice).

    Returns
    -------
    list of dict
        Per candidate: ``style``, ``knobs``, ``seq`` (connected) or ``chords``
        (disconnected, else None), ``stats``, ``scores`` and ``rank``
        (the sum of the four SSIM figures against the picture, both windows plain
        and blurred; 0 for a single candidate).
    """
    from .methods.fitness import chord_weights, edge_consistency, gradients, solve_fitness
    from .model.scoring import SSIM_KEYS, score_chords
    from .methods.sampling import fitness_table, sample_connected, sample_disconnected

    inv = 255.0 - pic.gray
    if float(inv[mask].max(initial=0.0)) < 1.0:
        raise BadInput("fitness found nothing to draw: the picture is blank inside the frame; "
                       "expected a picture with some dark parts")
    gy, gx = gradients(inv)
    b = ((1.0 - alpha) * inv + alpha * np.hypot(gx, gy)).ravel()
    w = (mask.astype(np.float32) if weights is None else np.where(mask, weights, 0).astype(np.float32)).ravel()
    d = (edge_consistency(space, rowptr, chords_of_pixel, gy, gx) if any(c["gamma"] > 0 for _, c in candidates)
         else np.zeros(space.m))
    runs = []
    for name, knobs in candidates:
        t = time.perf_counter()
        report(f"solving ({name})")
        v = chord_weights(space, d, beta=knobs["beta"], gamma=knobs["gamma"])
        f, info = solve_fitness(rowptr, chords_of_pixel, b, w, v, iterations=iterations)
        t_solve = round(time.perf_counter() - t, 3)
        table = fitness_table(space, f, T=knobs["T"])
        report(f"sampling ({name})")
        if disconnected:
            chords, seq = sample_disconnected(space, table, k, epsilon=epsilon), []
        else:
            chords, seq = None, sample_connected(space, table, k, epsilon=epsilon, start_pin=start_pin)
        run = {"style": name, "knobs": knobs, "seq": seq, "chords": chords, "scores": None, "rank": 0.0,
               "stats": {"solve_iterations": info["iterations"], "solve_residual": round(info["residual"], 3),
                         "solve_seconds": t_solve,
                         "fitness_min": round(float(f.min()), 4), "fitness_max": round(float(f.max()), 4)}}
        if len(candidates) > 1:
            report(f"scoring ({name})")
            drawn = chords if disconnected else list(zip(seq[:-1], seq[1:]))
            sc = score_chords(drawn, space.pin_xy, pic.gray if reference is None else reference, frame=space.frame)
            run["scores"] = {k: round(sc[k], 4) for k in SSIM_KEYS}
            run["rank"] = sum(sc[k] for k in SSIM_KEYS)
            log.info("style %s: SSIM %.4f, blurred %.4f", name, sc["ssim"], sc["ssim_blurred"])
        runs.append(run)
    return runs
