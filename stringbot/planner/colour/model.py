"""The woven piece in colour, as the planner keeps it: sharp threads, the later one on top.

The physical model is the reference rendering's
(:func:`stringbot.planner.model.reference.reference_shares`): a thread is a band of
its real width with a sharp edge, and it hides what it covers.  The planner
keeps it on a fine canvas of ``f x f`` samples per working pixel (the
thread about one sample wide, :class:`stringbot.planner.model.union.UnionStamp`),
each sample holding the colour on top there (0: the board).  The planner
lays threads in winding order, so a new thread always lies on top: the
samples it covers take its colour, and each working pixel's colour ``u``
(linear RGB, the mean of its samples: reflectances mix linearly) changes by
exactly what those samples changed.

**How a thread is judged before it is laid.**  A thread of colour ``c``
covering a share ``s`` of a pixel falls on its samples as often as they are
there, so it moves the pixel to ``u + s (c - u)`` on average.  The error is
the squared CIELAB difference from the picture, pixel by pixel, lightness
weighed :data:`LIGHTNESS` against 1 for a* and b* (and each pixel by its
weight: 0 outside the frame).  For every colour and pixel the model keeps ``S``, the
exact change of the pixel's error that a typical thread (``s0``, the median
share) of that colour would make, per unit of share; a chord's gain is its
share times the sum of ``S`` over its pixels: one gather and one sum for the
~300 chords from a pin.  (The exact change, not a Taylor expansion: near
black CIELAB's slope is 8 times that at mid gray, and a Gauss-Newton step
misjudged a light thread on a dark board; docs/planner.md, "Colour".)

**The texture.**  The eye, and the plain luminance SSIM, also see how the
samples of a pixel differ: half a pixel of black thread on the board is a
mid gray on average but a stripe.  So each pixel's error also counts
:data:`TEXTURE` times the variance of its samples' luminance (linear light),
kept exactly as threads are laid (the mean luminance and the mean of its
square over the samples) and judged for a typical thread as the colour is:
a mid tone is then rather made of a lighter thread covering more of the
pixel than of a dark one covering less.
"""

import numpy as np

from ..model.union import UnionStamp, fine_per_pixel, unique
from ..picture.resample import unsharp
from .palette import hex_to_rgb, lab, to_linear, to_srgb

__all__ = ["Piece", "chord_weights_px", "linear_colors", "luminance", "sharpened", "LIGHTNESS", "SHARPEN",
           "TEXTURE"]

#: the weight of lightness in the error, against 1 for each of a* and b* (docs/planner.md, "Colour")
LIGHTNESS = 2.0
#: the planner lays threads against the picture sharpened (an unsharp mask of its luminance in linear light:
#: this amount, sigma in working pixels): chelsea's plain luminance SSIM at Prem-Dharshan's line count 0.313 ->
#: 0.329 with 8 spool changes (docs/planner.md, "Colour")
SHARPEN = (2.0, 1.0)
#: the weight of the thread's texture in the error: each pixel's variance of luminance (linear light) over its
#: samples, times this, is added to its CIELAB error (0: the mean colour alone).  On the working grid only (the
#: draft orders the colours without it): the plain luminance SSIM at Prem-Dharshan's line count with 2 spool
#: changes chelsea 0.333 -> 0.340, coffee 0.335 -> 0.340, the colour error lower (docs/planner.md, "Colour")
TEXTURE = 3000.0
#: linear light -> luminance (Rec. 709)
_Y = np.array([0.2126, 0.7152, 0.0722])


def luminance(linear_rgb):
    """The luminance (Rec. 709) of linear RGB, shape (..., 3) -> (...)."""
    return np.asarray(linear_rgb, dtype=np.float64) @ _Y


def sharpened(rgb, *, amount=SHARPEN[0], sigma=SHARPEN[1]):
    """sRGB picture (m, m, 3) in [0, 1], its luminance sharpened: ``y + amount (y - blur(y))`` in linear light.

    Each pixel's linear RGB is scaled by its sharpened luminance over its own
    (clipped to [0, 1]): the lightness steepens at edges, the colour stays.

    The planner's error is per working pixel; the eye (and SSIM) also sees the
    picture's edges finer than a pixel.  Laying threads against a sharpened
    target puts them on the edges (the eye's stripes, rims, whiskers) rather
    than spreading them evenly over the pixels beside them.
    """
    if amount <= 0:
        return np.asarray(rgb, dtype=np.float64)
    lin = to_linear(rgb)
    y = luminance(lin)
    ys = unsharp(y, amount=amount, sigma=sigma)
    return to_srgb(lin * (ys / np.maximum(y, 1e-6))[..., None])


def linear_colors(hex_colors):
    """``"#rrggbb"`` colours -> linear RGB, shape (K, 3)."""
    return np.array([to_linear(hex_to_rgb(c)) for c in hex_colors]).reshape(-1, 3)


def chord_weights_px(space, size, width_px):
    """Share of each pixel of its 1-pixel line a chord covers: ``width_px * sqrt(1 + slope^2)`` (< 1)."""
    from ..model.chords import pin_pixels

    rc = pin_pixels(space.pin_xy, size).astype(np.float64)
    d = np.abs(rc[space.ends[:, 1]] - rc[space.ends[:, 0]])
    major, minor = d.max(axis=1), d.min(axis=1)
    w = width_px * np.sqrt(1.0 + (minor / np.maximum(major, 1.0)) ** 2)
    return np.minimum(w, 0.999).astype(np.float32)


class Piece:
    """The piece under construction on an ``m x m`` working grid (see the module notes).

    Parameters
    ----------
    target : ndarray of float, shape (m * m, 3)
        The picture, linear RGB, flat pixels.
    weight : ndarray of float, shape (m * m,)
        Pixel weights (0 outside the frame).
    board : array_like of float, shape (3,)
        The board, linear RGB.
    colors : ndarray of float, shape (K, 3)
        The thread colours, linear RGB.
    pin_xy : ndarray of float, shape (pins, 2)
    width_px : float
        The thread's width in working pixels.
    nominal : float
        A typical thread's share of a pixel: the change of the error is exact for it.
    lightness : float
        The weight of lightness in the error (:data:`LIGHTNESS`).
    samples : float
        Samples of the fine canvas across a thread, about (1; the draft: fewer).
    texture : float, optional
        The weight of each pixel's variance of luminance over its samples in the error (default
        :data:`TEXTURE`; 0: none).
    """

    def __init__(self, target, weight, board, colors, pin_xy, width_px, *, nominal=0.2, lightness=LIGHTNESS,
                 samples=1.0, texture=None):
        texture = TEXTURE if texture is None else float(texture)
        self._args = (target, weight, board, colors, pin_xy, width_px)
        self._kw = dict(nominal=nominal, lightness=lightness, samples=samples, texture=texture)
        self.texture = texture
        self.m = int(round(np.sqrt(len(target))))
        self.n = self.m * self.m
        self.target_lab = lab(np.asarray(target, dtype=np.float64))
        self.weight = np.asarray(weight, dtype=np.float64)
        self.board = np.asarray(board, dtype=np.float64)
        self.colors = np.asarray(colors, dtype=np.float64)
        self.K = len(self.colors)
        self.metric = np.array([float(lightness), 1.0, 1.0])
        self.nominal = float(nominal)
        self.pin_xy = np.asarray(pin_xy, dtype=np.float64)
        f = fine_per_pixel(width_px, samples=samples)
        self.stamp = UnionStamp(self.m, f, width_px)
        self.top = np.zeros(self.stamp.F * self.stamp.F, dtype=np.uint8)  # 0 board, k + 1 colour k
        self.palette = np.vstack([self.board[None], self.colors])         # by sample value
        self.per_sample = 1.0 / (f * f)
        self.u = np.empty((self.n, 3))
        self.u[:] = self.board
        # each pixel's mean luminance and mean squared luminance over its samples (the texture's variance)
        self.lum = luminance(self.palette)
        self.y1 = np.full(self.n, self.lum[0])
        self.y2 = np.full(self.n, self.lum[0] ** 2)
        self._mark = np.zeros(self.n, dtype=np.int64)
        # per colour and pixel, the error's change per unit of thread share (weighted)
        self.S = np.zeros((self.K, self.n), dtype=np.float32)
        for lo in range(0, self.n, 65536):
            self.refresh(np.arange(lo, min(lo + 65536, self.n)))

    def fresh(self):
        """The same piece over the bare board."""
        return Piece(*self._args, **self._kw)

    def refresh(self, p):
        """Recompute ``S`` at pixels ``p``: the exact change of the error for a typical thread of each colour."""
        u = self.u[p]
        pts = np.empty((self.K + 1, len(p), 3))
        pts[0] = u
        pts[1:] = u + self.nominal * (self.colors[:, None, :] - u)
        d = lab(pts.reshape(-1, 3)).reshape(self.K + 1, len(p), 3) - self.target_lab[p]
        e = (d * d) @ self.metric
        if self.texture:
            y1, y2 = self.y1[p], self.y2[p]
            k1 = y1 + self.nominal * (self.lum[1:, None] - y1)
            k2 = y2 + self.nominal * (self.lum[1:, None] ** 2 - y2)
            e[0] += self.texture * (y2 - y1 * y1)
            e[1:] += self.texture * (k2 - k1 * k1)
        self.S[:, p] = (e[1:] - e[0]) * (self.weight[p] / self.nominal)

    def lay(self, k, a, b):
        """Lay a thread of colour ``k`` from pin ``a`` to pin ``b`` on top; returns the pixels it changed."""
        samples = self.stamp(self.pin_xy[a], self.pin_xy[b])
        old = self.top[samples]
        moved = old != k + 1
        samples, old = samples[moved], old[moved]
        if not len(samples):
            return np.zeros(0, np.int64)
        self.top[samples] = k + 1
        cells, inv = unique(self.stamp.cells(samples), self._mark)
        kinds = len(self.palette)
        lost = np.bincount(inv * kinds + old, minlength=len(cells) * kinds).reshape(len(cells), kinds)
        moved = lost * self.per_sample
        self.u[cells] += moved @ (self.colors[k] - self.palette)   # what each sample changed
        self.y1[cells] += moved @ (self.lum[k + 1] - self.lum)
        self.y2[cells] += moved @ (self.lum[k + 1] ** 2 - self.lum ** 2)
        self.refresh(cells)
        return cells

    def error(self):
        """Sum over pixels of the weighted squared CIELAB difference (and texture, :data:`TEXTURE`)."""
        d = lab(self.u) - self.target_lab
        e = (d * d) @ self.metric + self.texture * (self.y2 - self.y1 * self.y1)
        return float((self.weight * e).sum())
