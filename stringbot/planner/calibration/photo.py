"""Reading a photo of a wound calibration sheet: where it is, how it is lit, how dark each patch is.

The steps (:func:`fit_photo`):

1. **The photo** (:func:`read_photo`): read as luminance (any PIL picture; EXIF
   orientation applied; longer side reduced to :data:`MAX_SIDE`), decoded from
   sRGB to linear light, where light from thread and board adds up by area.
2. **The sheet** (:func:`find_sheet`): the four corner marks are dark blobs on
   white once the photo is divided by the local paper level; a mark is a filled
   ellipse (a printed disc seen in perspective), the top-left one hollow.  The
   hollow one and three discs going round it clockwise (the photo is not
   mirrored) fix the perspective, a homography from the sheet's millimetres to
   the photo's pixels, refined on the full photo (each mark's centre of
   darkness, corrected for the shift of a disc's centre under perspective).
3. **The light** (:func:`illumination`): where the sheet is known to be bare --
   paper outside the pin circle away from marks and labels, board between the
   patches away from every thread -- the photo is ``light(x, y) * reflectance``
   with a smooth light (the exponential of a cubic in the sheet's coordinates)
   and reflectance 1 on paper and ``board`` on the board: one robust linear
   least-squares fit (Huber weights) gives both.
4. **The patches** (:func:`measure_cells`): each cell's mean reflectance,
   every photo pixel inside it weighted by the sheet area it sees.
5. **The thread** (:func:`fit_thread`): a cell covered a fraction ``F(w)`` by
   threads of width ``w`` (:func:`~stringbot.planner.calibration.sheet.cell_coverage`,
   the exact union of sharp bands) reflects ``board - (board - thread) F(w)``;
   ``w`` and ``thread`` by least squares over the cells (scipy).

The width is an *effective* width: the one a sharp-edged opaque thread would
need to darken the board as the real one does.  A thread that lets some board
through (fuzz, a translucent fibre) of width ``w`` and opacity ``o`` darkens
exactly as an opaque one of width ``o w`` wherever threads cross at an angle,
so a photo tells ``o w``, never ``o`` and ``w`` apart (docs/maker.md).
"""

import itertools
import logging
import math
from dataclasses import dataclass

import numpy as np

from ...errors import BadInput
from .sheet import cell_coverage

log = logging.getLogger(__name__)

__all__ = ["read_photo", "find_sheet", "illumination", "measure_cells", "fit_thread", "fit_photo", "Fit",
           "MAX_SIDE"]

#: the photo's longer side is reduced to this many pixels
MAX_SIDE = 3000
#: side of the working image in which the marks are looked for
FIND_SIDE = 1200
#: at most this many disc candidates are tried as the three discs
MAX_DISCS = 10
EXPECTED = ("expected a photo of the whole wound sheet from `stringbot calibrate sheet`, taken from the front, "
            "its four corner marks in view (the hollow one at the top left)")


def read_photo(path, *, what="photo"):
    """The photo as linear-light luminance.

    Returns
    -------
    ndarray of float32, shape (rows, cols)
        Linear light in [0, 1] (sRGB decoded); pixel ``(r, c)`` is centred on ``(x, y) = (c, r)``.
    """
    from ..picture.read import _upright_size, read_picture
    from ..colour.palette import to_linear

    w, h = _upright_size(path, what)
    side = max(w, h)
    size = min(side, MAX_SIDE)
    pic = read_picture(path, size=size, crop={"cx": w / 2.0, "cy": h / 2.0, "r": side / 2.0},
                       gray="luminance", what=what)
    k = size / side
    r0, r1 = int(round((side - h) / 2 * k)), int(round((side + h) / 2 * k))
    c0, c1 = int(round((side - w) / 2 * k)), int(round((side + w) / 2 * k))
    return to_linear(pic.gray[r0:r1, c0:c1] / 255.0).astype(np.float32)


def _paper_level(image, size):
    """The local level of white: a maximum filter wider than a mark, smoothed."""
    from scipy import ndimage

    return ndimage.uniform_filter(ndimage.maximum_filter(image, size=size), size=size)


def _blobs(small):
    """Mark candidates in the working image: ``(kind, (x, y), filled_area)``, kind "ring" or "disc"."""
    from skimage.measure import label, regionprops

    side = max(small.shape)
    norm = small / np.maximum(_paper_level(small, max(3, int(0.15 * side))), 1e-6)
    lo, hi = math.pi * (0.008 * side) ** 2, math.pi * (0.15 * side) ** 2
    found = []
    for reg in regionprops(label(norm < 0.5)):
        if not lo <= reg.area_filled <= hi:
            continue
        filled = regionprops(reg.image_filled.astype(np.uint8))[0]
        major, minor = filled.axis_major_length, filled.axis_minor_length
        if minor < 0.3 * major or filled.solidity < 0.93:
            continue
        if not 0.85 <= filled.area / (math.pi / 4 * major * minor) <= 1.15:
            continue
        hole = 1.0 - reg.area / reg.area_filled
        kind = "disc" if hole < 0.1 else "ring" if 0.12 <= hole <= 0.6 and reg.euler_number == 0 else None
        if kind:
            r0, c0 = reg.bbox[:2]
            y, x = filled.centroid
            found.append((kind, (c0 + x, r0 + y), float(reg.area_filled), reg.bbox))
    return found


def _homography(src, dst):
    from skimage.transform import estimate_transform

    return estimate_transform("projective", np.asarray(src, float), np.asarray(dst, float))


def _disc_outline(tf, x, y, r, n=64):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return tf(np.stack([x + r * np.cos(t), y + r * np.sin(t)], axis=1))


def _polygon_area_centroid(p):
    x, y = p[:, 0], p[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cross = x * y1 - x1 * y
    area = cross.sum() / 2.0
    return abs(area), np.array([((x + x1) * cross).sum(), ((y + y1) * cross).sum()]) / (6.0 * area)


def _clockwise(pts):
    """The four points go round clockwise as seen (y down) and make a convex quadrilateral."""
    d = np.roll(pts, -1, axis=0) - pts
    cross = d[:, 0] * np.roll(d, -1, axis=0)[:, 1] - d[:, 1] * np.roll(d, -1, axis=0)[:, 0]
    return bool((cross > 0).all())


def find_sheet(photo, sheet, *, what="photo"):
    """The homography from the sheet's millimetres to the photo's pixels, from its four marks.

    Returns
    -------
    skimage.transform.ProjectiveTransform
        ``tf(xy_mm) -> (x, y)`` pixels; ``tf.inverse`` the other way.

    Raises
    ------
    BadInput
        Naming what was found when the four marks are not.
    """
    from skimage.transform import downscale_local_mean

    f = max(1, int(math.ceil(max(photo.shape) / FIND_SIDE)))
    rows, cols = (photo.shape[0] // f) * f, (photo.shape[1] // f) * f
    small = downscale_local_mean(photo[:rows, :cols], (f, f)) if f > 1 else photo
    blobs = _blobs(small)
    rings = [b for b in blobs if b[0] == "ring"]
    discs = sorted((b for b in blobs if b[0] == "disc"), key=lambda b: -b[2])[:MAX_DISCS]
    marks = sheet.marks
    best = None
    for ring in rings:
        for trio in itertools.permutations(discs, 3):
            quad = [ring, *trio]
            pts = np.array([b[1] for b in quad])
            if not _clockwise(pts):
                continue
            tf = _homography(marks[:, :2], pts)
            areas = [_polygon_area_centroid(_disc_outline(tf, *m))[0] for m in marks]
            if max(abs(math.log(a / b[2])) for a, b in zip(areas, quad)) > math.log(1.6):
                continue
            size = _polygon_area_centroid(pts)[0]
            if best is None or size > best[0]:
                best = (size, quad)
    if best is None:
        raise BadInput(f"{what}: the calibration sheet's marks were not found (hollow ring marks: "
                       f"{len(rings)}, disc marks: {len([b for b in blobs if b[0] == 'disc'])}; a hollow one "
                       f"and three discs round it clockwise are needed); {EXPECTED}")
    centres = np.array([_refine_centre(photo, bbox, f, ((x + 0.5) * f - 0.5, (y + 0.5) * f - 0.5))
                        for _, (x, y), _, bbox in best[1]])
    tf = _homography(marks[:, :2], centres)
    for _ in range(2):   # a disc's centre of darkness is not the image of its centre under perspective
        shift = np.array([_polygon_area_centroid(_disc_outline(tf, *m))[1] - tf(m[None, :2])[0] for m in marks])
        tf = _homography(marks[:, :2], centres - shift)
    return tf


def _refine_centre(photo, bbox, f, near):
    """A mark's centre of darkness on the full photo, within its (working image) box: the dark
    piece there that holds (or is the largest, if none holds) the rough centre ``near``."""
    from scipy import ndimage

    r0, c0, r1, c1 = bbox
    pad_r, pad_c = (r1 - r0) // 3 + 1, (c1 - c0) // 3 + 1
    r0, c0 = max(0, (r0 - pad_r) * f), max(0, (c0 - pad_c) * f)
    r1, c1 = min(photo.shape[0], (r1 + pad_r) * f), min(photo.shape[1], (c1 + pad_c) * f)
    win = photo[r0:r1, c0:c1]
    paper, ink = np.percentile(win, 95), np.percentile(win, 2)
    dark = ndimage.binary_fill_holes(win < (paper + ink) / 2)
    lab, n = ndimage.label(dark)
    if n > 1:
        rc = int(np.clip(round(near[1]) - r0, 0, win.shape[0] - 1)), int(np.clip(round(near[0]) - c0, 0,
                                                                                   win.shape[1] - 1))
        keep = lab[rc] or 1 + int(np.argmax(ndimage.sum(dark, lab, range(1, n + 1))))
        dark = lab == keep
    y, x = ndimage.center_of_mass(dark)
    return c0 + x, r0 + y


#: paper used for the light lies this fraction of the diameter outside the pin circle (the ring's body)
RING_OUT = 0.06
#: bare board used for the light is this fraction of the diameter from every thread
BARE_MARGIN = 0.012


def _classes(sheet, step):
    """Sheet map of what is known bare: 1 paper, 2 board, 0 anything else; ``step`` mm a cell.

    Returns ``(classes, origin)``: ``classes[i, j]`` is at ``(origin + j * step, origin + i * step)``.
    """
    from scipy import ndimage
    from skimage.draw import line

    d, r, h = sheet.diameter_mm, sheet.radius_mm, sheet.half_mm
    n = int(math.ceil(2 * h / step)) + 1
    origin = -h
    ax = origin + np.arange(n) * step
    x, y = np.meshgrid(ax, ax)
    rad = np.hypot(x, y)
    ink = np.zeros((n, n), bool)
    for a, b in sheet.chord_mm():
        rr, cc = line(*(int(round((v - origin) / step)) for v in (a[1], a[0], b[1], b[0])))
        ok = (rr >= 0) & (rr < n) & (cc >= 0) & (cc < n)
        ink[rr[ok], cc[ok]] = True
    far = ndimage.distance_transform_edt(~ink) * step > BARE_MARGIN * d
    paper = (np.maximum(abs(x), abs(y)) <= h - 0.02 * d) & (rad >= r + RING_OUT * d)
    for mx, my, mr in sheet.marks:
        paper &= np.hypot(x - mx, y - my) > 1.4 * mr
    for _, _, (x0, y0, x1, y1) in sheet.labels:
        e = 0.02 * d
        paper &= ~((x > x0 - e) & (x < x1 + e) & (y > y0 - e) & (y < y1 + e))
    board = (rad <= r - sheet.rim_mm) & far
    return np.where(paper, 1, np.where(board, 2, 0)).astype(np.uint8), origin


def _terms(u, v):
    """The light's terms: monomials of degree <= 3 in the sheet's coordinates over its half side."""
    return np.stack([u ** i * v ** j for i in range(4) for j in range(4 - i)], axis=-1)


@dataclass(frozen=True)
class Light:
    """The photo's light on the sheet: ``light(x_mm, y_mm)``; the board's reflectance (paper = 1)."""

    coef: np.ndarray
    half_mm: float
    board: float
    #: robust spread of the log residuals on the bare areas (0.01: 1 %)
    spread: float
    paper_px: int
    board_px: int

    def __call__(self, x, y):
        return np.exp(_terms(np.asarray(x) / self.half_mm, np.asarray(y) / self.half_mm) @ self.coef)


def illumination(photo, tf, sheet, *, samples=200_000, what="photo"):
    """Fit the light and the board from the photo's known bare paper and board (module notes, 3).

    Returns
    -------
    Light
    """
    step = max(0.25, sheet.diameter_mm / 600.0)
    classes, origin = _classes(sheet, step)
    stride = max(1, int(math.sqrt(photo.size / samples)))
    r, c = np.mgrid[0:photo.shape[0]:stride, 0:photo.shape[1]:stride]
    r, c = r.ravel(), c.ravel()
    xy = tf.inverse(np.stack([c, r], axis=1).astype(float))
    i = np.rint((xy[:, 1] - origin) / step).astype(int)
    j = np.rint((xy[:, 0] - origin) / step).astype(int)
    ok = (i >= 0) & (i < classes.shape[0]) & (j >= 0) & (j < classes.shape[1])
    kind = np.zeros(len(r), np.uint8)
    kind[ok] = classes[i[ok], j[ok]]
    use = kind > 0
    paper_px, board_px = int((kind == 1).sum()), int((kind == 2).sum())
    if paper_px < 500 or board_px < 500:
        raise BadInput(f"{what}: too little bare paper ({paper_px} samples) or bare board ({board_px}) is in "
                       f"view to tell the light; {EXPECTED}")
    a = np.concatenate([_terms(xy[use, 0] / sheet.half_mm, xy[use, 1] / sheet.half_mm),
                        (kind[use] == 2).astype(float)[:, None]], axis=1)
    y = np.log(np.maximum(photo[r[use], c[use]].astype(float), 1e-4))
    w = np.ones(len(y))
    for _ in range(8):                      # iteratively reweighted least squares, Huber weights
        aw = a * w[:, None]
        coef = np.linalg.solve(aw.T @ a, aw.T @ y)
        res = y - a @ coef
        spread = 1.4826 * np.median(np.abs(res - np.median(res))) + 1e-6
        w = np.minimum(1.0, 1.345 * spread / np.maximum(np.abs(res), 1e-12))
    return Light(coef=coef[:-1], half_mm=sheet.half_mm, board=float(np.exp(coef[-1])), spread=float(spread),
                 paper_px=paper_px, board_px=board_px)


def measure_cells(photo, tf, sheet, light):
    """Each cell's mean reflectance (paper = 1), pixels weighted by the sheet area each sees.

    Returns
    -------
    (ndarray of float, shape (cells,), ndarray of int, shape (cells,))
        The reflectances (NaN where a cell is not wholly in the photo) and the pixels used.
    """
    from skimage.draw import polygon

    inv = tf.inverse.params
    mean = np.full(len(sheet.cells), np.nan)
    count = np.zeros(len(sheet.cells), int)
    for k, (x0, x1, y0, y1) in enumerate(sheet.cells):
        corners = tf(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
        rr, cc = polygon(corners[:, 1], corners[:, 0], shape=photo.shape)
        if not len(rr):
            continue
        h = inv @ np.stack([cc, rr, np.ones(len(rr))])
        area = abs(np.linalg.det(inv)) / np.abs(h[2]) ** 3        # sheet mm^2 per pixel
        if area.sum() < 0.9 * (x1 - x0) * (y1 - y0):
            continue
        refl = photo[rr, cc] / light(h[0] / h[2], h[1] / h[2])
        mean[k] = float((refl * area).sum() / area.sum())
        count[k] = len(rr)
    return mean, count


@dataclass(frozen=True)
class Fit:
    """A fitted thread (linear-light reflectances; the paper's white is 1).

    ``board_gray`` and ``thread_gray`` are the same as sRGB gray levels (0 black, 1 the paper), as a
    picture's pixels are; ``cells`` is ``(strip, covered, observed, model)`` per measured cell.
    """

    effective_mm: float
    board: float
    thread: float
    rms: float
    cells: tuple
    light_spread: float

    @property
    def board_gray(self):
        from ..colour.palette import to_srgb
        return float(to_srgb(self.board))

    @property
    def thread_gray(self):
        from ..colour.palette import to_srgb
        return float(to_srgb(self.thread))


def fit_thread(sheet, observed, board, *, what="photo"):
    """Least-squares width and thread reflectance for the cells' ``observed`` reflectances.

    Parameters
    ----------
    sheet : Sheet
    observed : ndarray of float, shape (cells,)
        Mean reflectance per cell (NaN: not measured).
    board : float
        The bare board's reflectance.

    Returns
    -------
    (width_mm, thread, rms, covered)
        ``covered`` the cells' covered fractions at the fitted width.

    Raises
    ------
    BadInput
        Too few cells, or patches no darker than the board (a sheet not wound).
    """
    from scipy.interpolate import CubicSpline
    from scipy.optimize import least_squares

    ok = np.isfinite(observed)
    if ok.sum() < 6:
        raise BadInput(f"{what}: only {int(ok.sum())} of the sheet's {len(observed)} patch cells are in view; "
                       f"{EXPECTED}")
    contrast = (board - observed[ok]) / board
    if contrast.max() < 0.03:
        raise BadInput(f"{what}: the patches are no darker than the bare board (at most {100 * contrast.max():.1f} "
                       "% darker); expected a photo of the sheet wound with its thread (`stringbot wind`)")
    nominal = sheet.thread_mm
    grid = np.geomspace(nominal / 6.0, nominal * 6.0, 41)
    spline = CubicSpline(np.log(grid), cell_coverage(sheet, grid)[ok].T)
    obs = observed[ok]

    def residuals(p):
        thread, lw = p
        return board - (board - thread) * spline(lw) - obs

    def jacobian(p):
        thread, lw = p
        return np.stack([spline(lw), -(board - thread) * spline(lw, 1)], axis=1)

    best = None
    for start in (0.25, 1.0, 4.0):
        sol = least_squares(residuals, [0.05 * board, math.log(nominal * start)], jac=jacobian,
                            bounds=([0.0, math.log(grid[0])], [0.999 * board, math.log(grid[-1])]), x_scale=[0.1, 0.3])
        if best is None or sol.cost < best.cost:
            best = sol
    thread, lw = best.x
    width = math.exp(lw)
    if not grid[1] <= width <= grid[-2]:
        raise BadInput(f"{what}: the fitted thread width {width:.3f} mm is at the end of the range the sheet "
                       f"measures ({grid[0]:.3f}..{grid[-1]:.3f} mm for its {nominal:g} mm thread); expected a "
                       "photo of the sheet wound with the machine's thread")
    covered = np.full(len(observed), np.nan)
    covered[ok] = spline(lw)
    return width, float(thread), float(np.sqrt(np.mean(best.fun ** 2))), covered


def fit_photo(path, sheet, *, what="photo"):
    """Read a photo of the wound ``sheet`` and fit its thread (the module notes' five steps).

    ``what`` names the photo in error messages (with its path).

    Returns
    -------
    Fit
    """
    photo = read_photo(path, what=what)
    what = f"{what} {str(path)!r}"
    tf = find_sheet(photo, sheet, what=what)
    light = illumination(photo, tf, sheet, what=what)
    observed, _ = measure_cells(photo, tf, sheet, light)
    width, thread, rms, covered = fit_thread(sheet, observed, light.board, what=what)
    model = light.board - (light.board - thread) * covered
    names = [sheet.strips[k].name for k in sheet.cell_strip]
    cells = tuple((n, float(c), float(o), float(m)) for n, c, o, m in zip(names, covered, observed, model)
                  if np.isfinite(o))
    log.info("%s: thread %.4f mm, board %.4f, thread %.4f (linear), RMS %.4f over %d cells", what, width,
             light.board, thread, rms, len(cells))
    return Fit(effective_mm=width, board=light.board, thread=thread, rms=rms, cells=cells,
               light_spread=light.spread)
