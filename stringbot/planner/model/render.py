"""Drawing a plan: as woven (the default), or the paper's binary drawing.

*As woven* (:func:`draw_woven`): the reference rendering
(:mod:`stringbot.planner.model.reference`: the threads at the plan's real width
with a sharp edge, their union, converged), black on a white board, so the
picture predicts the piece.  *Binary* (:func:`draw`):
black 1-pixel lines (one per chord) on white, pins at ``pin_xy * (size - 1)``
rounded to pixel centres: the drawing the paper scores (section 4.1,
:mod:`stringbot.planner.model.scoring`); a 1-pixel line at 1001 px is a 0.5 mm
thread on a 500 mm frame, so it looks darker than the piece will.
"""

import io
import logging

import numpy as np

from .chords import line_pixels, pin_pixels

log = logging.getLogger(__name__)

__all__ = ["draw", "draw_woven", "woven_image", "preview_drawing", "png_bytes", "preview_png", "PREVIEW_SAMPLES"]

#: samples across one thread in the preview `stringbot plan` writes: half the reference's (a quarter of the
#: time; its mean lightness as converged, within 0.0002; the drawing within about 0.003 rms, blurred)
PREVIEW_SAMPLES = 2.0


def draw(plan_or_chords, pin_xy=None, *, size=1001):
    """Draw chords as black 1-pixel lines on white.

    Parameters
    ----------
    plan_or_chords : Plan or sequence of (int, int)
    pin_xy : ndarray of float, shape (pins, 2), optional
        Needed when chords are given.
    size : int

    Returns
    -------
    ndarray of uint8, shape (size, size)
        0 on a thread, 255 elsewhere.
    """
    if pin_xy is None:
        chords = plan_or_chords.chord_list()
        pin_xy = plan_or_chords.pin_xy
    else:
        chords = plan_or_chords
    img = np.full(size * size, 255, dtype=np.uint8)
    if len(chords):
        c = np.asarray(chords, dtype=np.int64)
        rc = pin_pixels(pin_xy, size)
        _, flat = line_pixels(rc[c[:, 0], 0], rc[c[:, 0], 1], rc[c[:, 1], 0], rc[c[:, 1], 1], size)
        img[flat] = 0
    return img.reshape(size, size)


def draw_woven(plan, *, size=1001, board=255, thread=0, samples=None):
    """Draw a plan as woven: the reference rendering (:mod:`stringbot.planner.model.reference`) over the board.

    Parameters
    ----------
    plan : Plan
        Its ``diameter_mm`` and ``thread_mm`` give the thread's width.
    size : int
    board, thread : int
        Gray levels 0..255 of the board and the thread.
    samples : float, optional
        Samples across one thread (default: the reference's
        :data:`~stringbot.planner.model.reference.SAMPLES_PER_WIDTH`; the preview:
        :data:`PREVIEW_SAMPLES`).

    Returns
    -------
    ndarray of uint8, shape (size, size)
    """
    return woven_image(plan.chord_list(), plan.pin_xy, size=size, thread_fraction=plan.thread_model().fraction,
                       board=board, thread=thread, samples=samples)


def woven_image(chords, pin_xy, *, size, thread_fraction, board=255, thread=0, samples=None, rows=None):
    """The reference rendering of chords as uint8 gray (``rows``: only the rows ``r0 <= r < r1`` of it,
    :func:`~stringbot.planner.model.reference.reference_coverage`'s)."""
    from .reference import SAMPLES_PER_WIDTH, reference_gray

    gray = reference_gray(chords, pin_xy, size=size, thread_fraction=thread_fraction, board=float(board),
                          thread=float(thread), samples=SAMPLES_PER_WIDTH if samples is None else samples,
                          rows=rows)
    return np.clip(np.rint(gray), 0, 255).astype(np.uint8)


def preview_drawing(plan, size, *, board=255, thread=0):
    """The preview `stringbot plan` writes: :func:`draw_woven` with :data:`PREVIEW_SAMPLES`, as the
    polish's helper processes drew it already where they did (the plan's ``woven_drawings``)."""
    made = getattr(plan, "woven_drawings", None)  # drawn already, by the polish's helper process
    img = None if made is None else made(size, board, thread)
    return img if img is not None else draw_woven(plan, size=size, board=board, thread=thread,
                                                  samples=PREVIEW_SAMPLES)


def preview_png(plan, size, *, board=255, thread=0):
    """``png_bytes(preview_drawing(plan, size, ...))``, of the drawing the polish's helper processes
    made where they did (the plan's ``woven_drawings``)."""
    made = getattr(plan, "woven_drawings", None)
    png = getattr(made, "png", None)
    png = None if png is None else png(size, board, thread)
    return png if png is not None else png_bytes(preview_drawing(plan, size, board=board, thread=thread))


def png_bytes(image):
    """Encode a uint8 gray array as PNG bytes (zlib's fastest level: the previews of the six sample pictures
    2 % smaller to 1.4 % larger than at level 3, in two thirds of the time, 0.03-0.04 s at 1001 px)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.asarray(image, dtype=np.uint8), "L").save(buf, format="PNG", compress_level=1)
    return buf.getvalue()
