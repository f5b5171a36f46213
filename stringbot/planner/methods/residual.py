"""The default planner: chords chosen with feedback from the picture as woven.

The picture is a target *darkness* ``t = 1 - gray / 255`` (0 outside the
frame).  The planner keeps the drawing as woven (:mod:`.canvas`) under the planner's thread
model (:mod:`stringbot.planner.model.union`: the reference rendering's union of
sharp threads on a fine canvas of ``f x f`` samples per working pixel, the
thread about one sample wide): ``D``, the share of each working pixel the
threads drawn so far cover.  The error is ``E = sum w (t - D)^2`` (``w``: 1
in the frame, up to 2 on important pixels, 0 outside).  The chooser and the
refinement see ``t`` sharpened (an unsharp mask, :data:`SHARPEN`): the
error is per working pixel, while the eye (and the plain SSIM) also sees the
picture's edges, and a sharpened target puts the threads on them rather
than evenly beside them.  The eye's error (the stop, half the score) and the
polish keep ``t`` itself.

*Choosing* (image-space error diffusion).  From the current pin, each
chord's score is the mean, over points spaced evenly along it (``int(hypot)``
of them, so no direction is favoured), of
``w (1 - D) ((t - D) - kappa (1 - D))``: how much darker the picture wants
to be there, times how much darker one more thread would still make it (it
falls on the uncovered part, ``1 - D``), less its own second-order cost.
With ``lines="auto"`` half the score (:data:`EYE_SHARE`) is the same slope of
the error as the eye sees it (below), on its coarse grid: the piece is judged
from a step away, where a thread's own stripe does not count.
The chord of highest score is drawn, and the error it leaves (or the
darkness it overshoots) is what the next choices see.  A chord drawn again
lies on the first and adds nothing (its score is 0).  The last ``min_loop``
pins are not gone back to.

*Stopping* (``lines="auto"``).  What decides is the error as the eye sees it
from a step away, the as-woven scorer's (:mod:`stringbot.planner.methods.eye`:
blurred, on a coarse grid, kept up to date chord by chord).  A chord that
does not lower it may still lead the thread to where the next ones do, so
the run goes on until ``patience`` chords in a row have not brought it
below its lowest, and the sequence is cut back to where it was lowest:
another thread would no longer improve the piece as it will hang.

The sequence then goes to :mod:`stringbot.planner.methods.refine` (a line count) or
:mod:`stringbot.planner.methods.polish` (``lines="auto"``).
"""

import logging
import time

import numpy as np

from ...errors import BadInput
from ..model.lines import PinLines
from ..picture.resample import unsharp
from ..progress import report
from . import Outcome
from .canvas import Canvas, fresh

log = logging.getLogger(__name__)

__all__ = ["run", "residual_sequence", "best_start", "woven_canvas", "frame_polish", "FACE_PASSES", "FACE_LED_PASSES", "CHOOSE_FACE", "PATIENCE",
           "EYE_SHARE", "EYE_FIRST", "LENGTH_POWER", "SHARPEN", "POLISH_ROUNDS"]

#: Threads in a row that may fail to lower the error before an automatic run ends.
PATIENCE = 40
MAX_AUTO = 60_000
#: with ``lines="auto"``, the share of a chord's score that is the slope of the error as the eye sees it
#: (the rest: the pixel error's); docs/planner.md, "How the chooser scores a chord"
EYE_SHARE = 0.5
#: with ``lines="auto"``, the chords from a pin whose pixel score is taken: the ones the eye scores highest
#: (the pixel score of all of them: the same plans' quality, 10 % more of the chooser's time)
EYE_FIRST = 40
#: with ``lines="auto"``, a chord's score is its mean slope times its length to this power (0: the mean,
#: the gain per length; 1: the sum, its whole gain): longer chords, fewer lines (docs/planner.md)
LENGTH_POWER = 0.3
#: the chooser and the refinement lay threads against the darkness sharpened, ``t + amount (t - blur(t))``
#: clipped to [0, 1] (:func:`~stringbot.planner.picture.resample.unsharp`; this amount, the blur's sigma this
#: fraction of the working size: 6 px at 401): the threads go to the picture's edges, which the plain SSIM
#: rewards (at ThreadTone's line counts ThreadTone + 0.062 on average, from + 0.037); the stop, the eye's
#: half of the score and the polish judge the piece against the picture itself (docs/planner.md, "Quality")
SHARPEN = (1.5, 0.015)
#: Points per frame side at which the choice samples each chord: a plan with a line count is judged pixel by
#: pixel at the working size (every pixel at 401 px); the first draft of a plan to be polished needs half as
#: many (the polish reworks it against the piece as woven, scoring chords every 1/128 of the frame):
#: 0.1-0.2 s less, as-woven error within 1 % (docs/planner.md, "Speed").
CHOOSE_POINTS, CHOOSE_POINTS_POLISHED = 400, 200
#: rounds of the polish's reroutes (``--polish`` pins each; :func:`~.polish.polish_rounds`): a pin's best way
#: round depends on its neighbours', which the round before rerouted (astronaut as woven 0.1325 -> 0.1303 for
#: three, docs/planner.md, "Polish"); ``--face`` keeps one (its own polishes follow)
POLISH_ROUNDS = 3
#: ``--face``: the share of the face's extra weight the chooser and its stop see (the polishes see all of
#: it): a chord chosen for the face's sake darkens the rest of the frame along its length, a polish's move
#: is judged where it is (docs/planner.md, "Faces")
CHOOSE_FACE = 0.5
#: ``--face``: passes of inserts and deletes in the second polish, the one the frame's error leads and the
#: face's own error guards (:func:`frame_polish`; docs/planner.md, "Faces")
FACE_PASSES = 2
#: ``--face``: then passes of inserts and deletes in a third polish, the face-weighted error leading and the
#: frame's guarding (after its reroutes): the face gains where the frame does not lose (:func:`frame_polish`)
FACE_LED_PASSES = 2


def best_start(canvas, space, pin_lines):
    """The pin to start from: an end of the chord of highest score on the canvas (the lower pin on a tie)."""
    g = canvas.slope()
    best, pin = -np.inf, 0
    for a in range(space.pins):
        others, pix, starts, counts = pin_lines.get_with_counts(a)
        if len(others):
            top = float((np.add.reduceat(g.take(pix), starts) / counts).max())
            if top > best:
                best, pin = top, a
    return pin


def residual_sequence(canvas, space, lines, *, start_pin=None, min_loop=3, pin_lines=None, patience=PATIENCE,
                      on_chord=None, eye_lines=None):
    """Choose a pin sequence by the darkness residual (see the module notes).

    Parameters
    ----------
    canvas : Canvas
        Modified: the chosen chords are drawn on it.
    space : ChordSpace
    lines : int or "auto"
        Chords to draw; ``"auto"``: until ``patience`` chords in a row have not
        brought the error below its lowest, then back to where it was lowest
        (the error as the eye sees it where the canvas keeps it, ``eye=True``;
        else the pixel error).
    start_pin : int or None
        None: :func:`best_start`.
    min_loop : int
    pin_lines : PinLines, optional
        Shared per-pin line points (built here when not given).
    patience : int
    on_chord : callable, optional
        ``on_chord((a, b))`` for each chord chosen, as it is (some may be cut
        back at the end).
    eye_lines : PinLines, optional
        The per-pin line points on the eye's grid (:func:`eye_lines_for`; built here when not given).

    Returns
    -------
    list of int
    """
    auto = lines == "auto"
    limit = MAX_AUTO if auto else int(lines)
    pins = pin_lines or PinLines(space, canvas.size, nearest=True)
    mix = EYE_SHARE if canvas.eye is not None else 0.0
    if mix:
        eye_lines = eye_lines or eye_lines_for(canvas, space)
        eye_rows = {}
        eg = canvas.eye_slope
        # the pixel slope is a darkness per unit of coverage; the eye's is per unit of coverage of a
        # cell, blurred twice: the two are put on one scale by their spread over the blank frame
        escale = float(np.std(canvas.slope())) / max(float(np.std(eg)), 1e-12)
    if start_pin is None:
        start_pin = best_start(canvas, space, pins)
    seq = [int(start_pin)]
    cur = int(start_pin)
    g = canvas.slope()
    eye = canvas.eye
    err = best = canvas.error() if eye is None else eye.error()
    best_len = 1
    for _ in range(limit):
        others, pix, starts, counts = pins.get_with_counts(cur)
        if not len(others):
            break
        if mix:
            row = eye_rows.get(cur)
            if row is None:
                eo, ep, es, ec = eye_lines.get_with_counts(cur)
                row = eye_rows[cur] = (canvas.eye.pidx[ep], es, ec)
            longer = counts ** LENGTH_POWER  # the chord's length in points, to a power
            by_eye = fresh(np.add.reduceat(eg.take(row[0]), row[1]) / row[2] * longer, canvas.uses[cur, others])
            # the pixel score of the chords the eye scores highest only (a fifth of the points to sum)
            top = np.argpartition(-by_eye, EYE_FIRST)[:EYE_FIRST] if len(others) > EYE_FIRST else \
                np.arange(len(others))
            n = counts[top].astype(np.int64)
            ends = np.cumsum(n)
            at = np.repeat(starts[top] - (ends - n), n) + np.arange(int(ends[-1]))
            raw = np.full(len(others), -np.inf)
            raw[top] = ((1.0 - mix) * (np.add.reduceat(g.take(pix[at]), ends - n) / counts[top]) * longer[top]
                        + mix * escale * by_eye[top])
        else:
            raw = np.add.reduceat(g.take(pix), starts) / counts
        score = fresh(raw, canvas.uses[cur, others])
        for q in seq[-min_loop:]:
            k = int(np.searchsorted(others, q))
            if k < len(others) and others[k] == q:
                score[k] = -np.inf
        k = int(np.argmax(score))
        if not np.isfinite(score[k]):
            break
        nxt = int(others[k])
        err += canvas.apply(chords_in=[(cur, nxt)])
        if eye is not None:
            err = eye.error()
        if on_chord is not None:
            on_chord((cur, nxt))
        seq.append(nxt)
        cur = nxt
        if len(seq) % 200 == 0:
            report("choosing threads", len(seq) - 1, None if auto else limit)
        if auto:
            if err < best:
                best, best_len = err, len(seq)
            elif len(seq) - best_len >= patience:
                break
    if auto and len(seq) > best_len:
        extra = list(zip(seq[best_len - 1:-1], seq[best_len:]))
        canvas.apply(chords_out=extra)
        log.info("residual: %d more threads did not improve the picture; keeping %d lines",
                 len(seq) - best_len, best_len - 1)
        seq = seq[:best_len]
    return seq


def eye_lines_for(canvas, space):
    """The chooser's per-pin line points on the eye's grid (a point every grid pixel)."""
    return PinLines(space, canvas.eye.size, nearest=True, spacing=1.0)


def run(job):
    """``--method residual`` through the methods' contract (:mod:`stringbot.planner.methods`): the residual
    choice under the thread model, then the refinement (a line count) or the polish (``lines="auto"``)."""
    k = job.knobs
    seq, stats, drawings = _plan(job.space, job.picture, job.mask, job.weights, job.lines, job.model,
                                 start_pin=job.start_pin, refine=k["refine"], polish=k["polish"], preview=k["preview"],
                                 passes=k.get("polish_passes", 0), frame_weights=job.frame_weights)
    params = {"refine": k["refine"], "polish": k["polish"], "polish_rounds": _rounds(k["polish"], job.frame_weights),
              "polish_passes": k.get("polish_passes", 0), "thread_px": round(job.model.width_px(k["size"]), 4)}
    return Outcome(seq, params, stats, drawings=drawings)


def _rounds(polish, frame_weights):
    """Rounds of the polish's reroutes: :data:`POLISH_ROUNDS`, one with ``--face``, none without the polish."""
    return 0 if not polish else 1 if frame_weights is not None else POLISH_ROUNDS


def _plan(space, pic, mask, weights, lines, model, *, start_pin, refine, polish, preview=None, passes=0,
          frame_weights=None):
    """The residual choice under the thread model, then refinement and polish: ``(seq, stats, drawings)``;
    with ``frame_weights`` (``weights`` without the face's, ``--face``) then :func:`frame_polish`."""
    from .polish import polish_plan
    from .refine import refine_sequence

    size = pic.gray.shape[0]
    target = np.where(mask, 1.0 - pic.gray / 255.0, 0.0)
    if float(target.max(initial=0.0)) < 1.0 / 255:
        raise BadInput("residual found nothing to draw: the picture is blank inside the frame; "
                       "expected a picture with some dark parts")
    w = mask.astype(np.float64) if weights is None else np.where(mask, weights, 0.0)
    # the threads are chosen against the picture sharpened (see SHARPEN), judged by the eye against itself
    amount, sigma = SHARPEN
    sharp = np.where(mask, unsharp(1.0 - pic.gray / 255.0, amount=amount, sigma=sigma * size), 0.0)
    # --face: the chooser (and its stop) sees a share of the face's extra weight, the polishes all of it
    chosen_w = w if frame_weights is None else \
        np.where(mask, frame_weights + CHOOSE_FACE * (w - frame_weights), 0.0)
    canvas = Canvas(sharp, chosen_w, space.pin_xy, model.width_px(size), eye=lines == "auto", eye_target=target)
    # points about every 1/400 of the frame along each chord (at 801 px every other pixel: the mean
    # residual along a chord needs no more, and this halves the work of large sizes); every 1/200 for
    # a plan to be polished (see CHOOSE_POINTS_POLISHED)
    points = CHOOSE_POINTS_POLISHED if polish else CHOOSE_POINTS
    pin_lines = PinLines(space, size, nearest=True, spacing=max(1.0, (size - 1) / points))
    helper = eye_lines = None
    if polish:
        from .woven_helper import WovenHelper, two_cores

        if two_cores():  # a helper process draws the polish's canvas while the threads are chosen
            from .shared_points import SharedPoints
            from .woven_helper import TwinDrawing

            # the twin draws the preview of the reroutes only: after passes of inserts and deletes, drawn here
            drawing = None if preview is None or passes or frame_weights is not None else TwinDrawing(preview, model)
            # the helper lays out the chooser's points first: the pixels' from the last pin down (best_start
            # takes them from the first up), then the eye's grid's (taken as the pins are first visited)
            points = None
            if canvas.eye is not None:
                eye_lines = eye_lines_for(canvas, space)
                points = SharedPoints([pin_lines, eye_lines], [(0, p) for p in range(space.pins - 1, -1, -1)]
                                      + [(1, p) for p in range(space.pins)])
            helper = WovenHelper(lambda: woven_canvas(target, w, space, model), space, drawing=drawing,
                                 patience=PATIENCE, points=points)
    try:
        t = time.perf_counter()
        seq = residual_sequence(canvas, space, lines, start_pin=start_pin, pin_lines=pin_lines,
                                on_chord=None if helper is None else helper.add, eye_lines=eye_lines)
        t_choose = time.perf_counter() - t
        # more lines than a run that stopped itself can keep (it keeps PATIENCE fewer than it chose)
        capped = lines == "auto" and len(seq) - 1 > MAX_AUTO - PATIENCE
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
            out["line_cap"] = MAX_AUTO
            log.info("residual: stopped at the line cap of %d lines, not because the picture was matched", MAX_AUTO)
        del canvas, pin_lines, eye_lines  # their chord caches (hundreds of MB at 600 pins) are not needed any more
        if not polish:
            return seq, out, None
        t = time.perf_counter()
        report("polishing")
        rounds = _rounds(polish, frame_weights)
        done = None if helper is None else helper.finish(seq, polish, passes, rounds=rounds)
        out["polish_processes"] = 1 if done is None else 2
        drawings = None if done is None else helper.drawing
        if done is None:
            woven = woven_canvas(target, w, space, model)
            woven.build(list(zip(seq[:-1], seq[1:])))
            done = polish_plan(woven, seq, space, budget=polish, rounds=rounds, passes=passes)
        seq, ps = done
        out.update(polish=ps, polish_seconds=round(time.perf_counter() - t, 3))
        if frame_weights is not None:
            t = time.perf_counter()
            report("polishing the frame")
            fw = np.where(mask, frame_weights, 0.0)
            seq, out["frame_polish"] = frame_polish(target, w, fw, space, model, seq, budget=polish)
            out["frame_polish_seconds"] = round(time.perf_counter() - t, 3)
        return seq, out, drawings
    finally:
        if helper is not None:
            helper.close()


def frame_polish(target, w, frame_w, space, model, seq, *, budget, passes=None, face_passes=None):
    """``--face``: after the face-weighted plan, a polish that the frame's error (``frame_w``: the weights
    without the face's) leads and the face's guards (the error weighed by ``w - frame_w``, the face's
    extra weight, 0 away from it): a change is kept only where the frame's error drops and the face's
    does not rise (:class:`~.polish.Guarded`), so the frame wins back some of what weighing the face cost
    it and the face keeps what it gained.  Then (``face_passes``, default :data:`FACE_LED_PASSES`) the same
    the other way round, on the same drawing: the face-weighted error ``w`` leads, the frame's guards, so
    the face gains where the frame does not lose.  ``(seq, stats)`` as :func:`~.polish.polish_plan`, the
    second polish's stats under ``face_led``."""
    from .eye import EyeError
    from .polish import Guarded, polish_plan
    from .woven import EYE_SIGMA

    lead = woven_canvas(target, frame_w, space, model)
    lead.build(list(zip(seq[:-1], seq[1:])))
    sigma = EYE_SIGMA * lead.size
    guard = EyeError(*_on_grid(target, w - frame_w, space), sigma=sigma)  # on the lead's D
    guard.reset(lead.D)
    seq, stats = polish_plan(Guarded(lead, guard), seq, space, budget=budget,
                             passes=FACE_PASSES if passes is None else passes)
    face_passes = FACE_LED_PASSES if face_passes is None else face_passes
    if face_passes:
        frame_guard = EyeError(*_on_grid(target, frame_w, space), sigma=sigma)
        frame_guard.reset(lead.D)
        _reweigh(lead, _on_grid(target, w, space)[1])
        seq, stats["face_led"] = polish_plan(Guarded(lead, frame_guard), seq, space, budget=budget, passes=face_passes)
    return seq, stats


def _reweigh(canvas, w):
    """Give a drawn :class:`~.woven.WovenCanvas` other pixel weights ``w`` (on its grid): its error and slope
    as :meth:`~.woven.WovenCanvas.finish` makes them, the drawing kept."""
    canvas.s = np.sqrt(np.asarray(w, dtype=np.float64).ravel())
    canvas.reset(canvas.D)
    canvas.u[canvas.pidx] = canvas.s * (1.0 - canvas.D)
    canvas.g = canvas.u * canvas.G


def _on_grid(target, w, space):
    """The target and the weights on the polish's grid (:func:`woven_canvas`), 0 outside the frame."""
    from ..model.chords import frame_mask
    from ..picture.resample import resize_square
    from .woven import GRID

    size = target.shape[0]
    m = min(GRID, size)
    if m != size:
        target = resize_square(target, m)
        w = resize_square(w, m)
    inside = frame_mask(m, space.frame)
    return np.where(inside, target, 0.0), np.where(inside, w, 0.0)


def woven_canvas(target, w, space, model):
    """The polish's canvas for a picture at the working size: the error on a grid of
    :data:`~stringbot.planner.methods.woven.GRID` px at most (the eye's blur is 1 px there)."""
    from .woven import WovenCanvas

    t, w = _on_grid(target, w, space)
    return WovenCanvas(t, w, space.pin_xy, model.width_px(t.shape[0]))
