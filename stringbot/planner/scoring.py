"""Scoring a plan against its picture: the paper's SSIM and the as-woven error.

**The paper's SSIM** (section 4.1).  The chords are drawn as black 1-pixel
lines on white at 1001 x 1001 (:func:`stringbot.planner.render.draw`); that
drawing and the picture's crop are both resized to 201 x 201 and compared by
SSIM; then again after a Gaussian blur of both (sigma 2 pixels at 201 x 201;
the paper does not give its blur).  Tools and papers compute SSIM with one of
two windows, which differ by up to 0.03 (plain) and 0.07 (blurred) on thread
drawings, so both are reported:

* ``ssim`` / ``ssim_blurred``: Wang et al.'s (2004, the paper's reference)
  11 x 11 Gaussian window, sigma 1.5, population covariances;
* ``ssim_uniform`` / ``ssim_uniform_blurred``: scikit-image's default, a 7 x 7
  uniform window with sample covariances.

K1 = 0.01, K2 = 0.03 and a data range of 1 in both.  The picture is grayed and
cropped exactly as the plan was made; outside a circular frame it counts as
white, as the drawing does.

**The as-woven error** (``woven_error``): what the piece looks like against
the picture, whatever the planner believed.  The chords are drawn under the
thread model (:mod:`stringbot.planner.thread`) on a 2048 x 2048 canvas with a
thread as wide as 1/2048 of the frame (one canvas pixel, about a 0.25 mm
thread on a 500 mm ring), coverage capped at 1, black thread on a white
board; the canvas is box-filtered to 512 x 512 and compared with the picture's
crop read at 512 x 512 (white outside the frame), both Gaussian-blurred with
sigma 2 pixels: the root-mean-square difference over the pixels of the frame,
in gray levels of 0..1 (0 perfect; a blank board against a mid-gray picture
scores 0.5).
"""

import logging

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["score", "score_chords", "ssim_pair", "woven_error", "woven_drawing", "SCORE_DRAW", "SCORE_SIZE",
           "BLUR_SIGMA", "WOVEN_CANVAS", "WOVEN_SIZE", "WOVEN_SIGMA", "SSIM_KEYS"]

SCORE_DRAW = 1001
SCORE_SIZE = 201
BLUR_SIGMA = 2.0  # pixels at 201 x 201; the paper does not give its blur
WOVEN_CANVAS = 2048
WOVEN_SIZE = 512
WOVEN_SIGMA = 2.0  # pixels at 512 x 512
#: The four SSIM figures of a score: two windows, plain and blurred.
SSIM_KEYS = ("ssim", "ssim_blurred", "ssim_uniform", "ssim_uniform_blurred")

_WANG = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False)


def ssim_pair(a, b, *, blur_sigma=BLUR_SIGMA):
    """The four SSIM figures of two gray images in [0, 1] (see the module notes).

    Returns
    -------
    dict
        ``ssim``, ``ssim_blurred`` (Gaussian 11 x 11 window) and
        ``ssim_uniform``, ``ssim_uniform_blurred`` (scikit-image's default 7 x 7 window).
    """
    from scipy.ndimage import gaussian_filter
    from skimage.metrics import structural_similarity

    ab, bb = gaussian_filter(a, blur_sigma), gaussian_filter(b, blur_sigma)
    return {"ssim": float(structural_similarity(a, b, data_range=1.0, **_WANG)),
            "ssim_blurred": float(structural_similarity(ab, bb, data_range=1.0, **_WANG)),
            "ssim_uniform": float(structural_similarity(a, b, data_range=1.0)),
            "ssim_uniform_blurred": float(structural_similarity(ab, bb, data_range=1.0))}


def _framed(gray, frame):
    """A picture's crop in [0, 1], white outside a circular frame."""
    from .fitness import frame_mask

    g = np.asarray(gray, dtype=np.float64) / 255.0
    return np.where(frame_mask(g.shape[0], frame), g, 1.0)


def woven_drawing(chords, pin_xy, *, size=WOVEN_SIZE, canvas=WOVEN_CANVAS, width=1.0 / WOVEN_CANVAS):
    """The chords as woven: black thread on a white board, box-filtered from a fine canvas.

    Parameters
    ----------
    chords : sequence of (int, int)
    pin_xy : ndarray of float, shape (pins, 2)
    size : int
        Side of the result; ``canvas`` must be a whole multiple of it.
    canvas : int
        Side of the canvas the threads are drawn on.
    width : float
        Thread width as a fraction of the frame's diameter.

    Returns
    -------
    ndarray of float64, shape (size, size)
        Gray in [0, 1], 1 white.
    """
    from .thread import composite, coverage

    if canvas % size:
        raise ValueError(f"canvas {canvas} is not a multiple of size {size}")
    cov = coverage(chords, pin_xy, size=canvas, width_px=width * canvas)
    f = canvas // size
    img = composite(cov).astype(np.float64)
    return img.reshape(size, f, size, f).mean(axis=(1, 3))


def woven_error(chords, pin_xy, gray, *, frame):
    """The as-woven error of chords against a picture (see the module notes).

    Parameters
    ----------
    chords : sequence of (int, int)
    pin_xy : ndarray of float, shape (pins, 2)
    gray : ndarray of float, shape (512, 512)
        The picture's crop read at :data:`WOVEN_SIZE`, gray levels 0..255.
    frame : {"circle", "square"}

    Returns
    -------
    float
        Root-mean-square difference over the frame, gray levels in 0..1.
    """
    from scipy.ndimage import gaussian_filter

    from .fitness import frame_mask

    g = np.asarray(gray, dtype=np.float64)
    if g.shape != (WOVEN_SIZE, WOVEN_SIZE):
        raise ValueError(f"picture is {g.shape}; expected {WOVEN_SIZE} x {WOVEN_SIZE}")
    target = gaussian_filter(_framed(g, frame), WOVEN_SIGMA)
    drawn = gaussian_filter(woven_drawing(chords, pin_xy), WOVEN_SIGMA)
    mask = frame_mask(WOVEN_SIZE, frame)
    return float(np.sqrt(np.mean((drawn - target)[mask] ** 2)))


def score(plan, gray, *, frame=None, blur_sigma=BLUR_SIGMA, woven_gray=None):
    """Score a plan's drawing against its picture.

    Parameters
    ----------
    plan : Plan
    gray, blur_sigma, woven_gray
        As for :func:`score_chords`.
    frame : {"circle", "square"}, optional
        Default: the plan's.

    Returns
    -------
    dict
        See :func:`score_chords`.
    """
    return score_chords(plan.chord_list(), plan.pin_xy, gray, frame=frame or plan.frame, blur_sigma=blur_sigma,
                        woven_gray=woven_gray)


def score_chords(chords, pin_xy, gray, *, frame, blur_sigma=BLUR_SIGMA, woven_gray=None):
    """The paper's SSIM of chords drawn on pins against a picture, and optionally the as-woven error.

    Parameters
    ----------
    chords : sequence of (int, int)
    pin_xy : ndarray of float, shape (pins, 2)
        Pin positions in the unit square (x right, y down).
    gray : ndarray of float, shape (n, n)
        The picture's crop, gray levels in [0, 255] (201 x 201 avoids a second resampling).
    frame : {"circle", "square"}
        Outside a circle the picture counts as white.
    blur_sigma : float
        Gaussian sigma, in pixels at 201 x 201, of the blurred comparison.
    woven_gray : ndarray of float, shape (512, 512), optional
        The picture's crop read at 512 x 512: also compute ``woven_error``.

    Returns
    -------
    dict
        ``ssim``, ``ssim_blurred``, ``ssim_uniform``, ``ssim_uniform_blurred``
        (see :func:`ssim_pair`), ``lines`` and, with ``woven_gray``, ``woven_error``.
    """
    from skimage.transform import resize

    from .render import draw

    a = resize(_framed(gray, frame), (SCORE_SIZE, SCORE_SIZE), anti_aliasing=True)
    drawing = draw(chords, pin_xy, size=SCORE_DRAW).astype(np.float64) / 255.0
    b = resize(drawing, (SCORE_SIZE, SCORE_SIZE), anti_aliasing=True)
    out = ssim_pair(a, b, blur_sigma=blur_sigma)
    out["lines"] = len(chords)
    if woven_gray is not None:
        out["woven_error"] = woven_error(chords, pin_xy, woven_gray, frame=frame)
    return out
