"""Resizing a square picture as ``skimage.transform.resize(order=1)`` does, with numpy alone.

The default plan resizes twice (the target to the polish's grid, the preview
to its size); scipy.ndimage and skimage.transform take about 0.3-0.4 s to
import, a tenth of the whole command.  Both steps are separable and linear,
so each is a small matrix per axis:

* anti-aliasing (when shrinking): a Gaussian of sigma ``(n_in / n_out - 1) / 2``
  input pixels, cut at 4 sigma, mirrored at the edges (``scipy.ndimage``'s
  ``mirror``, skimage's ``reflect``);
* linear interpolation at ``(i + 0.5) n_in / n_out - 0.5`` (``grid_mode``),
  mirrored at the edges.

``tests/test_resample.py`` checks the result against skimage to 1e-9.

:func:`gaussian_blur` is the same Gaussian at a size kept (``scipy.ndimage.gaussian_filter``'s, reflected at
the edges), and :func:`unsharp` the unsharp mask the planners lay threads against.
"""

import numpy as np

__all__ = ["resize_square", "resize_taps", "gaussian_blur", "unsharp"]


def _mirror(idx, n):
    """Indices reflected into ``0..n-1`` about the edge pixels' centres (``d c b | a b c d | c b a``)."""
    if n == 1:
        return np.zeros_like(idx)
    period = 2 * (n - 1)
    idx = np.abs(idx) % period
    return np.where(idx >= n, period - idx, idx)


def _gaussian(sigma):
    """``(offsets, weights)`` of a sampled Gaussian of ``sigma`` pixels, cut at 4 sigma, summing to 1."""
    r = int(4.0 * sigma + 0.5)
    off = np.arange(-r, r + 1)
    k = np.exp(-0.5 * (off / sigma) ** 2)
    return off, k / k.sum()


def resize_taps(n_in, n_out, *, anti_aliasing):
    """One axis's resize as taps: output ``i`` is ``sum_k weight[i, k] * input[index[i, k]]``.

    Parameters
    ----------
    n_in, n_out : int
        Sizes before and after.
    anti_aliasing : bool
        Blur before shrinking (as skimage does).

    Returns
    -------
    index : ndarray of int64, shape (n_out, k)
    weight : ndarray of float64, shape (n_out, k)
    """
    n_in, n_out = int(n_in), int(n_out)
    scale = n_in / n_out
    x = (np.arange(n_out) + 0.5) * scale - 0.5
    x0 = np.floor(x).astype(np.int64)
    fr = x - x0
    pos = np.stack([x0, x0 + 1], axis=1)  # unmirrored: the blur is mirrored about the same edges
    wts = np.stack([1.0 - fr, fr], axis=1)
    sigma = max(0.0, (scale - 1.0) / 2.0)
    if anti_aliasing and sigma > 0:
        off, k = _gaussian(sigma)
        # the blurred value at a mirrored position is the blur at the position it mirrors
        pos = (_mirror(pos, n_in)[:, :, None] + off[None, None, :]).reshape(n_out, -1)
        wts = (wts[:, :, None] * k[None, None, :]).reshape(n_out, -1)
    return _mirror(pos, n_in), wts


def _along_rows(a, idx, w):
    out = np.zeros((idx.shape[0],) + a.shape[1:], dtype=a.dtype)
    w = w.astype(a.dtype)
    for k in range(idx.shape[1]):
        out += w[:, k, None] * a[idx[:, k]]
    return out


def resize_square(image, size, *, anti_aliasing=True):
    """``skimage.transform.resize(image, (size, size), order=1, anti_aliasing=...)`` of a square 2-D array.

    Parameters
    ----------
    image : ndarray of float, shape (n, n)
        float32 is resized in float32 (faster; skimage's to about 1e-6).
    size : int
    anti_aliasing : bool

    Returns
    -------
    ndarray of float64 (float32 for a float32 image), shape (size, size)
    """
    a = np.asarray(image)
    a = a.astype(np.float32 if a.dtype == np.float32 else np.float64, copy=False)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ValueError(f"image of shape {a.shape}; expected a square")
    idx, w = resize_taps(a.shape[0], size, anti_aliasing=anti_aliasing)
    out = _along_rows(_along_rows(a, idx, w).T, idx, w).T
    return np.clip(out, a.min(initial=np.inf), a.max(initial=-np.inf))


def _reflect(idx, n):
    """Indices reflected into ``0..n-1`` about the picture's edges (``c b a | a b c d | d c b``)."""
    idx = np.mod(idx, 2 * n)
    return np.where(idx >= n, 2 * n - 1 - idx, idx)


def gaussian_blur(image, sigma):
    """A square 2-D array blurred by a Gaussian of ``sigma`` pixels, cut at 4 sigma, reflected at the edges
    (``scipy.ndimage.gaussian_filter(image, sigma)``, its default ``mode="reflect"``), float64."""
    a = np.asarray(image, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ValueError(f"image of shape {a.shape}; expected a square")
    if sigma <= 0:
        return a.copy()
    off, k = _gaussian(float(sigma))
    n = a.shape[0]
    pad = _reflect(np.arange(-off[-1], n + off[-1]), n)  # the picture reflected, off[-1] pixels each side
    # each tap a shifted slice of the padded picture (no gather per tap), summed tap after tap as
    # _along_rows sums them: rows, then columns
    rows = np.zeros((n, n))
    b = a[pad]
    for j, kj in enumerate(k):
        rows += kj * b[j:j + n]
    out = np.zeros((n, n))
    b = rows[:, pad]
    for j, kj in enumerate(k):
        out += kj * b[:, j:j + n]
    return out


def unsharp(y, *, amount, sigma, lo=0.0, hi=1.0):
    """The unsharp mask ``y + amount (y - blur(y))`` of a square picture, clipped to ``[lo, hi]``.

    Parameters
    ----------
    y : ndarray of float, shape (n, n)
    amount : float or ndarray of float, shape (n, n)
        One for the picture or one per pixel; 0: ``y`` as it is (clipped).
    sigma : float
        The blur's sigma in pixels (:func:`gaussian_blur`).
    lo, hi : float

    Returns
    -------
    ndarray of float64, shape (n, n)
    """
    y = np.asarray(y, dtype=np.float64)
    amount = np.asarray(amount, dtype=np.float64)
    if np.all(amount <= 0):
        return np.clip(y, lo, hi)
    return np.clip(y + amount * (y - gaussian_blur(y, sigma)), lo, hi)
