"""A colour plan as it will hang, and how far it is from the picture.

**As woven** (:func:`woven_rgb`): the reference rendering
(:func:`stringbot.planner.model.reference.reference_shares`) in colour.  Every
thread is a band of its real width with a sharp edge; the layers lie in
winding order, later ones on top, and a thread hides what it covers: each
sample of the fine canvas shows the colour of the last thread over it, or the
board.  An output pixel is the mean of its samples in linear light
(:mod:`.palette`: reflectances mix linearly), converted to sRGB only to show
or to compare.  A plan whose colour comes back in a later run is drawn as
wound: the later run lies over everything wound before it.

**The colour score** (:func:`colour_score`), the neutral yardstick of the
mono planner (:mod:`stringbot.planner.model.scoring`) in colour: the plan drawn as
woven at 512 x 512 and the picture's crop read at 512 x 512 (the board's
colour outside a circular frame), both Gaussian-blurred with sigma 2 pixels
in linear light (as the eye averages), then

* ``delta_e``: the mean CIEDE2000 (``skimage.color.deltaE_ciede2000``) over
  the pixels of the frame (0 perfect; about 2.3 is a just noticeable
  difference);
* ``ssim`` / ``ssim_blurred`` (and ``ssim_uniform`` / ``ssim_uniform_blurred``,
  scikit-image's default window): the SSIM of the luminances of the two (the
  neutral yardstick's gray, :data:`stringbot.planner.model.scoring.LUMINANCE` on the
  sRGB values), unblurred and blurred, as
  :func:`stringbot.planner.model.scoring.ssim_pair` computes them.
"""

import numpy as np

from .palette import WHITE, hex_to_rgb, to_linear, to_srgb

__all__ = ["woven_rgb", "woven_shares", "compose", "to_uint8", "colour_score", "plan_layers", "SCORE_SIZE",
           "BLUR_SIGMA", "PREVIEW_SAMPLES"]

SCORE_SIZE = 512
BLUR_SIGMA = 2.0
#: samples across a thread in the preview (as the mono preview: the mean as converged within 0.0002)
PREVIEW_SAMPLES = 2.0


def plan_layers(plan):
    """``[(color, chords), ...]`` of a plan, in winding order (a chord set: one layer)."""
    if not plan.connected:
        return [(plan.colors[0], plan.chord_list())]
    return [(layer.color, layer.chords()) for layer in plan.layers]


def woven_shares(layers, pin_xy, *, size, thread_fraction, samples=None, rows=None):
    """Which colour lies on top where: ``(colors, shares)``.

    Parameters
    ----------
    layers : sequence of (str, sequence of (int, int))
        ``(color "#rrggbb", chords)`` in winding order (a colour may come back).
    pin_xy : ndarray of float, shape (pins, 2)
    size : int
    thread_fraction : float
        The thread's width as a fraction of the frame (a plan's ``thread_model().fraction``).
    samples : float, optional
        Samples across a thread (default: the reference's,
        :data:`~stringbot.planner.model.reference.SAMPLES_PER_WIDTH`).
    rows : (int, int), optional
        Only those output rows.

    Returns
    -------
    colors : list of str
        The distinct colours, in order of first appearance.
    shares : ndarray of float32, shape (len(colors), size, size)
        The share of each pixel where that colour is on top.
    """
    from ..model.reference import SAMPLES_PER_WIDTH, reference_shares

    colors = list(dict.fromkeys(c for c, _ in layers))
    return colors, reference_shares([chords for _, chords in layers], pin_xy, size=size,
                                    thread_fraction=thread_fraction, ids=[colors.index(c) for c, _ in layers],
                                    samples=SAMPLES_PER_WIDTH if samples is None else samples, rows=rows)


def compose(colors, shares, background):
    """Linear RGB (..., 3) of ``shares`` (K, ...) of ``colors`` over the board."""
    board = to_linear(hex_to_rgb(background))
    img = np.empty(shares.shape[1:] + (3,), dtype=np.float64)
    img[:] = board
    for c, s in zip(colors, shares):
        img += s[..., None].astype(np.float64) * (to_linear(hex_to_rgb(c)) - board)
    return img


def to_uint8(rgb, *, linear=False):
    """sRGB floats in [0, 1] (or linear light, ``linear``) -> uint8, as previews and frames are stored."""
    rgb = to_srgb(rgb) if linear else np.asarray(rgb, dtype=np.float64)
    return np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8)


def woven_rgb(layers, pin_xy, *, background=WHITE, size=1001, thread_fraction=None, samples=None, linear=False):
    """The piece as woven (see the module notes).

    Parameters
    ----------
    layers : sequence of (str, sequence of (int, int))
        ``(color "#rrggbb", chords)`` in winding order.
    pin_xy : ndarray of float, shape (pins, 2)
    background : str
        The board.
    size : int
        Side of the result.
    thread_fraction : float, optional
        Thread width as a fraction of the frame (default 0.25 mm on 500 mm: 1/2000).
    samples : float, optional
        Samples across a thread (:func:`woven_shares`; the preview: :data:`PREVIEW_SAMPLES`).
    linear : bool
        Return linear light instead of sRGB.

    Returns
    -------
    ndarray of float64, shape (size, size, 3)
        In [0, 1].
    """
    from ..model.thread import DEFAULT_DIAMETER_MM, DEFAULT_THREAD_MM

    fraction = DEFAULT_THREAD_MM / DEFAULT_DIAMETER_MM if thread_fraction is None else float(thread_fraction)
    layers = [(c, ch) for c, ch in layers if len(ch)]
    colors, shares = woven_shares(layers, pin_xy, size=size, thread_fraction=fraction, samples=samples)
    img = compose(colors, shares, background)
    return img if linear else to_srgb(img)


def _blurred(linear_rgb, sigma):
    from scipy.ndimage import gaussian_filter

    return np.stack([gaussian_filter(linear_rgb[..., c], sigma) for c in range(3)], axis=-1)


def _luminance(linear_rgb):
    from ..model.scoring import LUMINANCE

    return to_srgb(linear_rgb) @ np.asarray(LUMINANCE, dtype=np.float64)


def colour_score(layers, pin_xy, picture_rgb, *, frame, background=WHITE, thread_fraction=None, face=None,
                 crop=None):
    """The colour score of ``layers`` against a picture (see the module notes).

    Parameters
    ----------
    layers : sequence of (str, chords)
        As for :func:`woven_rgb`.
    pin_xy : ndarray of float, shape (pins, 2)
    picture_rgb : ndarray of float, shape (512, 512, 3)
        The picture's crop read at :data:`SCORE_SIZE`, sRGB in [0, 1].
    frame : {"circle", "square"}
    background : str
    thread_fraction : float, optional
        Thread width as a fraction of the frame (a plan records its frame and thread; default 1/2000).
    face : sequence of float, optional
        A face box ``(row, col, height, width)`` in source pixels (a plan made with ``--face`` records it),
        with ``crop`` the picture's crop: the luminance SSIM inside it and over the frame, as for a
        one-thread plan (:func:`stringbot.planner.model.scoring.face_ssim`).

    Returns
    -------
    dict
        ``delta_e``, ``ssim``, ``ssim_blurred``, ``ssim_uniform``, ``ssim_uniform_blurred``, ``lines``
        and ``runs`` (layers with threads); with ``face``, ``face``: ``box``, ``ssim_face``,
        ``ssim_frame``, ``ssim_face_blurred``, ``ssim_frame_blurred`` and ``delta_e_face``.
    """
    from skimage.color import deltaE_ciede2000, rgb2lab

    from ..model.chords import frame_mask
    from ..model.scoring import ssim_pair

    pic = np.asarray(picture_rgb, dtype=np.float64)
    if pic.shape != (SCORE_SIZE, SCORE_SIZE, 3):
        raise ValueError(f"picture is {pic.shape}; expected {SCORE_SIZE} x {SCORE_SIZE} x 3")
    mask = frame_mask(SCORE_SIZE, frame)
    board = to_linear(hex_to_rgb(background))
    target = np.where(mask[..., None], to_linear(pic), board)
    woven = woven_rgb(layers, pin_xy, background=background, size=SCORE_SIZE, thread_fraction=thread_fraction,
                      linear=True)
    tb, wb = _blurred(target, BLUR_SIGMA), _blurred(woven, BLUR_SIGMA)
    de = deltaE_ciede2000(rgb2lab(to_srgb(tb)), rgb2lab(to_srgb(wb)))
    s = ssim_pair(_luminance(target), _luminance(woven), blur_sigma=BLUR_SIGMA)
    out = {"delta_e": float(de[mask].mean()), **s, "lines": int(sum(len(c) for _, c in layers)),
           "runs": sum(1 for _, c in layers if len(c))}
    if face is not None:
        out["face"] = _face_figures(face, crop, frame, _luminance(woven), _luminance(target), de, mask)
    return out


def _face_figures(box, crop, frame, woven_lum, target_lum, delta_e, mask):
    """The face box's figures of :func:`colour_score`."""
    from ..model.scoring import WOVEN_SIGMA, face_ssim
    from ..picture.face import face_box_pixels

    out = {"box": [float(v) for v in box]}
    for tail, sigma in (("", None), ("_blurred", WOVEN_SIGMA)):
        f = face_ssim(woven_lum, target_lum, box, crop=crop, frame=frame, blur_sigma=sigma)
        out[f"ssim_face{tail}"], out[f"ssim_frame{tail}"] = f["face"], f["frame"]
    r0, c0, r1, c1 = face_box_pixels(box, crop=crop, size=SCORE_SIZE)
    inside = np.zeros_like(mask)
    inside[r0:r1, c0:c1] = True
    inside &= mask
    out["delta_e_face"] = float(delta_e[inside].mean()) if inside.any() else float("nan")
    return out
