"""Drawing a plan: as woven (the default), or the paper's binary drawing.

*As woven* (:func:`draw_woven`): the threads drawn under the thread model
(:mod:`stringbot.planner.thread`) at the plan's real thread width, black on a
white board, so the picture predicts the piece.  *Binary* (:func:`draw`):
black 1-pixel lines (one per chord) on white, pins at ``pin_xy * (size - 1)``
rounded to pixel centres: the drawing the paper scores (section 4.1,
:mod:`stringbot.planner.scoring`); a 1-pixel line at 1001 px is a 0.5 mm
thread on a 500 mm frame, so it looks darker than the piece will.
"""

import io
import logging
import math

import numpy as np

from .chords import line_pixels, pin_pixels

log = logging.getLogger(__name__)

__all__ = ["draw", "draw_woven", "woven_drawing", "fine_side", "png_bytes", "preview_png", "MAX_FINE"]

#: largest side of the canvas a drawing as woven is made on before it is averaged down
MAX_FINE = 4096


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


def draw_woven(plan, *, size=1001, board=255, thread=0):
    """Draw a plan as woven: its threads at their real width, coverage capped at 1, over the board.

    Parameters
    ----------
    plan : Plan
        Its ``diameter_mm`` and ``thread_mm`` give the thread's width.  The
        threads are drawn where the thread is about one pixel wide (so that
        two threads on one spot are as dark as one, and two side by side twice
        as dark), then averaged down to ``size``; a plan just polished is
        averaged down from the polish's own canvas (its ``woven_cover``), or
        was drawn so already by the polish's helper (its ``woven_drawings``).
    size : int
    board, thread : int
        Gray levels 0..255 of the board and the thread.

    Returns
    -------
    ndarray of uint8, shape (size, size)
    """
    from .thread import coverage

    made = getattr(plan, "woven_drawings", None)  # drawn already, by the polish's helper process
    if made is not None:
        img = made(size, board, thread)
        if img is not None:
            return img
    # threads overlap where they overlap at their own width: drawn on the canvas the polish uses (the
    # thread about one pixel wide; 2048 px for 0.25 mm on 500 mm), or finer for a large drawing, then
    # averaged down; a plan just polished brings that canvas with it (the same drawing)
    model = plan.thread_model()
    side = fine_side(model, size)
    fine = getattr(plan, "woven_cover", None)
    if fine is None or fine.shape[0] != side:
        fine = coverage(plan.chord_list(), plan.pin_xy, size=side, width_px=model.width_px(side))
    return woven_drawing(fine, size, board=board, thread=thread)


def fine_side(model, size):
    """Side of the canvas a drawing as woven of ``size`` px is made on (:func:`draw_woven`)."""
    from .woven import GRID, fine_factor

    side = GRID * fine_factor(model.width_px(GRID), GRID)
    if side < 2 * size:
        side = size * max(1, min(int(math.ceil(1.0 / model.width_px(size) - 1e-9)), MAX_FINE // size))
    return side


def woven_drawing(fine, size, *, board=255, thread=0):
    """The drawing of a fine canvas's coverage (capped at 1), averaged down to ``size``: uint8 gray."""
    from .thread import composite

    k = fine.shape[0] // size
    n = fine.shape[0] // k
    if k > 1:  # the mean of each k x k block, as a sum of k * k strided views (a reduction over two axes is slow)
        cov = np.zeros((n, n), dtype=np.float32)
        for i in range(k):
            for j in range(k):
                cov += fine[i:n * k:k, j:n * k:k]
        cov *= np.float32(1.0 / (k * k))
    else:
        cov = fine[:n, :n]
    if n != size:
        from .resample import resize_square

        cov = resize_square(cov, size, anti_aliasing=False)
    return np.clip(np.rint(composite(cov, board=float(board), thread=float(thread))), 0, 255).astype(np.uint8)


def preview_png(plan, size, *, board=255, thread=0):
    """``png_bytes(draw_woven(plan, size=size, ...))``, taken as it is when the polish's twin has
    encoded it already (the plan's ``woven_drawings``)."""
    made = getattr(plan, "woven_drawings", None)
    png = getattr(made, "png", None)
    png = None if png is None else png(size, board, thread)
    return png if png is not None else png_bytes(draw_woven(plan, size=size, board=board, thread=thread))


def png_bytes(image):
    """Encode a uint8 gray array as PNG bytes."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.asarray(image, dtype=np.uint8), "L").save(buf, format="PNG", compress_level=3)
    return buf.getvalue()
