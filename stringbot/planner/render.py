"""Drawing a plan and scoring it against its picture (section 4.1).

A drawing is binary: black 1-pixel lines (one per chord) on white, pins at
``pin_xy * (size - 1)`` rounded to pixel centres.  The score is the paper's:
the drawing at 1001 x 1001 and the picture's crop are both resized to
201 x 201 and compared by SSIM (Wang et al. 2004, the paper's reference: an
11 x 11 Gaussian window of sigma 1.5, K1 = 0.01, K2 = 0.03); then again after a
Gaussian blur of both.  The picture is grayed and cropped exactly as the plan
was made (its ``crop`` and recorded gray weights); outside a circular frame
it counts as white, as the drawing does.
"""

import io
import logging

import numpy as np

from .chords import line_pixels, pin_pixels

log = logging.getLogger(__name__)

__all__ = ["draw", "png_bytes", "score", "score_chords", "SCORE_DRAW", "SCORE_SIZE", "BLUR_SIGMA"]

SCORE_DRAW = 1001
SCORE_SIZE = 201
BLUR_SIGMA = 2.0  # pixels at 201 x 201; the paper does not give its blur


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


def png_bytes(image):
    """Encode a uint8 gray array as PNG bytes."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.asarray(image, dtype=np.uint8), "L").save(buf, format="PNG", compress_level=3)
    return buf.getvalue()


def score(plan, gray, *, frame=None, blur_sigma=BLUR_SIGMA):
    """SSIM of a plan's drawing against its picture, plain and blurred.

    Parameters
    ----------
    plan : Plan
    gray, blur_sigma
        As for :func:`score_chords` (a ``gray`` of 201 x 201 avoids a second resampling).
    frame : {"circle", "square"}, optional
        Default: the plan's.

    Returns
    -------
    dict
        ``{"ssim": float, "ssim_blurred": float, "lines": int}``.
    """
    return score_chords(plan.chord_list(), plan.pin_xy, gray, frame=frame or plan.frame, blur_sigma=blur_sigma)


def score_chords(chords, pin_xy, gray, *, frame, blur_sigma=BLUR_SIGMA):
    """SSIM of chords drawn on pins against a picture, plain and blurred (see :func:`score`).

    Parameters
    ----------
    chords : sequence of (int, int)
    pin_xy : ndarray of float, shape (pins, 2)
        Pin positions in the unit square (x right, y down).
    gray : ndarray of float, shape (n, n)
        The picture's crop, gray levels in [0, 255].
    frame : {"circle", "square"}
        Outside a circle the picture counts as white.
    blur_sigma : float
        Gaussian sigma, in pixels at 201 x 201, of the blurred comparison.

    Returns
    -------
    dict
        ``{"ssim": float, "ssim_blurred": float, "lines": int}``.
    """
    from scipy.ndimage import gaussian_filter
    from skimage.metrics import structural_similarity
    from skimage.transform import resize

    from .fitness import frame_mask

    g = np.asarray(gray, dtype=np.float64) / 255.0
    g = np.where(frame_mask(g.shape[0], frame), g, 1.0)
    drawing = draw(chords, pin_xy, size=SCORE_DRAW).astype(np.float64) / 255.0
    a = resize(g, (SCORE_SIZE, SCORE_SIZE), anti_aliasing=True)
    b = resize(drawing, (SCORE_SIZE, SCORE_SIZE), anti_aliasing=True)
    ssim = dict(data_range=1.0, gaussian_weights=True, sigma=1.5, use_sample_covariance=False)
    plain = structural_similarity(a, b, **ssim)
    ab, bb = gaussian_filter(a, blur_sigma), gaussian_filter(b, blur_sigma)
    blurred = structural_similarity(ab, bb, **ssim)
    return {"ssim": float(plain), "ssim_blurred": float(blurred), "lines": len(chords)}
