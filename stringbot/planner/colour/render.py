"""A colour plan as woven, and how far it is from the picture.

**As woven** (:func:`woven_rgb`): each layer's chords are drawn with the
thread model's footprints (:func:`stringbot.planner.thread.footprints`:
anti-aliased, a thread's width per unit of length) and the layers are
composited in winding order, later ones on top, over the board, in linear
light (:mod:`.palette`); the canvas is box-filtered to the size asked for and
converted to sRGB.

Threads of a layer are combined as opaque threads lying across a pixel at
unrelated places: the share they leave uncovered is the product of what each
leaves, ``1 - a = prod (1 - c_i)`` (:func:`union_coverage`).  This is the
coverage of real threads at any canvas size: 3000 random chords on a 300-pin
ring leave 31.5 % of the frame uncovered by the union drawn at 401 px and
31.7 % at 2005 px, while the capped sum (:func:`~stringbot.planner.thread.coverage`)
leaves 9.0 % at 401 px, 22.5 % at 2005 px and 28.3 % at 4010 px: it approaches
the union only as the thread becomes several pixels wide, because the
anti-aliasing filter spreads a thread over 3 pixels where neighbours are
then counted as overlapping.

**The colour score** (:func:`colour_score`), the colour counterpart of the
paper's blurred SSIM: the plan woven at 512 x 512 with a thread 1/2048 of the
frame wide (about 0.25 mm on a 500 mm ring, as the as-woven error of
:mod:`.scoring`) and resized to 201 x 201; the picture's crop read at 201 x
201; both Gaussian-blurred with sigma 2 pixels (as for the blurred SSIM; in
linear light, as the eye averages), then

* ``delta_e``: the mean CIEDE2000 (``skimage.color.deltaE_ciede2000``) over
  the pixels of the frame (0 perfect; about 2.3 is a just noticeable
  difference);
* ``ssim`` / ``ssim_blurred``: the SSIM of the luminances (CIE L*, 0..1) of
  the two, unblurred and blurred, with Wang et al.'s Gaussian window
  (:func:`stringbot.planner.scoring.ssim_pair`); outside a circular frame both
  count as the board.
"""

import numpy as np

from .palette import WHITE, hex_to_rgb, to_linear, to_srgb

__all__ = ["woven_rgb", "union_coverage", "colour_score", "plan_layers", "SCORE_WIDTH", "SCORE_WOVEN",
           "SCORE_SIZE", "BLUR_SIGMA"]

SCORE_WIDTH = 1.0 / 2048
SCORE_WOVEN = 512
SCORE_SIZE = 201
BLUR_SIGMA = 2.0


_BATCH = 400  # chords per footprint batch: bounds the temporaries


def union_coverage(chords, pin_xy, *, size, width_px):
    """Coverage of a layer's chords on a ``size x size`` canvas, combined as opaque threads.

    Parameters
    ----------
    chords : sequence of (int, int)
    pin_xy : ndarray of float, shape (pins, 2)
    size : int
    width_px : float
        Thread width in pixels of this canvas.

    Returns
    -------
    ndarray of float32, shape (size, size)
        ``1 - prod (1 - c_i)`` over the threads' footprints ``c_i``.
    """
    from ..thread import footprints

    c = np.asarray(chords, dtype=np.int64).reshape(-1, 2)
    xy = np.asarray(pin_xy, dtype=np.float64)
    log_left = np.zeros(size * size)
    for lo in range(0, len(c), _BATCH):
        cc = c[lo:lo + _BATCH]
        _, flat, cover = footprints(xy[cc[:, 0]], xy[cc[:, 1]], size, width_px)
        log_left += np.bincount(flat, weights=np.log1p(-np.minimum(cover, 1.0 - 1e-6)), minlength=size * size)
    return (1.0 - np.exp(log_left)).reshape(size, size).astype(np.float32)


def woven_rgb(layers, pin_xy, *, background=WHITE, size=1001, canvas=None, width=None, linear=False):
    """The piece as woven.

    Parameters
    ----------
    layers : sequence of (str, sequence of (int, int))
        ``(color "#rrggbb", chords)`` in winding order.
    pin_xy : ndarray of float, shape (pins, 2)
    background : str
        The board.
    size : int
        Side of the result.
    canvas : int, optional
        Side of the canvas the threads are drawn on, a whole multiple of
        ``size`` (default ``size``).
    width : float, optional
        Thread width as a fraction of the frame (default 0.25 mm on 500 mm: 1/2000).
    linear : bool
        Return linear light instead of sRGB.

    Returns
    -------
    ndarray of float64, shape (size, size, 3)
        In [0, 1].
    """
    from ..thread import DEFAULT_DIAMETER_MM, DEFAULT_THREAD_MM

    canvas = size if canvas is None else int(canvas)
    if canvas % size:
        raise ValueError(f"canvas {canvas} is not a multiple of size {size}")
    width = DEFAULT_THREAD_MM / DEFAULT_DIAMETER_MM if width is None else float(width)
    img = np.broadcast_to(to_linear(hex_to_rgb(background)).astype(np.float32), (canvas, canvas, 3)).copy()
    for color, chords in layers:
        if not len(chords):
            continue
        cov = union_coverage(chords, pin_xy, size=canvas, width_px=width * canvas)[..., None]
        img *= 1.0 - cov
        img += to_linear(hex_to_rgb(color)).astype(np.float32) * cov
    f = canvas // size
    if f > 1:
        img = img.reshape(size, f, size, f, 3).mean(axis=(1, 3))
    img = img.astype(np.float64)
    return img if linear else to_srgb(img)


def plan_layers(plan):
    """``[(color, chords), ...]`` of a plan, in winding order (a chord set: one layer)."""
    if not plan.connected:
        return [(plan.colors[0], plan.chord_list())]
    return [(layer.color, layer.chords()) for layer in plan.layers]


def _blurred_lab(linear_rgb, sigma):
    from scipy.ndimage import gaussian_filter
    from skimage.color import rgb2lab

    b = np.stack([gaussian_filter(linear_rgb[..., c], sigma) for c in range(3)], axis=-1)
    return rgb2lab(to_srgb(b))


def colour_score(layers, pin_xy, picture_rgb, *, frame, background=WHITE, width=SCORE_WIDTH):
    """The colour score of ``layers`` against a picture (see the module notes).

    Parameters
    ----------
    layers : sequence of (str, chords)
        As for :func:`woven_rgb`.
    pin_xy : ndarray of float, shape (pins, 2)
    picture_rgb : ndarray of float, shape (201, 201, 3)
        The picture's crop read at :data:`SCORE_SIZE`, sRGB in [0, 1].
    frame : {"circle", "square"}
    background : str
    width : float
        Thread width as a fraction of the frame (a plan records its frame and thread).

    Returns
    -------
    dict
        ``delta_e``, ``ssim``, ``ssim_blurred`` and ``lines``.
    """
    from skimage.color import deltaE_ciede2000, rgb2lab
    from skimage.transform import resize

    from ..fitness import frame_mask
    from ..scoring import ssim_pair

    pic = np.asarray(picture_rgb, dtype=np.float64)
    if pic.shape != (SCORE_SIZE, SCORE_SIZE, 3):
        raise ValueError(f"picture is {pic.shape}; expected {SCORE_SIZE} x {SCORE_SIZE} x 3")
    mask = frame_mask(SCORE_SIZE, frame)
    board = to_linear(hex_to_rgb(background))
    target = np.where(mask[..., None], to_linear(pic), board)
    woven = woven_rgb(layers, pin_xy, background=background, size=SCORE_WOVEN, width=width, linear=True)
    woven = resize(woven, (SCORE_SIZE, SCORE_SIZE, 3), anti_aliasing=True)
    woven = np.where(mask[..., None], woven, board)
    de = deltaE_ciede2000(_blurred_lab(target, BLUR_SIGMA), _blurred_lab(woven, BLUR_SIGMA))
    lum_t = rgb2lab(to_srgb(target))[..., 0] / 100.0
    lum_w = rgb2lab(to_srgb(woven))[..., 0] / 100.0
    s = ssim_pair(lum_t, lum_w, blur_sigma=BLUR_SIGMA)
    return {"delta_e": float(de[mask].mean()), "ssim": s["ssim"], "ssim_blurred": s["ssim_blurred"],
            "lines": int(sum(len(c) for _, c in layers))}
