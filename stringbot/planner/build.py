"""Picture -> Plan in three steps: check the knobs, read the picture, run one method; then record it all.

:func:`plan_picture` is the planner's entry:

1. **The knobs** (:func:`~stringbot.planner.knobs.settle`): each in range and given to a method that
   takes it, the method's defaults filled in from its record in the registry
   (:mod:`stringbot.planner.methods`).  Nothing is read before they pass.
2. **The picture** (:func:`read_for_plan`): the part of it to paint (:func:`crop_for`: the crop given,
   the whole picture with ``fit``, centred on the largest face with ``face``, the method's own, or the
   largest centred circle), read at the method's working size, gray and resampling
   (:mod:`stringbot.planner.picture.read`), the importance weights (an importance mask's, the face's:
   :mod:`stringbot.planner.picture.face`), the frame mask; a picture too dark for black thread on white
   is refused.
3. **One method** (its ``run(job)``, :class:`~stringbot.planner.methods.Job`): the sequence, the knobs
   it used and its figures, recorded in the :class:`~stringbot.planner.plan_file.Plan` with the
   picture's identity, the line count and the thread's length.
"""

import functools
import logging
import time

import numpy as np

from ..errors import BadInput
from .knobs import auto_lines, settle
from .methods import DEFAULT_METHOD, DEFAULTS, Job, outcome
from .model.chords import chord_space, frame_mask, thread_length
from .picture.face import crop_on_face, face_for_plan, face_weights
from .picture.read import fit_crop, read_mask, read_picture
from .plan_file import Plan
from .progress import report

log = logging.getLogger(__name__)

__all__ = ["plan_picture", "crop_for", "read_for_plan", "check_not_too_dark", "MIN_MEAN_GRAY"]

#: Mean gray (0..255) inside the frame below which a picture is too dark for black thread on a white
#: board: the thread would have to cover more than 90 % of it (a black disc; all-black runs to the line
#: cap, 60000 lines, 13 km).  The sample pictures' means are 103-148, a night photo at 15 % of the
#: camera's 19; at 30 % (37) it plans in 3600 lines.
MIN_MEAN_GRAY = 25.5


def plan_picture(path, *, pins=300, frame="circle", size=None, crop=None, lines="auto", start_pin=None,
                 method=DEFAULT_METHOD, disconnected=False, importance=None, gray=None, style=None,
                 alpha=DEFAULTS["alpha"], beta=None, gamma=None, T=None,
                 epsilon=DEFAULTS["epsilon"], iterations=DEFAULTS["iterations"], cache=True, rng=None,
                 picture=None, reference=None, greedy_reference_radius=DEFAULTS["greedy_reference_radius"],
                 diameter_mm=None, thread_mm=None, fit=False, refine=None, polish=None, polish_passes=None, preview=None, face="off"):
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
        Fitness only: which setting of beta, gamma and T
        (:mod:`stringbot.planner.methods.fitness`); None is ``auto``.
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
        Residual and euler: pins the as-woven polish revisits
        (:mod:`stringbot.planner.methods.polish`; 0: none); None: 1000 with
        ``lines="auto"``, 0 with a line count (the paper's SSIM at a given
        line count rewards the pixel-level drawing, which the polish trades
        for the piece as seen).
    polish_passes : int or None
        Residual and euler: passes of inserts and deletes after the polish
        (:func:`~stringbot.planner.methods.polish.move_passes`; slower, a
        little better); 0: none; None: the method's (none; euler deletes
        once after the polish anyway with ``lines="auto"``).
    preview : int or None
        The side of the drawing as woven the caller will make
        (:func:`~stringbot.planner.model.render.draw_woven`, black on white): a
        polish on two cores draws it meanwhile (the plan's ``woven_drawings``).
    face : {"off", "auto", "on"}
        Keep the largest face in the crop and weigh it (:func:`read_for_plan`).

    Returns
    -------
    Plan
        ``stats`` holds ``lines``, ``thread_diameters``, ``seconds`` and the
        method's own figures.
    """
    t0 = time.perf_counter()
    knobs = settle(pins=pins, frame=frame, size=size, crop=crop, lines=lines, start_pin=start_pin, method=method,
                   disconnected=disconnected, gray=gray, style=style, alpha=alpha, beta=beta, gamma=gamma, T=T,
                   epsilon=epsilon, iterations=iterations, greedy_reference_radius=greedy_reference_radius,
                   diameter_mm=diameter_mm, thread_mm=thread_mm, fit=fit, refine=refine, polish=polish,
                   polish_passes=polish_passes)
    pic, mask, weights, found, frame_weights = read_for_plan(path, knobs, picture=picture, importance=importance,
                                                             rng=rng, face=face)
    how = knobs.method
    target = None if knobs.lines == "auto" and how.stops_itself else \
        auto_lines(pic.gray, mask) if knobs.lines == "auto" else int(knobs.lines)
    space = chord_space(knobs.pins, knobs.frame)
    report("chords")
    t_setup = time.perf_counter()
    job = Job(space, pic, mask, weights, "auto" if target is None else target, knobs.start_pin, knobs.model,
              knobs=dict(DEFAULTS, size=knobs.size, **knobs.given, rng=rng, cache=cache, preview=preview),
              reference=functools.partial(_scored_against, path, pic, read=picture is None, given=reference,
                                          gray=knobs.gray), frame_weights=frame_weights)
    result = outcome(how.runner()(job))
    seq = [int(p) for p in result.sequence]
    chord_list = result.chords if result.chords is not None else list(zip(seq[:-1], seq[1:]))
    if not chord_list:
        raise BadInput(f"{how.name} found nothing to draw: the picture is blank inside the frame; "
                       "expected a picture with some dark parts")
    params = {"pins": knobs.pins, "frame": knobs.frame, "size": knobs.size, "crop": pic.crop, "lines": knobs.lines,
              "lines_target": target, "start_pin": knobs.start_pin if knobs.start_pin is not None else seq[0],
              "method": how.name, "disconnected": knobs.given["disconnected"], "gray": pic.gray_method,
              "gray_requested": knobs.gray, "gray_weights": pic.weights,
              "importance": str(importance) if importance is not None else None, "face": found and found.to_record(),
              **result.params}
    stats = {"mean_gray": round(float(pic.gray[mask].mean()), 3), "chords": int(space.m), **result.stats}
    stats.update(lines=len(chord_list), thread_diameters=round(thread_length(space.pin_xy, chord_list), 3),
                 setup_seconds=round(t_setup - t0, 3), seconds=round(time.perf_counter() - t0, 3))
    if target is not None and len(chord_list) < target:
        why = result.stats.get("stopped")
        log.warning("%s stopped after %d of %d lines%s", how.name, len(chord_list), target,
                    f": {why}" if why else "")
    return Plan(diameter_mm=knobs.model.diameter_mm, thread_mm=knobs.model.thread_mm,
                pins=knobs.pins, frame=knobs.frame, pin_xy=space.pin_xy, crop=pic.crop, sequence=seq,
                method=how.name, parameters=params, source=pic.source, stats=stats,
                connected=result.chords is None, chords=[(int(a), int(b)) for a, b in (result.chords or [])],
                woven_drawings=result.drawings)


def crop_for(path, knobs, *, face=None):
    """The part of the picture at ``path`` to paint, ``{"cx", "cy", "r"}`` in its pixels, or None (the
    largest centred circle): the crop given, the whole picture letterboxed (``fit``), centred on ``face``
    (a :class:`~stringbot.planner.picture.face.Face`), or the method's own."""
    if knobs.fit:
        return fit_crop(path, knobs.frame)
    if knobs.crop is not None:
        return knobs.crop
    if face is not None:
        return crop_on_face(path, face)
    return knobs.method.default_crop(path)


def read_for_plan(path, knobs, *, picture=None, importance=None, rng=None, face="off"):
    """The picture as the method plans it: ``(picture, mask, weights, face, frame_weights)``.

    Parameters
    ----------
    path : str or Path
    knobs : Knobs
        From :func:`~stringbot.planner.knobs.settle`.
    picture : Picture, optional
        Already read (``path`` is not read then, nor cropped).
    importance : str or Path, optional
        A mask picture of the source's size: the importance weights.
    rng : None, int or numpy Generator
        Randomness of the decolorization.
    face : {"off", "auto", "on"}
        Look for the largest face (:func:`~stringbot.planner.picture.face.face_for_plan`: ``on`` refuses
        a picture without one), centre the crop on it unless one is given, weigh it; not with ``picture``.

    Returns
    -------
    picture : Picture
        At the working size (:mod:`stringbot.planner.picture.read`), as the method grays and resamples.
    mask : ndarray of bool, shape (size, size)
        The frame.
    weights : ndarray of float32 or None
        1 .. 2 by the importance mask, times the face's weights (1 .. 3), None without either.
    face : Face or None
        The face found, in source pixels.
    frame_weights : ndarray of float32 or None
        With a face, the weights without the face's (the importance mask's, else all 1); else None.
    """
    how, size = knobs.method, knobs.size
    found = None if picture is not None else face_for_plan(path, face=face)
    crop = knobs.crop if picture is not None else crop_for(path, knobs, face=found)
    report("reading the picture")
    pic = picture or read_picture(path, size=size, crop=crop, gray=knobs.gray, rng=rng, resample=how.resample,
                                  weights=how.weights_for(knobs.gray))
    weights = None
    if importance is not None:
        weights = read_mask(importance, size=size, crop=pic.crop,
                            source_size=(pic.source["width"], pic.source["height"]))
    frame_weights = None
    if found is not None:  # --face: the face weighs more
        frame_weights = np.ones((size, size), np.float32) if weights is None else weights
        weights = face_weights(found, crop=pic.crop, size=size, gray=pic.gray, times=weights)
    mask = frame_mask(size, knobs.frame)
    check_not_too_dark(pic.gray, mask)
    return pic, mask, weights, found, frame_weights


def _scored_against(path, pic, *, read, given, gray):
    """The picture as ``stringbot score`` reads it: ``given`` (a Picture), or the crop of ``path`` read at
    the score's size (``read``), else the working picture itself."""
    if given is not None:
        return given.gray
    if not read:
        return pic.gray
    from .model.scoring import SCORE_SIZE

    return read_picture(path, size=SCORE_SIZE, crop=pic.crop, gray=gray, weights=pic.weights).gray


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
