"""Faces: find the largest frontal face, keep it in the crop, weigh it.

A portrait is judged by its face.  ``stringbot plan IMG --face`` (and
``--face auto``, when a face is found) keeps the largest face in the crop,
raises the weight of the face (its eyes, mouth and outline) in the
planner's importance map, so that the threads go where the eye looks first.

Finding the face
    scikit-image's LBP frontal-face cascade
    (:func:`skimage.data.lbp_frontal_face_cascade_filename`,
    :class:`skimage.feature.Cascade`; shipped with scikit-image, nothing to
    download) looks at the picture's luminance reduced to
    :data:`DETECT_SIDE` pixels on its longer side.  The cascade is asked for
    every window it accepts, unmerged; windows about the same place and size
    are grouped, and a group is a face when at least :data:`MIN_VOTES`
    windows agree (a true face gathers 14 to 50 at this size on the test
    portraits, the cascade's false alarms on the sample pictures at most 5).
    Of the faces, the largest is kept.

The crop
    The default crop (the largest circle the picture holds, centred) when
    the face box lies inside it, else moved towards the face as little as
    holds it, never shrunk (centring the crop on the face, and a crop closer
    about it, lowered the face's SSIM as woven: docs/planner.md, "Faces").

The weights
    1 everywhere, raised over the face (:data:`FACE_WEIGHT` over a
    soft-edged ellipse about the box, which holds its eyes, mouth and
    outline); :func:`face_weights` can raise the eyes and the mouth further
    (Gaussian spots) and the face's edges (the picture's gradient inside it),
    but measured as woven that lowered the face's SSIM, so by default they get
    nothing more (:data:`EYE_WEIGHT`, :data:`MOUTH_WEIGHT`,
    :data:`EDGE_WEIGHT`).  Smooth Gaussian bumps, larger or smaller
    ellipses and the ellipse weighed by the face's local contrast did no
    better either (``benchmarks/bench_face.py --shapes``).  The eyes and the
    mouth are placed by the face
    box's proportions (:data:`EYE_ROW`, :data:`EYE_COL`, :data:`MOUTH_ROW`),
    which placed them better than a second look for the darkest spots inside
    the box (docs/planner.md, "Faces").

Every position is ``(row, col)``; boxes are ``(row, col, height, width)``
with ``(row, col)`` the top-left corner, in the source picture's pixels.
"""

import logging
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["Face", "find_faces", "largest_face", "face_for_plan", "crop_on_face", "face_crop", "face_weights",
           "face_box_pixels", "DETECT_SIDE", "MIN_VOTES", "FACES"]

#: ``--face`` values: ``auto`` uses a face when one is found, ``on`` requires one, ``off`` never looks
FACES = ("auto", "on", "off")
#: the longer side, in pixels, of the picture the cascade looks at (faces of 24 px and more there: a face
#: at least 7.5 % of the picture's longer side); a smaller picture is looked at as it is
DETECT_SIDE = 320
#: the cascade's windows that must agree on a place and size for a face
MIN_VOTES = 8
#: the windows' scale step, as in scikit-image's example
SCALE_FACTOR = 1.1
#: extra weight inside the face, and on top of it on each eye, on the mouth and on the face's strongest
#: edges: the face raised alike gave its SSIM as woven more than eyes, mouth and edges raised above it;
#: +2 balances the face's gain against the frame's loss (+1: less for the face, +3: more off the frame;
#: docs/planner.md, "Faces")
FACE_WEIGHT, EYE_WEIGHT, MOUTH_WEIGHT, EDGE_WEIGHT = 2.0, 0.0, 0.0, 0.0
#: the eyes' and the mouth's place in the cascade's box, as shares of its height and width
EYE_ROW, EYE_COL, MOUTH_ROW = 0.38, 0.30, 0.77


@dataclass(frozen=True)
class Face:
    """A face found in a picture.

    Attributes
    ----------
    row, col : float
        The top-left corner of the face box, in source pixels.
    height, width : float
        The face box's size, in source pixels.
    votes : int
        How many of the cascade's windows agree on it.
    """

    row: float
    col: float
    height: float
    width: float
    votes: int

    @property
    def centre(self):
        """``(row, col)`` of the box's centre."""
        return self.row + self.height / 2.0, self.col + self.width / 2.0

    @property
    def eyes(self):
        """``((row, col), (row, col))``: the eyes (left of the picture first), by the box's proportions."""
        r = self.row + EYE_ROW * self.height
        return (r, self.col + EYE_COL * self.width), (r, self.col + (1.0 - EYE_COL) * self.width)

    @property
    def mouth(self):
        """``(row, col)`` of the mouth, by the box's proportions."""
        return self.row + MOUTH_ROW * self.height, self.col + 0.5 * self.width

    def to_record(self):
        """The face as the plan's parameters record it (source pixels, rounded)."""
        return {"box": [round(float(v), 1) for v in (self.row, self.col, self.height, self.width)],
                "votes": int(self.votes),
                "eyes": [[round(float(v), 1) for v in p] for p in self.eyes],
                "mouth": [round(float(v), 1) for v in self.mouth]}


def _cascade():
    from skimage.data import lbp_frontal_face_cascade_filename
    from skimage.feature import Cascade

    return Cascade(lbp_frontal_face_cascade_filename())


def _group(windows):
    """Group windows ``(row, col, side)`` about the same place and size: ``[(votes, row, col, side)]``,
    most votes first (each group the median of its windows)."""
    b = np.asarray(windows, dtype=np.float64).reshape(-1, 3)
    centre = b[:, :2] + b[:, 2:3] / 2.0
    side = b[:, 2]
    near = ((np.hypot(*(centre[:, None, :] - centre[None, :, :]).transpose(2, 0, 1))
             < 0.25 * np.minimum(side[:, None], side[None, :]))
            & (np.maximum(side[:, None], side[None, :]) < 1.5 * np.minimum(side[:, None], side[None, :])))
    free = np.ones(len(b), dtype=bool)
    groups = []
    while free.any():
        counts = (near & free[None, :]).sum(axis=1) * free
        seed = int(np.argmax(counts))
        members = near[seed] & free
        free &= ~members
        groups.append((int(members.sum()), *np.median(b[members], axis=0)))
    return sorted(groups, key=lambda g: -g[0])


def find_faces(gray, *, min_votes=MIN_VOTES):
    """Frontal faces in a gray picture.

    Parameters
    ----------
    gray : ndarray, shape (h, w)
        Gray levels 0..255 (or 0..1), at about :data:`DETECT_SIDE` pixels on the longer side.
    min_votes : int
        Windows of the cascade that must agree on a face.

    Returns
    -------
    list of Face
        In the pixels of ``gray``, most votes first.
    """
    g = np.asarray(gray, dtype=np.float64)
    if g.max(initial=0.0) > 1.0:
        g = g / 255.0
    side = min(g.shape)
    if side < 24:
        return []
    raw = _cascade().detect_multi_scale(img=g, scale_factor=SCALE_FACTOR, step_ratio=1, min_size=(24, 24),
                                        max_size=(side, side), min_neighbor_number=1,
                                        intersection_score_threshold=2.0)  # above 1: nothing merged
    if not raw:
        return []
    groups = _group([(d["r"], d["c"], d["width"]) for d in raw])
    return [Face(row=float(r), col=float(c), height=float(s), width=float(s), votes=int(n))
            for n, r, c, s in groups if n >= min_votes]


def face_for_plan(path, *, face="auto"):
    """Resolve ``--face`` for a plan: the face to centre on and weigh, or None.

    Parameters
    ----------
    path : str or Path
        The picture.
    face : {"auto", "on", "off"}
        ``auto``: the largest face when there is one; ``on``: require one
        (:class:`~stringbot.errors.BadInput` when there is none); ``off``: do not look.

    Returns
    -------
    Face or None
        In source pixels.
    """
    from ...errors import BadInput

    if face not in FACES:
        raise BadInput(f"--face {face!r}; expected one of {', '.join(FACES)}")
    if face == "off":
        return None
    found = largest_face(path)
    if found is None:
        if face == "on":
            raise BadInput(f"no face found in {str(path)!r} (the frontal-face cascade finds faces seen from the "
                           f"front, at least {24 / DETECT_SIDE:.0%} of the picture's longer side); plan with "
                           "--face auto or without --face (and choose the part to paint with --crop CX,CY,R)")
        log.info("face: none found in %s; the crop and the weights are as without --face", path)
        return None
    log.info("face: found at rows %.0f-%.0f, columns %.0f-%.0f (%d votes)", found.row, found.row + found.height,
             found.col, found.col + found.width, found.votes)
    return found


def crop_on_face(path, face):
    """:func:`face_crop` of a face in the picture at ``path`` (its size as shown)."""
    from .read import fit_crop

    whole = fit_crop(path, "square")
    return face_crop(face, width=2 * whole["cx"], height=2 * whole["cy"])


def largest_face(path, *, min_votes=MIN_VOTES):
    """The largest frontal face in a picture file, or None.

    Parameters
    ----------
    path : str or Path
        The picture (read as :func:`~stringbot.planner.picture.read.read_picture` reads it: EXIF
        orientation applied, transparency on white).
    min_votes : int

    Returns
    -------
    Face or None
        In source pixels (of the picture as shown).
    """
    from .read import fit_crop, read_picture

    whole = fit_crop(path, "square")  # the square about the whole picture, white beyond it
    side = int(min(DETECT_SIDE, round(2 * whole["r"])))  # a small picture as it is
    pic = read_picture(path, size=side, crop=whole, gray="luminance", what="picture")
    faces = find_faces(pic.gray, min_votes=min_votes)
    if not faces:
        return None
    f = max(faces, key=lambda x: (x.width, x.votes))
    k = 2.0 * whole["r"] / side
    y0, x0 = whole["cy"] - whole["r"], whole["cx"] - whole["r"]
    return Face(row=y0 + f.row * k, col=x0 + f.col * k, height=f.height * k, width=f.width * k, votes=f.votes)


def face_crop(face, *, width, height):
    """The crop that holds a face: the default crop (the largest circle the picture holds, centred) when
    the face box lies inside it, else that circle moved towards the face box's centre as little as holds
    the box (in steps of a hundredth of the way), or as near to it as the picture allows.  (Centring the
    crop on the face lowered the face's SSIM as woven and the frame's: docs/planner.md, "Faces".)

    Parameters
    ----------
    face : Face
        In source pixels.
    width, height : int
        The picture's size.

    Returns
    -------
    dict
        ``{"cx", "cy", "r"}`` in source pixels, inside the picture.
    """
    r = min(width, height) / 2.0
    cy, cx = face.centre
    near = np.array([width / 2.0, height / 2.0])
    far = np.array([np.clip(cx, r, width - r), np.clip(cy, r, height - r)])
    corners = np.array([(face.col + dx, face.row + dy) for dx in (0.0, face.width) for dy in (0.0, face.height)])
    at = far
    for t in np.linspace(0.0, 1.0, 101):
        centre = near + t * (far - near)
        if np.hypot(*(corners - centre).T).max() <= r:
            at = centre
            break
    return {"cx": float(at[0]), "cy": float(at[1]), "r": float(r)}


def face_box_pixels(box, *, crop, size):
    """A box in source pixels as ``(row0, col0, row1, col1)`` pixels of a ``size``-pixel picture of ``crop``
    (clipped to it; end exclusive)."""
    k = size / (2.0 * crop["r"])
    y0, x0 = crop["cy"] - crop["r"], crop["cx"] - crop["r"]
    r, c, h, w = box
    out = [int(np.floor((r - y0) * k)), int(np.floor((c - x0) * k)),
           int(np.ceil((r + h - y0) * k)), int(np.ceil((c + w - x0) * k))]
    return tuple(int(np.clip(v, 0, size)) for v in out)


def face_weights(face, *, crop, size, gray, times=None, strength=None, eyes=None, mouth=None, edges=None):
    """The importance map of a face at the working size.

    Parameters
    ----------
    face : Face
        In source pixels.
    crop : dict
        ``{"cx", "cy", "r"}``: the plan's crop.
    size : int
        The working size.
    gray : ndarray, shape (size, size)
        The picture at the working size (0..255): its edges inside the face are raised.
    times : ndarray, shape (size, size), optional
        Other weights (an importance mask's) to multiply.
    strength, eyes, mouth, edges : float, optional
        Extra weight over the face, on each eye, on the mouth and on the face's strongest edges
        (defaults: :data:`FACE_WEIGHT`, :data:`EYE_WEIGHT`, :data:`MOUTH_WEIGHT`, :data:`EDGE_WEIGHT`).

    Returns
    -------
    ndarray of float32, shape (size, size)
        1 away from the face, ``1 + strength`` over it (a soft-edged ellipse about the box), more on the
        features.
    """
    from scipy.ndimage import gaussian_filter, sobel

    strength = FACE_WEIGHT if strength is None else strength
    eyes = EYE_WEIGHT if eyes is None else eyes
    mouth = MOUTH_WEIGHT if mouth is None else mouth
    edges = EDGE_WEIGHT if edges is None else edges
    k = size / (2.0 * crop["r"])  # working pixels per source pixel
    y0, x0 = crop["cy"] - crop["r"], crop["cx"] - crop["r"]
    rows, cols = np.mgrid[0:size, 0:size].astype(np.float64) + 0.5
    rows, cols = rows / k + y0, cols / k + x0  # each pixel's centre in source pixels
    w = face.width
    cy, cx = face.centre

    def spot(p, sr, sc):
        return np.exp(-0.5 * (((rows - p[0]) / sr) ** 2 + ((cols - p[1]) / sc) ** 2))

    # the face: an ellipse a little taller than the box (the cascade's box cuts the forehead and the chin)
    d = np.hypot((rows - cy) / (0.62 * face.height), (cols - cx) / (0.5 * w))
    inside = np.clip((1.15 - d) / 0.3, 0.0, 1.0)
    out = 1.0 + strength * inside
    if eyes:
        for eye in face.eyes:
            out += eyes * spot(eye, 0.08 * w, 0.11 * w)
    if mouth:
        out += mouth * spot(face.mouth, 0.07 * w, 0.16 * w)
    if edges and (inside > 0.5).any():
        g = gaussian_filter(np.asarray(gray, dtype=np.float64), max(0.7, 0.01 * w * k))
        grad = np.hypot(sobel(g, 0), sobel(g, 1))
        top = float(np.percentile(grad[inside > 0.5], 90))
        if top > 0:
            out += edges * inside * np.clip(grad / top, 0.0, 1.0)
    return (out if times is None else out * times).astype(np.float32)
