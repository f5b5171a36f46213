"""Synthetic photos of a wound calibration sheet, for benchmarks/bench_calibrate.py and the tests.

Made independently of the fit's model: every photo pixel is sampled ``k x k``
times; each sample is mapped back to the sheet through the camera's
homography and coloured by what lies there (table, paper, the board inside the
cut circle, the printed marks and labels, the pins); the threads are sharp
opaque bands of a known width, each drawn as the photo image of its rectangle
(``skimage.draw.polygon`` on the sample grid, so perspective thins and thickens
them as a camera would).  The samples are averaged in linear light, then lit
(a gradient and a vignette), blurred, given noise and written as 8-bit sRGB.
"""

import numpy as np
from scipy import ndimage
from skimage.draw import polygon
from skimage.transform import estimate_transform

from stringbot.planner.colour.palette import to_srgb


def camera(sheet, shape, *, tilt=(0.0, 0.0), turn=0.0, fill=0.85, shift=(0.0, 0.0)):
    """A homography sheet mm -> photo (x, y) px: the sheet centred, ``fill`` of the short side, turned
    ``turn`` degrees, its far edges shrunk by ``tilt`` = (left-right, top-bottom) fractions (perspective)."""
    rows, cols = shape
    h = sheet.half_mm
    s = fill * min(rows, cols) / (2 * h)
    corners = np.array([[-h, -h], [h, -h], [h, h], [-h, h]])
    tx, ty = tilt
    squeeze = np.array([[1 - ty, 1 - tx], [1 - ty, 1 + tx], [1 + ty, 1 + tx], [1 + ty, 1 - tx]])
    a = np.radians(turn)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    pts = (corners * squeeze) @ rot.T * s
    pts += [cols / 2 + shift[0] * cols, rows / 2 + shift[1] * rows]
    return estimate_transform("projective", corners, pts)


def render_photo(sheet, tf, shape, *, width_mm, thread=0.03, board=0.80, paper=0.95, ink=0.03, table=0.25,
                 pins=0.35, gradient=(0.35, 30.0), vignette=0.25, light=0.9, blur=0.8, noise=0.01, k=4,
                 threads=True, marks=True, opacity=1.0, offset_mm=(0.0, 0.0), rng=0):
    """An 8-bit gray photo (ndarray of uint8, shape ``shape``) of ``sheet`` seen through ``tf``.

    Reflectances are linear light; ``gradient`` = (strength, direction in degrees) of a linear light
    gradient across the photo, ``vignette`` its fall-off towards the corners.  ``opacity`` < 1: each
    thread lets that much less than all of what lies under it through (a spot under ``n`` threads is
    ``thread + (under - thread) (1 - opacity) ** n``).  ``offset_mm``: the threads and pins lie that far
    from where the printed sheet says (a sheet laid off, or threads seen aside of the paper under them).
    """
    rows, cols = shape
    rng = np.random.default_rng(rng)
    r_mm, h = sheet.radius_mm, sheet.half_mm
    cut = r_mm - 0.5 * sheet.rim_mm
    xy_pins = sheet.pin_mm()
    out = np.zeros(shape, np.float64)
    mask = np.zeros((rows * k, cols * k), np.uint8)     # threads over each sample
    xy_pins = xy_pins + offset_mm
    if threads:
        piece = sheet.diameter_mm / 40          # short pieces: polygon() scans each one's bounding box
        for a, b in sheet.chord_mm() + np.asarray(offset_mm):
            length = np.linalg.norm(b - a)
            d = (b - a) / length
            n = np.array([-d[1], d[0]]) * width_mm / 2
            t = np.linspace(0.0, 1.0, int(np.ceil(length / piece)) + 1)[:, None]
            ends = a + t * (b - a)
            quads = tf(np.concatenate([ends[:-1] + n, ends[1:] + n, ends[1:] - n, ends[:-1] - n]))
            quads = quads.reshape(4, -1, 2)
            spots = []
            for q in np.transpose(quads, (1, 0, 2)):
                rr, cc = polygon((q[:, 1] + 0.5) * k - 0.5, (q[:, 0] + 0.5) * k - 0.5, shape=mask.shape)
                spots.append(rr.astype(np.int64) * mask.shape[1] + cc)
            spots = np.unique(np.concatenate(spots))          # each sample once per thread
            mask.ravel()[spots] = np.minimum(mask.ravel()[spots], 254) + 1
    step = max(1, 2_000_000 // (cols * k * k))
    sub = (np.arange(k) + 0.5) / k - 0.5
    for r0 in range(0, rows, step):
        r1 = min(rows, r0 + step)
        yy = (np.arange(r0, r1)[:, None] + sub[None, :]).ravel()
        xx = (np.arange(cols)[:, None] + sub[None, :]).ravel()
        X, Y = np.meshgrid(xx, yy)
        m = np.linalg.inv(tf.params)
        q = m @ np.stack([X.ravel(), Y.ravel(), np.ones(X.size)])
        x, y = q[0] / q[2], q[1] / q[2]
        rad = np.hypot(x, y)
        v = np.full(len(x), table)
        v[np.maximum(abs(x), abs(y)) <= h] = paper
        v[rad <= cut] = board
        if marks:
            for j, (mx, my, mr) in enumerate(sheet.marks):
                dist = np.hypot(x - mx, y - my)
                v[(dist <= mr) & ((dist >= sheet.ring_hole * mr) if j == 0 else True)] = ink
            for _, _, (x0, y0, x1, y1) in sheet.labels:
                inside = (x > x0) & (x < x1) & (y > y0 + 0.3 * (y1 - y0)) & (y < y1 - 0.3 * (y1 - y0))
                v[inside] = 0.5 * (paper + ink)
        near = np.abs(rad - r_mm) < sheet.pin_diameter_mm
        if near.any():
            d2 = ((x[near, None] - xy_pins[None, :, 0]) ** 2 + (y[near, None] - xy_pins[None, :, 1]) ** 2).min(1)
            vn = v[near]
            vn[d2 <= (sheet.pin_diameter_mm / 2) ** 2] = pins
            v[near] = vn
        v = v.reshape(r1 - r0, k, cols, k)
        sub_mask = mask[r0 * k:r1 * k].reshape(r1 - r0, k, cols, k)
        v = thread + (v - thread) * (1.0 - opacity) ** sub_mask
        out[r0:r1] = v.mean(axis=(1, 3))
    yy, xx = np.mgrid[0:rows, 0:cols]
    u, w = (xx - cols / 2) / (cols / 2), (yy - rows / 2) / (rows / 2)
    g, angle = gradient
    t = np.radians(angle)
    lit = light * (1 + g * (u * np.cos(t) + w * np.sin(t)) / 2) * (1 - vignette * (u ** 2 + w ** 2) / 2)
    img = ndimage.gaussian_filter(out * lit, blur) if blur else out * lit
    img = img + rng.normal(0.0, noise, img.shape) * np.sqrt(np.clip(img, 0, 1))
    return np.clip(np.rint(to_srgb(np.clip(img, 0, 1)) * 255), 0, 255).astype(np.uint8)
