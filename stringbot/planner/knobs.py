"""Checking a plan's knobs: each in its range, each given to a method that takes it, the method's defaults.

:func:`settle` is the first step of :func:`~stringbot.planner.build.plan_picture`: every knob is
checked before the picture is read, and a knob out of range, or given to a method that does not
take it, is one :class:`~stringbot.errors.BadInput` naming it.  What a method does when a knob is not
given comes from its record in the registry (:mod:`stringbot.planner.methods`).
"""

import math
from dataclasses import dataclass

import numpy as np

from ..errors import BadInput
from .methods import DEFAULTS, Method, get_method, methods_taking
from .model.thread import DEFAULT_DIAMETER_MM, DEFAULT_THREAD_MM, ThreadModel

__all__ = ["Knobs", "settle", "check_knobs", "thread_model", "auto_lines", "MAX_PINS", "MAX_LINES"]

MAX_PINS = 2000
MIN_SIZE, MAX_SIZE = 32, 2001
MAX_LINES = 100_000


@dataclass(frozen=True)
class Knobs:
    """A plan's knobs, checked, with the method's defaults filled in.

    Attributes
    ----------
    method : Method
        The registry's record of the method.
    pins, frame, size, lines, gray
        As given, or the method's default (``lines``: an int or ``"auto"``).
    start_pin : int or None
        None: the method picks it (:attr:`~stringbot.planner.methods.Method.picks_start`).
    crop : dict or None
        The crop given; None: decided when the picture is read (``fit``, the method's, the largest
        centred circle).
    fit : bool
    model : ThreadModel
    given : dict
        The method's knobs as given (None: not given) and the refinement's and polish's pins:
        ``alpha``, ``beta``, ``gamma``, ``T``, ``epsilon``, ``iterations``, ``style``,
        ``disconnected``, ``refine``, ``polish``, ``polish_passes``, ``greedy_reference_radius``.
    """

    method: Method
    pins: int
    frame: str
    size: int
    lines: object
    start_pin: int | None
    crop: dict | None
    fit: bool
    gray: str
    model: ThreadModel
    given: dict


def auto_lines(gray, mask):
    """``k = 500 + 10 (255 - mean gray)`` over the pixels of the frame (section 3.3)."""
    return int(round(500 + 10 * (255.0 - float(np.asarray(gray)[mask].mean()))))


def check_knobs(*, pins, frame, size, lines, start_pin, method, alpha, beta, gamma, T, epsilon, iterations,
                style="auto"):
    """Raise BadInput naming the first knob out of range (None: a knob not given)."""
    from .methods.fitness import STYLES

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
    d = DEFAULT_DIAMETER_MM if diameter_mm is None else diameter_mm
    t = DEFAULT_THREAD_MM if thread_mm is None else thread_mm
    for name, v, top in (("--diameter-mm", d, 100_000.0), ("--thread-mm", t, 100.0)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= top):
            raise BadInput(f"{name} {v:g}; expected millimetres, a number > 0 and <= {top:g}")
    if t * 20 > d:
        raise BadInput(f"--thread-mm {t:g} is more than a 20th of --diameter-mm {d:g}; "
                       "expected a thread much thinner than the frame")
    return ThreadModel(diameter_mm=float(d), thread_mm=float(t))


def _only_for(knob, names, how):
    """BadInput: ``names`` (the options given) are knobs of the methods that take ``knob``, not of ``how``."""
    many = " and " in names
    raise BadInput(f"{names} {'are knobs' if many else 'is a knob'} of --method "
                   f"{' or '.join(methods_taking(knob))} only "
                   f"(not of {how.name}); leave {'them' if many else 'it'} out")


def settle(*, pins, frame, size, crop, lines, start_pin, method, disconnected, gray, style, alpha, beta, gamma,
           T, epsilon, iterations, greedy_reference_radius, diameter_mm, thread_mm, fit, refine, polish,
           polish_passes=None):
    """Check every knob and fill in the method's defaults (the knobs as :func:`plan_picture` takes them).

    Returns
    -------
    Knobs

    Raises
    ------
    BadInput
        Naming the first knob out of range, or given to a method that does not take it.
    """
    how = get_method(method)
    if size is None:  # ThreadTone works on a 1001-px picture (imgRadius 500), the paper on 401 px
        size = how.size or DEFAULTS["size"]
    if gray is None:  # the paper grays by decolorization; the piece as woven is seen by its luminance
        gray = how.gray
    picks = start_pin is None and how.picks_start
    if start_pin is None:  # ThreadTone starts at its pin 0, which faces right: our pin pins / 4
        start_pin = pins // 4 if how.start_quarter else 0
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
    if refine is not None and "refine" not in how.knobs:
        raise BadInput(f"--refine works with --method {' or '.join(methods_taking('refine'))} only; "
                       f"{method} has no pixel refinement")
    if "polish" not in how.knobs and any(v is not None for v in (refine, polish, polish_passes)):
        _only_for("polish", " and ".join(f"--{n}" for n, v in (("refine", refine), ("polish", polish),
                                                                ("polish-passes", polish_passes)) if v is not None),
                  how)
    if polish is None:
        polish = DEFAULTS["polish"] if lines == "auto" else 0
    if refine is None:
        refine = 0 if polish else DEFAULTS["refine"]
    for name, v in (("refine", refine), ("polish", polish)):
        if not (isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 1_000_000):
            raise BadInput(f"--{name} {v}; expected 0..1000000 pins")
    from .methods.polish import MAX_PASSES

    if polish_passes is None:
        polish_passes = how.polish_passes if polish and lines == "auto" else 0
    if not (isinstance(polish_passes, int) and not isinstance(polish_passes, bool) and 0 <= polish_passes <= MAX_PASSES):
        raise BadInput(f"--polish-passes {polish_passes}; expected 0..{MAX_PASSES} passes")
    if polish_passes and not polish:
        raise BadInput(f"--polish-passes {polish_passes} follows the polish, which is off here (--polish 0, or a "
                       "line count); expected --lines auto (the default) or --polish N with it")
    given = {"alpha": alpha, "beta": beta, "gamma": gamma, "T": T, "epsilon": epsilon, "iterations": iterations,
             "style": style, "disconnected": bool(disconnected), "refine": refine, "polish": polish,
             "polish_passes": polish_passes, "greedy_reference_radius": greedy_reference_radius}
    return Knobs(method=how, pins=pins, frame=frame, size=size, lines=lines, start_pin=None if picks else start_pin,
                 crop=crop, fit=bool(fit), gray=gray, model=model, given=given)
