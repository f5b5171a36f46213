"""``--face`` in colour: the plan laid with the face weighed more, kept only as good as the frame allows.

The draft (the colours' order and shares) is the frame's alone (:mod:`.build`).
On its schedule the planner then lays the plan without the face's weights,
and the plan with them (:data:`FACE_CANDIDATES`: the face's extra weight and
the more lines it is given, in turn), each against its own target, and
estimates each as the score would see it (:func:`estimate`: the blurred
luminance SSIM of the piece as the planner keeps it, on its fine cells,
inside the face box and over the frame).  It keeps the first plan with the
face whose frame is not lower than the plan's without it by that estimate;
when none is, the one whose frame is best.  The plan without the face is laid
only to be compared with (docs/planner.md, "Faces", "In colour").
"""

import logging

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["estimate", "face_share", "lay_with_face", "FACE_CANDIDATES", "FACE_SHARPEN"]

#: the plans with the face, tried in turn: ``(the face's extra weight, the share of lines more)``; the lines more
#: only with ``--lines auto`` (the mean of three starts on the four portraits, blurred SSIM: at +2.0 the lines
#: +10 % took Obama speaking's frame from -0.010 to -0.004 against the plan without --face; docs/planner.md)
FACE_CANDIDATES = ((2.0, 0.1), (1.0, 0.1))
#: --face: the plan's target is sharpened this much more over the face (:func:`.model.sharpened`; times the
#: face's soft-edged ellipse, 1 inside): the face's blurred SSIM +0.004 / +0.003 / +0.005 / +0.005 on the four
#: portraits (the mean of three starts), the frame's -0.001 / +0.001 / +0.001 / +0.003 (docs/planner.md, "Faces")
FACE_SHARPEN = 4.0


def face_share(weight, plain):
    """Where the face's extra weight lies, 0..1: ``weight / plain - 1`` over its most (the ellipse's inside)."""
    from ..picture.face import FACE_WEIGHT

    weight = np.asarray(weight, np.float64)
    plain = np.ones_like(weight) if plain is None else np.broadcast_to(np.asarray(plain, np.float64), weight.shape)
    extra = np.divide(weight, plain, out=np.ones_like(weight), where=plain > 0) - 1.0
    return np.clip(extra / FACE_WEIGHT, 0.0, 1.0) if FACE_WEIGHT > 0 else np.zeros_like(weight)


def estimate(piece, box, *, crop, frame):
    """The planner's estimate of the score's blurred luminance SSIM, inside the face box and over the frame.

    Parameters
    ----------
    piece : Piece
        With the fine luminance (:class:`.model.Fine`): its cells' colours are the piece as woven at twice
        the working grid (512 px on the default 256), the picture's luminance there what they are matched to.
    box : sequence of float
        The face box ``(row, col, height, width)`` in source pixels.
    crop : dict
    frame : {"circle", "square"}

    Returns
    -------
    (float, float)
        ``(face, frame)``: as :func:`stringbot.planner.model.scoring.face_ssim` with the score's blur (2 px at
        512 px; on the portraits the frame's difference between two plans within 0.004 of the score's).
    """
    from ..model.chords import frame_mask
    from ..model.scoring import WOVEN_SIGMA, WOVEN_SIZE, face_ssim
    from .model import _gray

    n = piece.m2
    inside = frame_mask(n, frame)
    drawing = np.where(inside, _gray(piece.u_fine).reshape(n, n), 1.0)
    picture = np.where(inside, piece.fine.gray.reshape(n, n), 1.0)
    f = face_ssim(drawing, picture, box, crop=crop, frame=frame, blur_sigma=WOVEN_SIGMA * n / WOVEN_SIZE)
    return f["face"], f["frame"]


def lay_with_face(lay, lines, schedule, *, box, crop, frame, auto_lines=True, candidates=None):
    """Lay the plan without the face and the plans with it in turn; keep one (see the module notes).

    Parameters
    ----------
    lay : callable
        ``lay(strength, lines, schedule) -> Runner``: the runs of ``schedule`` laid on a fresh runner whose
        weights and target have the face's extra weight ``strength`` (None: the plan without the face), the
        runs in ``runner.runs``.
    lines : int
        The line budget of the plan without the face.
    schedule : list of (int, int)
        ``(colour, lines)`` of each run, for ``lines``.
    box, crop, frame
        As for :func:`estimate`.
    auto_lines : bool
        ``--lines auto``: the plans with the face get their lines more.
    candidates : sequence of (float, float), optional
        ``(strength, lines more)`` of each plan with the face, in turn (default :data:`FACE_CANDIDATES`).

    Returns
    -------
    (Runner, dict)
        The runner kept and its record: ``strength``, ``lines_more`` and the estimates (``face``, ``frame``)
        of ``without`` and of each plan tried.
    """
    candidates = FACE_CANDIDATES if candidates is None else candidates
    base = lay(None, lines, schedule)
    ref = estimate(base.piece, box, crop=crop, frame=frame)
    record = {"without": [round(ref[0], 4), round(ref[1], 4)], "tried": []}
    best = None
    for strength, more in candidates:
        more = float(more) if auto_lines else 0.0
        k = int(round(lines * (1.0 + more)))
        sched = [(c, max(1, int(round(n * k / lines)))) for c, n in schedule] if k != lines else schedule
        runner = lay(float(strength), k, sched)
        est = estimate(runner.piece, box, crop=crop, frame=frame)
        record["tried"].append({"strength": strength, "lines_more": more,
                                "face": round(est[0], 4), "frame": round(est[1], 4)})
        log.info("--face in colour: the face +%g, lines +%g %%: estimated SSIM face %.4f, frame %.4f (without the "
                 "face's weights: %.4f, %.4f)", strength, 100 * more, est[0], est[1], ref[0], ref[1])
        level = est[1] >= ref[1]           # the frame not lower: kept at once
        if level or best is None or est[1] > best[2][1]:
            best = (strength, more, est, runner)
        if level:
            break
    strength, more, est, runner = best
    record.update(strength=strength, lines_more=more)
    return runner, record
