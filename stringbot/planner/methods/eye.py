"""The error as the eye sees it from a step away: ``E = || B (s (t - D)) ||^2``, kept up to date.

``B`` is the eye's Gaussian blur (sigma 2 px at 512 px, the as-woven
scorer's: :data:`EYE_SIGMA` of the frame's side), ``t`` the target
darkness, ``D`` the drawing's and ``s`` the square root of the pixel
weights (0 outside the frame), on a grid of ``m`` pixels.  With
``G = B^2 (s (t - D))`` kept up to date, a change ``dD`` of the drawing
(``v = s dD``) changes the error by exactly ``-2 <v, G> + <v, B^2 v>``.

The polish (:class:`~stringbot.planner.methods.woven.WovenCanvas`) is one; the
chooser (:class:`~stringbot.planner.methods.canvas.Canvas`) keeps one on a coarse
grid to know when more threads stop making the piece better
(``--lines auto``).
"""

import math

import numpy as np

from ..model.scoring import WOVEN_SIGMA, WOVEN_SIZE

__all__ = ["EyeError", "EYE_SIGMA"]

#: the eye's blur: sigma as a fraction of the frame's side (the as-woven scorer's, 2 px at 512 px)
EYE_SIGMA = WOVEN_SIGMA / WOVEN_SIZE


class EyeError:
    """``E = || B (s (t - D)) ||^2`` on an ``m x m`` grid, ``D`` starting blank.

    Parameters
    ----------
    target : ndarray of float, shape (m, m)
        Darkness wanted, 0..1.
    weights : ndarray of float, shape (m, m)
        Pixel weights (0 outside the frame).
    sigma : float
        The blur's sigma in pixels of the grid.  ``B`` is cut at two sigmas (the scorer's filter goes
        on to four: ``E`` differs by about 0.1 %); under 1 pixel, three taps of its variance.

    Attributes
    ----------
    E : float
    G : ndarray of float64, shape (P * P,)
        ``B^2 (s (t - D))`` on the grid padded by :attr:`rad` pixels (flat).
    pidx : ndarray of int32, shape (m * m,)
        Each grid pixel's place on the padded grid.
    """

    def __init__(self, target, weights, *, sigma):
        m = target.shape[0]
        self.size = m
        self.t = np.asarray(target, dtype=np.float64).ravel()
        self.s = np.sqrt(np.asarray(weights, dtype=np.float64).ravel())
        self.D = np.zeros(m * m)
        sg = max(float(sigma), 1e-3)
        if sg < 1.0:  # a sampled Gaussian this narrow is narrower than it should be: 3 taps of its variance
            r1, a = 1, min(sg * sg / 2.0, 1.0 / 3.0)
            k1 = np.array([a, 1.0 - 2.0 * a, a])
        else:
            r1 = int(math.ceil(2.0 * sg))
            ax1 = np.arange(-r1, r1 + 1, dtype=np.float64)
            k1 = np.exp(-ax1 ** 2 / (2.0 * sg * sg))
            k1 /= k1.sum()
        ax1 = np.arange(-r1, r1 + 1, dtype=np.float64)
        k2 = np.convolve(k1, k1)
        rad = 2 * r1
        ax = np.arange(-rad, rad + 1, dtype=np.int64)
        P = m + 2 * rad
        self.rad, self.P = rad, P
        self._koff = (ax[:, None] * P + ax[None, :]).ravel()  # B^2 on the padded grid
        self._kw = np.outer(k2, k2).ravel()
        self._koff1 = (ax1.astype(np.int64)[:, None] * P + ax1.astype(np.int64)[None, :]).ravel()  # B
        self._kw1 = np.outer(k1, k1).ravel()
        r, c = np.divmod(np.arange(m * m), m)
        self.pidx = ((r + rad) * P + (c + rad)).astype(np.int32)  # each grid pixel on the padded grid
        # B^2 of a picture on the grid, as the padded grid: T x T^T (T: the 1-D kernel, grid -> padded)
        off = np.arange(m)[None, :] + rad - np.arange(P)[:, None]
        self._T = np.where(np.abs(off) <= rad, k2[np.clip(off + rad, 0, 2 * rad)], 0.0)
        self.G = self._blur2_grid(self.s * self.t)
        self.E = float(np.dot(self.s * self.t, self.G[self.pidx]))

    def _blur2_grid(self, x):
        """``B^2 x`` on the padded grid (flat) of ``x`` on the grid (zero around it)."""
        m = self.size
        return (self._T @ np.asarray(x, dtype=np.float64).reshape(m, m) @ self._T.T).ravel()

    def reset(self, D):
        """The error of the drawing ``D`` (flat, on the grid), from scratch; returns ``E``."""
        self.D = np.asarray(D, dtype=np.float64).ravel().copy()
        x = self.s * (self.t - self.D)
        self.G = self._blur2_grid(x)
        self.E = float(np.dot(x, self.G[self.pidx]))
        return self.E

    def error(self):
        """``E = || B (s (t - D)) ||^2``."""
        return self.E

    def change(self, cp, dD, *, blur2=False, sign=False):
        """``(dE, v, h)``: the exact change of ``E`` for ``dD`` on grid pixels ``cp`` (each once);
        ``h = B^2 v`` if ``blur2`` (else None: ``<v, B^2 v> = |B v|^2`` is cheaper).  ``sign``: when the
        linear term alone does not lower ``E``, that term (the quadratic one is never negative: ``dE``
        is not negative either)."""
        v = self.s[cp] * dD
        pp = self.pidx[cp]
        lin = -2.0 * np.dot(v, self.G[pp])
        if blur2:
            h = self._blur(cp, v, self._koff, self._kw)
            return float(lin + np.dot(v, h[pp])), v, h
        if sign and lin >= 0.0:
            return float(lin), v, None
        b = self._blur(cp, v, self._koff1, self._kw1)
        return float(lin + np.dot(b, b)), v, None

    def take(self, cp, dD):
        """Change the drawing by ``dD`` on grid pixels ``cp`` (each once); returns the exact change of ``E``."""
        dE, _, h = self.change(cp, dD, blur2=True)
        self.G -= h
        self.D[cp] += dD
        self.E += dE
        return dE

    def _blur(self, cp, v, koff, kw):
        idx = (self.pidx[cp][:, None] + koff[None, :]).ravel()
        return np.bincount(idx, weights=(v[:, None] * kw[None, :]).ravel(), minlength=self.P * self.P)
