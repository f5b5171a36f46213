"""Reading pictures: any PIL mode, bomb-safe downscaling, crop, decolorization.

The planner only ever sees a ``size x size`` float array of gray levels in
[0, 255] (0 black).  A picture is read like this:

1. PIL opens it lazily; zero-byte, foreign or truncated files are
   :class:`~stringbot.errors.BadInput`.  A camera's EXIF orientation is
   applied (crops are in the coordinates of the picture as shown).  Pictures of up to
   :data:`MAX_PIXELS` pixels are accepted (PIL's decompression-bomb limit is
   raised for the open only); a JPEG is decoded at a reduced scale
   (``Image.draft``).
2. The crop square is cut out in horizontal strips; each strip is brought to
   8-bit ``L`` or ``RGB`` (16-bit scaled, CMYK converted, palette expanded,
   transparent pixels composited on white, an animation's first frame) and
   reduced by an integer factor, so no full-size copy beyond PIL's own
   decoded image (and no full-size float array) is ever made.
3. The reduced crop is resampled to ``size x size`` (Lanczos).
4. Colour becomes gray by the real-time contrast-preserving decolorization
   of Lu, Xu and Jia (2012), or by plain luminance (:data:`LUMINANCE`:
   ``skimage.color.rgb2gray``'s weights; ThreadTone's are
   :data:`CV2_LUMINANCE`).
"""

import logging
from pathlib import Path

import numpy as np

from ..._files import sha256_file  # noqa: F401  (the picture's identity in the plan; imported from here too)
from ...errors import BadInput

log = logging.getLogger(__name__)

__all__ = ["Picture", "read_picture", "decolorize", "default_crop", "default_crop_share", "fit_crop", "parse_crop",
           "MAX_PIXELS", "LUMINANCE", "CV2_LUMINANCE"]

#: plain luminance: ``skimage.color.rgb2gray``'s weights (Rec. 709) on the sRGB values, what the scorer
#: compares with (:mod:`stringbot.planner.model.scoring`)
LUMINANCE = (0.2125, 0.7154, 0.0721)
#: OpenCV's ``COLOR_BGR2GRAY`` (Rec. 601), ThreadTone's
CV2_LUMINANCE = (0.299, 0.587, 0.114)
MAX_PIXELS = 1_000_000_000      # refuse larger pictures outright
MAX_DECODED_BYTES = 1_200_000_000  # PIL's decoded image must fit in this
MIN_SIDE = 8
_STRIP_ROWS = 512
_STRIP_PIXELS = 8_000_000  # a strip of the crop, converted, stays under ~32 MB


class Picture:
    """A cropped, gray, working-size picture.

    Attributes
    ----------
    gray : ndarray of float32, shape (size, size)
        Gray levels in [0, 255], 0 black.
    crop : dict
        ``{"cx", "cy", "r"}`` in source pixels.
    source : dict
        ``{"path", "sha256", "width", "height"}``.
    gray_method : str
        ``"decolor"`` (with ``weights``), ``"luminance"`` or ``"gray"`` (already gray).
    weights : tuple of float or None
        ``(w_r, w_g, w_b)`` chosen by the decolorization.
    rgb : ndarray of float32, shape (size, size, 3) or None
        The crop in colour (sRGB values in [0, 1]); a gray picture's gray in
        all three channels.  None when not read from a file.
    """

    def __init__(self, gray, crop, source, gray_method, weights=None, rgb=None):
        self.gray = gray
        self.crop = crop
        self.source = source
        self.gray_method = gray_method
        self.weights = weights
        self.rgb = rgb


def default_crop(width, height):
    """The largest centred circle (or square): ``{"cx", "cy", "r"}`` in source pixels."""
    return {"cx": width / 2.0, "cy": height / 2.0, "r": min(width, height) / 2.0}


def _upright_size(path, what="picture"):
    """(width, height) of the picture as shown: swapped where its EXIF orientation turns it."""
    im = _open(path, what)
    w, h = im.size
    try:
        if int(im.getexif().get(0x0112, 1)) in (5, 6, 7, 8):
            w, h = h, w
    except Exception:  # noqa: BLE001 -- a damaged EXIF block: as stored
        pass
    return w, h


def default_crop_share(path):
    """How much of the picture the default crop keeps: ``(share, (width, height))``.

    The default crop is the largest centred square (the circle's bounding square), so the share of
    the picture's area is the shorter side over the longer (1 for a square picture, 0.01 for 2000 x 20).
    """
    w, h = _upright_size(path)
    return min(w, h) / max(w, h), (w, h)


def fit_crop(path, frame="circle"):
    """The crop that holds the whole picture, letterboxed: centred, radius half the diagonal (circle) or half
    the longer side (square); what lies outside the picture is white."""
    w, h = _upright_size(path)
    r = float(np.hypot(w, h)) / 2.0 if frame == "circle" else max(w, h) / 2.0
    return {"cx": w / 2.0, "cy": h / 2.0, "r": r}


def threadtone_crop(path):
    """ThreadTone's crop: the largest centred square, its corner on whole pixels (``int((w - side) / 2)``)."""
    w, h = _upright_size(path)
    side = min(w, h)
    return {"cx": int((w - side) / 2) + side / 2.0, "cy": int((h - side) / 2) + side / 2.0, "r": side / 2.0}


def parse_crop(text):
    """Parse ``"CX,CY,R"`` into a crop dict; BadInput when malformed."""
    parts = str(text).split(",")
    try:
        cx, cy, r = (float(p) for p in parts)
    except ValueError:
        raise BadInput(f"--crop {text!r} is not CX,CY,R; expected three numbers, e.g. 256,256,200") from None
    if not all(np.isfinite([cx, cy, r])) or r <= 0:
        raise BadInput(f"--crop {text!r}: expected finite numbers and a radius R > 0")
    return {"cx": cx, "cy": cy, "r": r}


def _open(path, what):
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    if path.is_dir():
        raise BadInput(f"{what} {str(path)!r} is a folder; expected a picture file")
    if not path.is_file():
        raise BadInput(f"{what} {str(path)!r} does not exist")
    if path.stat().st_size == 0:
        raise BadInput(f"{what} {str(path)!r} is an empty file (0 bytes); expected a picture (PNG, JPEG, ...)")
    old = Image.MAX_IMAGE_PIXELS
    Image.MAX_IMAGE_PIXELS = MAX_PIXELS  # our own limit below; PIL's would refuse big, honest pictures
    try:
        im = Image.open(path)
    except UnidentifiedImageError:
        raise BadInput(f"{what} {str(path)!r} is not a picture PIL can read; expected PNG, JPEG, ...") from None
    except Image.DecompressionBombError:
        raise BadInput(f"{what} {str(path)!r} has more than {MAX_PIXELS:,} pixels; expected a smaller picture") from None
    except OSError as exc:
        raise BadInput(f"{what} {str(path)!r} cannot be read ({exc}); expected a picture file") from None
    finally:
        Image.MAX_IMAGE_PIXELS = old
    w, h = im.size
    if w < MIN_SIDE or h < MIN_SIDE:
        raise BadInput(f"{what} {str(path)!r} is {w} x {h} pixels; expected at least {MIN_SIDE} x {MIN_SIDE}")
    if w * h > MAX_PIXELS:
        raise BadInput(f"{what} {str(path)!r} has {w * h:,} pixels; expected at most {MAX_PIXELS:,}")
    if getattr(im, "n_frames", 1) > 1:
        log.warning("%s %s is animated; using its first frame", what, path)
    return im


def _decoded_bytes(im):
    per = {"1": 1, "L": 1, "P": 1, "I;16": 2, "I;16B": 2, "I;16L": 2, "LA": 4, "PA": 4}.get(im.mode, 4)
    return im.size[0] * im.size[1] * per


def _to_8bit(im):
    """Bring a (small) PIL image to 8-bit ``L`` or ``RGB``; alpha is composited on white."""
    from PIL import Image

    mode = im.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I", "F"):
        a = np.asarray(im, dtype=np.float64)
        top = 65535.0 if (mode.startswith("I;16") or a.max(initial=0) > 255) else 255.0
        if mode == "F" and a.max(initial=0) <= 1.0:
            top = 1.0
        return Image.fromarray(np.clip(a * (255.0 / top), 0, 255).round().astype(np.uint8), "L")
    if mode == "P":
        im = im.convert("RGBA" if "transparency" in im.info else "RGB")
    elif mode in ("1", "L", "RGB"):
        return im.convert("L") if mode == "1" else im
    elif mode in ("LA", "La", "PA", "RGBA", "RGBa") or "transparency" in im.info:
        im = im.convert("RGBA")
    else:  # CMYK, YCbCr, LAB, HSV, ...
        im = im.convert("RGB")
    if im.mode == "RGBA":
        white = Image.new("RGBA", im.size, (255, 255, 255, 255))
        im = Image.alpha_composite(white, im).convert("RGB")
    return im


def _cut(im, box, size, resample="lanczos"):
    """Cut ``box`` (may reach outside: white) from ``im`` and resample to ``size x size``.

    Works in strips reduced by an integer factor, so the full-resolution copy
    of the crop is never made.  Returns an 8-bit ``L`` or ``RGB`` PIL image.
    """
    from PIL import Image

    x0, y0, x1, y1 = box
    side = x1 - x0
    factor = max(1, int(side // (2 * size)))  # keep >= 2x oversampling for the final Lanczos
    ix0, iy0 = int(np.floor(x0)), int(np.floor(y0))
    ix1, iy1 = int(np.ceil(x1)), int(np.ceil(y1))
    out_w = -(-(ix1 - ix0) // factor)
    out_h = -(-(iy1 - iy0) // factor)
    canvas = None
    rows = max(factor, min(_STRIP_ROWS * factor, _STRIP_PIXELS // max(1, ix1 - ix0) // factor * factor))
    for sy in range(iy0, iy1, rows):
        ey = min(sy + rows, iy1)
        strip = _to_8bit(im.crop((ix0, sy, ix1, ey)))
        if canvas is None:
            fill = 255 if strip.mode == "L" else (255, 255, 255)
            canvas = Image.new(strip.mode, (out_w, out_h), fill)
        if strip.mode != canvas.mode:
            strip = strip.convert(canvas.mode)
        # pixels outside the picture are white, not black
        _whiten_outside(strip, (ix0, sy), im.size)
        if factor > 1:
            strip = strip.reduce(factor)
        canvas.paste(strip, (0, (sy - iy0) // factor))
    fb = ((x0 - ix0) / factor, (y0 - iy0) / factor, (x1 - ix0) / factor, (y1 - iy0) / factor)
    how = Image.Resampling.BILINEAR if resample == "bilinear" else Image.Resampling.LANCZOS
    return canvas.resize((size, size), how, box=fb)


def _whiten_outside(strip, origin, full):
    from PIL import Image

    ox, oy = origin
    w, h = strip.size
    inside = (max(0, -ox), max(0, -oy), min(w, full[0] - ox), min(h, full[1] - oy))
    if inside == (0, 0, w, h):
        return
    fill = 255 if strip.mode == "L" else (255, 255, 255)
    white = Image.new(strip.mode, (w, h), fill)
    if inside[2] > inside[0] and inside[3] > inside[1]:
        white.paste(strip.crop(inside), inside[:2])
    strip.paste(white, (0, 0))


def read_picture(path, *, size=401, crop=None, gray="decolor", what="picture", rng=None, weights=None,
                 resample="lanczos"):
    """Read, crop and gray a picture.

    Parameters
    ----------
    path : str or Path
    size : int
        Side of the working image in pixels.
    crop : dict or None
        ``{"cx", "cy", "r"}`` in source pixels; None: the largest centred circle.
        The crop square must overlap the picture; what lies outside is white.
    gray : {"decolor", "luminance"}
    what : str
        Name used in error messages.
    rng : None, int or numpy Generator
        For the random pairs of the decolorization; None: a fixed seed, so
        that the same picture always gives the same plan.
    weights : tuple of float, optional
        ``(w_r, w_g, w_b)`` to use instead of choosing them (e.g. a plan's
        recorded decolorization, to score against the very same gray).
    resample : {"lanczos", "bilinear"}
        The final resampling to ``size`` (bilinear: as ``cv2.resize`` does by default).

    Returns
    -------
    Picture
    """
    im = _open(path, what)
    w, h = im.size
    try:
        orientation = int(im.getexif().get(0x0112, 1))  # EXIF orientation: cameras store pictures turned
    except Exception:  # noqa: BLE001 -- a damaged EXIF block is no reason to refuse the picture
        orientation = 1
    if orientation in (5, 6, 7, 8):
        w, h = h, w  # the picture as it is shown: crops are in these coordinates
    crop = dict(crop) if crop else default_crop(w, h)
    cx, cy, r = crop["cx"], crop["cy"], crop["r"]
    box = (cx - r, cy - r, cx + r, cy + r)
    if box[2] <= 0 or box[3] <= 0 or box[0] >= w or box[1] >= h:
        raise BadInput(f"crop {cx:g},{cy:g},{r:g} lies outside the {w} x {h} {what}; "
                       "expected a circle centred on the picture")
    if 2 * r < MIN_SIDE:
        raise BadInput(f"crop radius {r:g} is too small; expected at least {MIN_SIDE / 2:g} pixels")
    try:
        if im.format == "JPEG" and im.mode in ("L", "RGB", "CMYK", "YCbCr"):
            scale = max(1, int(2 * r // (2 * size)))
            if scale > 1:
                raw_w, raw_h = im.size
                im.draft(im.mode, (max(1, raw_w // scale), max(1, raw_h // scale)))
        if _decoded_bytes(im) > MAX_DECODED_BYTES:
            raise BadInput(f"{what} {str(path)!r} ({w} x {h}, mode {im.mode}) needs more than "
                           f"{MAX_DECODED_BYTES / 1e9:.1f} GB to decode; expected a smaller picture")
        im.seek(0) if getattr(im, "n_frames", 1) > 1 else None
        if orientation != 1:
            from PIL import ImageOps

            im = ImageOps.exif_transpose(im)
        if im.size[0] != w:  # decoded at a reduced scale
            k = w / im.size[0]
            box = tuple(v / k for v in box)
        small = _cut(im, box, size, resample)
    except BadInput:
        raise
    except (OSError, SyntaxError, ValueError, EOFError) as exc:
        raise BadInput(f"{what} {str(path)!r} is damaged or truncated ({exc}); expected a complete picture") from None
    except MemoryError:
        raise BadInput(f"{what} {str(path)!r} is too large to read in memory; expected a smaller picture") from None
    source = {"path": str(path), "sha256": sha256_file(path), "width": int(w), "height": int(h)}
    if small.mode == "L":
        g = np.asarray(small, dtype=np.float32)
        return Picture(g, crop, source, "gray", rgb=np.repeat(g[..., None] / 255.0, 3, axis=2))
    rgb = np.asarray(small, dtype=np.float32) / 255.0
    if np.ptp(rgb, axis=2).max() < 1.0 / 255:
        return Picture(rgb[..., 0] * 255.0, crop, source, "gray", rgb=rgb)
    if weights is not None:
        wts = tuple(float(v) for v in weights)
    elif gray == "luminance":
        wts = LUMINANCE
    elif gray == "decolor":
        wts = decolorize(rgb, rng=rng)
    else:
        raise ValueError(f"gray {gray!r}; expected 'decolor' or 'luminance'")
    g = (rgb @ np.asarray(wts, dtype=np.float32)) * 255.0
    return Picture(np.clip(g, 0, 255).astype(np.float32), crop, source, gray, tuple(float(v) for v in wts), rgb=rgb)


def decolorize(rgb, *, sigma=0.05, rng=None):
    """Real-time contrast-preserving decolorization (Lu, Xu and Jia 2012).

    Of the 66 weights ``(w_r, w_g, w_b)`` on the 0.1 grid that sum to 1, pick
    the one whose gray differences best preserve the colour contrasts of a
    ~64 x 64 nearest-neighbour copy: global pairs (a random permutation) and
    local pairs (neighbours in a half-size copy), contrast
    ``delta = |rgb_x - rgb_y| / sqrt(2)`` (pairs with delta < 0.05 ignored),
    score ``mean log(exp(-(l + delta)^2 / sigma^2) + exp(-(l - delta)^2 / sigma^2))``
    with ``l`` the gray difference; the best score wins.

    Parameters
    ----------
    rgb : ndarray of float, shape (h, w, 3)
        Colour in [0, 1].
    sigma : float
    rng : None, int or numpy Generator
        None: a fixed seed.

    Returns
    -------
    tuple of float
        ``(w_r, w_g, w_b)``.
    """
    rng = np.random.default_rng(0 if rng is None else rng)
    h, w = rgb.shape[:2]
    scale = 64.0 / np.sqrt(h * w)
    ys = np.minimum((np.arange(max(1, round(h * scale))) / scale).astype(int), h - 1)
    xs = np.minimum((np.arange(max(1, round(w * scale))) / scale).astype(int), w - 1)
    small = rgb[np.ix_(ys, xs)].astype(np.float64)
    flat = small.reshape(-1, 3)
    pg = flat - flat[rng.permutation(len(flat))]
    half = small[::2, ::2]
    px = (half[:, :-1] - half[:, 1:]).reshape(-1, 3)
    py = (half[:-1, :] - half[1:, :]).reshape(-1, 3)
    p = np.concatenate([pg, px, py])
    det = np.sqrt((p ** 2).sum(axis=1)) / 1.41
    keep = det >= 0.05
    p, det = p[keep], det[keep]
    grid = [(r / 10, g / 10, (10 - r - g) / 10) for r in range(11) for g in range(11 - r)]
    wts = np.asarray(grid).T  # (3, 66)
    if len(p) == 0:
        return (0.299, 0.587, 0.114)
    l = p @ wts
    d = det[:, None]
    u = np.logaddexp(-((l + d) ** 2) / sigma ** 2, -((l - d) ** 2) / sigma ** 2)
    best = int(np.argmax(u.mean(axis=0)))
    return tuple(round(float(v), 1) for v in wts[:, best])


def read_mask(path, *, size, crop, source_size):
    """Importance weights from a mask picture of the source's size.

    White is important (weight 2.0), black is not (1.0), gray scales between.

    Returns
    -------
    ndarray of float32, shape (size, size)
    """
    im = _open(path, "mask")
    if im.size != tuple(source_size):
        raise BadInput(f"mask {str(path)!r} is {im.size[0]} x {im.size[1]}; expected the picture's size "
                       f"{source_size[0]} x {source_size[1]}")
    cx, cy, r = crop["cx"], crop["cy"], crop["r"]
    try:
        small = _cut(im, (cx - r, cy - r, cx + r, cy + r), size).convert("L")
    except (OSError, SyntaxError, ValueError, EOFError) as exc:
        raise BadInput(f"mask {str(path)!r} is damaged or truncated ({exc}); expected a complete picture") from None
    return 1.0 + np.asarray(small, dtype=np.float32) / 255.0
