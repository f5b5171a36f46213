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

**The fine luminance.**  The score's plain SSIM compares the luminance at
twice the working grid's resolution, unblurred, where a thread's place
within a pixel shows.  So the error may also count, on a grid twice as fine
(2 x 2 cells a pixel, each a quarter of its samples), the squared difference
of each cell's gray (the sRGB value of its luminance) from the picture's
there (:class:`Fine`); a chord is then judged by the cells it crosses on that
grid, which tell on which side of a pixel it runs.  Its colour error is
judged there too, each cell carrying a quarter of its pixel's ``S`` (a chord
crosses twice as many cells, each with twice the share): one gather and one
sum as before, on the finer grid.
"""

import numpy as np

from ..model.union import UnionStamp, fine_per_pixel, unique
from ..picture.read import LUMINANCE
from ..picture.resample import unsharp
from .palette import hex_to_rgb, lab, to_linear, to_srgb

__all__ = ["Piece", "Fine", "chord_weights_px", "linear_colors", "luminance", "sharpened", "LIGHTNESS", "SHARPEN",
           "TEXTURE", "FINE"]

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
#: the weight of the fine luminance (:class:`Fine`): each cell's squared difference of gray (0..1) times this.
#: The plain luminance SSIM at Prem-Dharshan's line counts with 2 / 8 / 32 spool changes: chelsea 0.340 / 0.334 /
#: 0.330 -> 0.345 / 0.347 / 0.344, coffee 0.340 / 0.366 / 0.365 -> 0.363 / 0.382 / 0.381 (docs/planner.md, "Colour")
FINE = 8000.0
#: linear light -> luminance (Rec. 709)
_Y = np.array([0.2126, 0.7152, 0.0722])


def luminance(linear_rgb):
    """The luminance (Rec. 709) of linear RGB, shape (..., 3) -> (...)."""
    return np.asarray(linear_rgb, dtype=np.float64) @ _Y


def sharpened(rgb, *, amount=SHARPEN[0], sigma=SHARPEN[1]):
    """sRGB picture (m, m, 3) in [0, 1], its luminance sharpened: ``y + amount (y - blur(y))`` in linear light
    (``amount`` a float, or one per pixel, shape (m, m): ``--face`` sharpens the face more).

    Each pixel's linear RGB is scaled by its sharpened luminance over its own
    (clipped to [0, 1]): the lightness steepens at edges, the colour stays.

    The planner's error is per working pixel; the eye (and SSIM) also sees the
    picture's edges finer than a pixel.  Laying threads against a sharpened
    target puts them on the edges (the eye's stripes, rims, whiskers) rather
    than spreading them evenly over the pixels beside them.
    """
    amount = np.asarray(amount, dtype=np.float64)
    if np.all(amount <= 0):
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


class Fine:
    """The picture's luminance on a grid twice as fine as the working grid: what :class:`Piece` matches there.

    Parameters
    ----------
    gray : ndarray of float, shape (2m * 2m,)
        The picture's gray there, flat cells: the sRGB value of its luminance (linear light), 0..1.
    weight : ndarray of float, shape (2m * 2m,)
        Each cell's weight (0 outside the frame), times the term's (:data:`FINE`).
    nominal : float
        A typical thread's share of a cell.
    """

    def __init__(self, gray, weight, nominal):
        self.gray = np.asarray(gray, dtype=np.float64).ravel()
        self.weight = np.asarray(weight, dtype=np.float64).ravel()
        self.nominal = float(nominal)


#: sRGB values of linear light 0, 1/N, ..., 1: the fine luminance's gray by table (8 times faster; within 1e-4)
_GRAY_N = 65535
_GRAY = to_srgb(np.linspace(0.0, 1.0, _GRAY_N + 1))
_GRAY_WEIGHTS = np.asarray(LUMINANCE, dtype=np.float64)


def _gray(rgb):
    """The score's gray of linear RGB (..., 3) in [0, 1]: its sRGB values (by :data:`_GRAY`) weighed by
    :data:`~stringbot.planner.picture.read.LUMINANCE`, as ``skimage.color.rgb2gray``."""
    return _GRAY.take((np.clip(rgb, 0.0, 1.0) * _GRAY_N + 0.5).astype(np.intp)) @ _GRAY_WEIGHTS


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
    fine : Fine, optional
        Also match the picture's luminance on a grid twice as fine (see the module notes); the chords are
        then judged there (``S2``, the gains on that grid).
    """

    def __init__(self, target, weight, board, colors, pin_xy, width_px, *, nominal=0.2, lightness=LIGHTNESS,
                 samples=1.0, texture=None, fine=None):
        texture = TEXTURE if texture is None else float(texture)
        self._args = (target, weight, board, colors, pin_xy, width_px)
        self._kw = dict(nominal=nominal, lightness=lightness, samples=samples, texture=texture, fine=fine)
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
        f += f % 2 if fine is not None else 0          # the fine grid's cells: f / 2 samples a side
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
        self.fine = fine
        if fine is not None:
            self.m2, self.h = 2 * self.m, f // 2
            self.u_fine = np.empty((self.m2 * self.m2, 3))              # each cell's colour (linear RGB)
            self.u_fine[:] = self.board
            self._mark2 = np.zeros(self.m2 * self.m2, dtype=np.int64)
            self.S2 = np.zeros((self.K, self.m2 * self.m2), dtype=np.float32)
            self.F2 = np.zeros_like(self.S2)                              # its fine part
            r, c = np.divmod(np.arange(self.n), self.m)
            self._kids = ((2 * r[:, None] + np.array([0, 0, 1, 1])) * self.m2    # each pixel's 4 cells
                          + 2 * c[:, None] + np.array([0, 1, 0, 1]))
            self._refresh_fine(np.arange(self.m2 * self.m2))
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
        if self.fine is not None:       # the cells of pixels p: their fine part plus a quarter of the pixel's S
            q = self._kids[p].ravel()
            self.S2[:, q] = self.F2[:, q] + np.repeat(self.S[:, p], 4, axis=1) * 0.25

    def _refresh_fine(self, q):
        """``F2`` at cells ``q``: the fine luminance's change for a typical thread of each colour, per unit of
        share (a chord crosses twice as many cells as pixels, each with twice the share: the cells' ``S2``
        adds a quarter of their pixel's ``S``, :meth:`refresh`)."""
        fine, u = self.fine, self.u_fine[q]
        pts = np.empty((self.K + 1, len(q), 3))
        pts[0] = u
        pts[1:] = u + fine.nominal * (self.colors[:, None, :] - u)
        d = _gray(pts) - fine.gray[q]
        e = d * d
        self.F2[:, q] = (e[1:] - e[0]) * (fine.weight[q] / fine.nominal)

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
        if self.fine is not None:
            F, h = self.stamp.F, self.h
            q, inv = unique((samples // (F * h)) * self.m2 + (samples % F) // h, self._mark2)
            lost = np.bincount(inv * kinds + old, minlength=len(q) * kinds).reshape(len(q), kinds)
            self.u_fine[q] += (lost * (1.0 / (h * h))) @ (self.colors[k] - self.palette)
            self._refresh_fine(q)
        self.refresh(cells)
        return cells

    def error(self):
        """Sum over pixels of the weighted squared CIELAB difference (and texture, :data:`TEXTURE`; and over
        the fine cells, :class:`Fine`)."""
        d = lab(self.u) - self.target_lab
        e = (d * d) @ self.metric + self.texture * (self.y2 - self.y1 * self.y1)
        out = float((self.weight * e).sum())
        if self.fine is not None:
            out += float((self.fine.weight * (_gray(self.u_fine) - self.fine.gray) ** 2).sum())
        return out
