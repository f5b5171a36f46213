"""Scoring a plan against its picture: the paper's SSIM and the as-woven error.

**The paper's SSIM** (section 4.1).  The chords are drawn as black 1-pixel
lines on white at 1001 x 1001 (:func:`stringbot.planner.model.render.draw`); that
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
the picture, whatever the planner believed.  The chords are drawn by the
reference rendering (:mod:`stringbot.planner.model.reference`: the plan's thread
at its real width with a sharp edge, the union of the threads, converged,
box-filtered) at 512 x 512, black thread on a white board, and compared with
the picture's crop read at 512 x 512 (white outside the frame), both
Gaussian-blurred with sigma 2 pixels: the root-mean-square difference over
the pixels of the frame, in gray levels of 0..1 (0 perfect; a blank board
against a mid-gray picture scores 0.5).
"""

import logging

import numpy as np

#: The neutral yardstick's gray: luminance weighed as ``skimage.color.rgb2gray`` does (Rec. 709 weights on
#: the sRGB values), the target the peers plan against, and the planner's plain luminance
from ..picture.read import LUMINANCE

log = logging.getLogger(__name__)

__all__ = ["score", "score_chords", "face_scores", "face_ssim", "ssim_pair", "woven_error", "woven_drawing", "SCORE_DRAW", "SCORE_SIZE",
           "BLUR_SIGMA", "WOVEN_THREAD", "WOVEN_SIZE", "blurred_rms", "WOVEN_SIGMA", "SSIM_KEYS", "LUMINANCE",
           "score_picture", "plan_gray"]

SCORE_DRAW = 1001
SCORE_SIZE = 201
BLUR_SIGMA = 2.0  # pixels at 201 x 201; the paper does not give its blur
WOVEN_SIZE = 512
#: the thread's width as a fraction of the frame where a plan does not say (0.25 mm on 500 mm)
WOVEN_THREAD = 0.25 / 500.0
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
    from .chords import frame_mask

    g = np.asarray(gray, dtype=np.float64) / 255.0
    return np.where(frame_mask(g.shape[0], frame), g, 1.0)


def woven_drawing(chords, pin_xy, *, size=WOVEN_SIZE, thread_fraction=WOVEN_THREAD):
    """The chords as woven, black thread on a white board: the reference rendering
    (:func:`~stringbot.planner.model.reference.reference_gray`).

    Parameters
    ----------
    chords : sequence of (int, int)
    pin_xy : ndarray of float, shape (pins, 2)
    size : int
        Side of the result.
    thread_fraction : float
        Thread width as a fraction of the frame's diameter (a plan's ``thread_mm / diameter_mm``).

    Returns
    -------
    ndarray of float64, shape (size, size)
        Gray in [0, 1], 1 white.
    """
    from .reference import reference_gray

    return reference_gray(chords, pin_xy, size=size, thread_fraction=thread_fraction).astype(np.float64)


def woven_error(chords, pin_xy, gray, *, frame, thread_fraction=WOVEN_THREAD):
    """The as-woven error of chords against a picture (see the module notes).

    Parameters
    ----------
    chords : sequence of (int, int)
    pin_xy : ndarray of float, shape (pins, 2)
    gray : ndarray of float, shape (512, 512)
        The picture's crop read at :data:`WOVEN_SIZE`, gray levels 0..255.
    frame : {"circle", "square"}
    thread_fraction : float
        Thread width as a fraction of the frame's diameter.

    Returns
    -------
    float
        Root-mean-square difference over the frame, gray levels in 0..1.
    """
    g = np.asarray(gray, dtype=np.float64)
    if g.shape != (WOVEN_SIZE, WOVEN_SIZE):
        raise ValueError(f"picture is {g.shape}; expected {WOVEN_SIZE} x {WOVEN_SIZE}")
    return blurred_rms(woven_drawing(chords, pin_xy, thread_fraction=thread_fraction), _framed(g, frame), frame=frame)


def blurred_rms(a, b, *, frame, sigma=WOVEN_SIGMA):
    """Root-mean-square difference over the frame of two gray images (0..1), both Gaussian-blurred
    with ``sigma`` pixels (the as-woven error's comparison)."""
    from scipy.ndimage import gaussian_filter

    from .chords import frame_mask

    a, b = (gaussian_filter(np.asarray(x, dtype=np.float64), sigma) for x in (a, b))
    d = a - b
    return float(np.sqrt(np.mean(d[frame_mask(d.shape[0], frame)] ** 2)))


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
                        woven_gray=woven_gray, thread_fraction=plan.thread_model().fraction)


def plan_gray(plan):
    """``(gray, weights)`` the plan was made against, as :func:`~stringbot.planner.picture.read.read_picture`
    takes them (``"decolor"`` with no weights where the plan does not say)."""
    gray = plan.parameters.get("gray_requested", "decolor")
    weights = plan.parameters.get("gray_weights")
    if not (isinstance(weights, list) and len(weights) == 3 and all(isinstance(x, (int, float)) for x in weights)):
        weights = None
    return (gray if gray in ("decolor", "luminance") else "decolor"), weights


def score_picture(plan, image, *, target="luminance", face_box=None):
    """Score a plan against a picture file, cropped as the plan says.

    Parameters
    ----------
    plan : Plan
    image : str or Path
    target : {"luminance", "own"}
        ``luminance``: the neutral yardstick, the picture's luminance weighed
        as ``skimage.color.rgb2gray`` does (:data:`LUMINANCE`), what the peers
        plan against; ``own``: the gray the plan was made against
        (:func:`plan_gray`: its decolorization's weights, as recorded).
    face_box : sequence of 4 floats, optional
        ``(row, col, height, width)`` in source pixels: score inside this
        face box (``luminance`` only) instead of the one the plan recorded.

    Returns
    -------
    dict
        :func:`score_chords`'s figures with ``woven_error``, and ``weights``
        (the colour-to-gray weights used, None for a gray picture) and
        ``source`` (the picture's ``source`` record: path, sha256, size); for
        a plan made with ``--face`` or given ``face_box`` (and
        ``luminance``), ``face``: the SSIM as woven inside the face box and
        over the frame (:func:`face_scores`).
    """
    from ..picture.read import read_picture

    if target == "luminance":
        gray, weights = "luminance", LUMINANCE
    elif target == "own":
        gray, weights = plan_gray(plan)
    else:
        raise ValueError(f"target {target!r}; expected 'luminance' or 'own'")
    pic = read_picture(image, size=SCORE_SIZE, crop=plan.crop, weights=weights, gray=gray)
    woven = read_picture(image, size=WOVEN_SIZE, crop=plan.crop, weights=pic.weights, gray=gray)
    out = score(plan, pic.gray, woven_gray=woven.gray)
    out.update(weights=pic.weights, source=pic.source)
    if face_box is not None and target == "luminance":
        out["face"] = face_scores(plan, woven.gray, box=face_box)
    elif target == "luminance" and (plan.parameters or {}).get("face"):  # made with --face: SSIM inside its box
        out["face"] = face_scores(plan, woven.gray)
    return out


def score_chords(chords, pin_xy, gray, *, frame, blur_sigma=BLUR_SIGMA, woven_gray=None, thread_fraction=WOVEN_THREAD):
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
    thread_fraction : float
        The thread's width as a fraction of the frame (for ``woven_error``).

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
        out["woven_error"] = woven_error(chords, pin_xy, woven_gray, frame=frame, thread_fraction=thread_fraction)
    return out


def face_scores(plan, woven_gray, *, box=None):
    """The plan as woven against its picture, inside the face box and over the frame.

    Parameters
    ----------
    plan : Plan
        Drawn by the reference rendering (:func:`~stringbot.planner.model.render.draw_woven`) at the
        picture's size.
    woven_gray : ndarray, shape (n, n)
        The picture's luminance (0..255) read with the plan's crop.
    box : sequence of float, optional
        ``(row, col, height, width)`` in source pixels; default: the face the plan recorded
        (:mod:`stringbot.planner.picture.face`).

    Returns
    -------
    dict
        ``box``, ``ssim_face``, ``ssim_frame`` (plain) and ``ssim_face_blurred``,
        ``ssim_frame_blurred`` (both blurred by :data:`WOVEN_SIGMA` pixels first); see :func:`face_ssim`.
    """
    from .render import draw_woven

    box = box if box is not None else plan.parameters["face"]["box"]
    n = np.asarray(woven_gray).shape[0]
    drawing = draw_woven(plan, size=n).astype(np.float64) / 255.0
    picture = _framed(woven_gray, plan.frame)
    out = {"box": [float(v) for v in box]}
    for tail, sigma in (("", None), ("_blurred", WOVEN_SIGMA)):
        s = face_ssim(drawing, picture, box, crop=plan.crop, frame=plan.frame, blur_sigma=sigma)
        out[f"ssim_face{tail}"], out[f"ssim_frame{tail}"] = s["face"], s["frame"]
    return out


def face_ssim(drawing, picture, box, *, crop, frame, blur_sigma=None):
    """SSIM of a drawing against its picture inside a face box and over the frame.

    Parameters
    ----------
    drawing, picture : ndarray, shape (n, n)
        Gray levels in [0, 1], of the same crop (the picture white outside the frame).
    box : sequence of float
        ``(row, col, height, width)`` in source pixels.
    crop : dict
        ``{"cx", "cy", "r"}`` of both.
    frame : {"circle", "square"}
    blur_sigma : float or None
        Blur both by this many pixels first (None: plain).

    Returns
    -------
    dict
        ``face`` (the mean of SSIM's map over the box's pixels inside the frame; NaN when the box is out
        of the frame) and ``frame`` (over the frame): scikit-image's ``structural_similarity`` with
        Wang et al.'s Gaussian window (sigma 1.5), data range 1.
    """
    from scipy.ndimage import gaussian_filter
    from skimage.metrics import structural_similarity

    from ..picture.face import face_box_pixels
    from .chords import frame_mask

    a, b = (np.asarray(x, dtype=np.float64) for x in (drawing, picture))
    if blur_sigma:
        a, b = gaussian_filter(a, blur_sigma), gaussian_filter(b, blur_sigma)
    _, smap = structural_similarity(a, b, data_range=1.0, full=True, **_WANG)
    n = a.shape[0]
    inside = frame_mask(n, frame)
    r0, c0, r1, c1 = face_box_pixels(box, crop=crop, size=n)
    face = np.zeros_like(inside)
    face[r0:r1, c0:c1] = True
    face &= inside
    return {"face": float(smap[face].mean()) if face.any() else float("nan"), "frame": float(smap[inside].mean())}
