"""The default planner: chords chosen with feedback from the picture as woven.

The picture is a target *darkness* ``t = 1 - gray / 255`` (0 outside the
frame).  The planner keeps the drawing as woven under the thread model
(:mod:`stringbot.planner.thread`): ``S``, the summed coverage of the threads
drawn so far at the working size (a thread ``thread_mm / diameter_mm * size``
pixels wide, anti-aliased, the same in every direction), and its darkness
``D = 1 - exp(-S)`` (threads crossing at random leave gaps: coverage
saturates, two threads on one spot are not twice as dark).  The error is
``E = sum w (t - D)^2`` (``w``: 1 in the frame, up to 2 on important pixels,
0 outside).

*Choosing* (image-space error diffusion).  From the current pin, each
chord's score is the mean, over points spaced evenly along it (``int(hypot)``
of them, so no direction is favoured), of ``w (t - D) exp(-S)``: how much
darker the picture wants to be there, times how much darker one more thread
would still make it (the error's slope).  The chord of highest score is
drawn, its coverage is added to ``S``, and the error it leaves (or the
darkness it overshoots) is what the next choices see.  The last
``min_loop`` pins are not gone back to.

*Stopping* (``lines="auto"``).  Before a chord is added its exact change of
``E`` is computed on its own pixels; the run stops at the first chord from
the current pin that would not lower ``E``: another thread would no longer
improve the picture as woven.

The sequence then goes to :mod:`stringbot.planner.refine`.
"""

import logging

import numpy as np

from .greedy import _PinLines
from .thread import footprints

log = logging.getLogger(__name__)

__all__ = ["Canvas", "residual_sequence"]


class Canvas:
    """The drawing as woven at the working size, and its error against the target.

    Parameters
    ----------
    target : ndarray of float, shape (size, size)
        Darkness wanted, 0..1.
    weights : ndarray of float, shape (size, size)
        Pixel weights (0 outside the frame).
    pin_xy : ndarray of float, shape (pins, 2)
    width_px : float
        Thread width in pixels at this size.
    """

    def __init__(self, target, weights, pin_xy, width_px):
        self.size = target.shape[0]
        self.t = np.asarray(target, dtype=np.float64).ravel()
        self.w = np.asarray(weights, dtype=np.float64).ravel()
        self.S = np.zeros_like(self.t)
        self.pin_xy = np.asarray(pin_xy, dtype=np.float64)
        self.width = float(width_px)
        self._fp = {}
        # the slope of the error: how much one more thread's coverage lowers it, per unit of coverage
        self.g = (self.w * self.t).astype(np.float32)

    def footprint(self, a, b):
        """``(flat, cover)`` of the chord between pins ``a`` and ``b`` (cached)."""
        key = (a, b) if a < b else (b, a)
        fp = self._fp.get(key)
        if fp is None:
            _, flat, cov = footprints(self.pin_xy[key[0]][None], self.pin_xy[key[1]][None], self.size, self.width)
            fp = self._fp[key] = (flat.astype(np.int64), cov.astype(np.float64))
            if len(self._fp) > 200_000:
                self._fp.clear()
        return fp

    def error(self):
        """``E = sum w (t - D)^2``."""
        return float(np.sum(self.w * (self.t - (1.0 - np.exp(-self.S))) ** 2))

    def delta(self, chords_out=(), chords_in=()):
        """Exact change of ``E`` if ``chords_out`` were removed and ``chords_in`` added (nothing changes)."""
        parts = [(self.footprint(a, b), -1.0) for a, b in chords_out] + [(self.footprint(a, b), 1.0)
                                                                          for a, b in chords_in]
        if not parts:
            return 0.0
        flat = np.concatenate([fp[0] for fp, _ in parts])
        cov = np.concatenate([fp[1] * s for fp, s in parts])
        pix, inv = np.unique(flat, return_inverse=True)
        dS = np.bincount(inv, weights=cov, minlength=len(pix))
        S0 = self.S[pix]
        S1 = np.maximum(S0 + dS, 0.0)
        t, w = self.t[pix], self.w[pix]
        return float(np.sum(w * ((t - 1.0 + np.exp(-S1)) ** 2 - (t - 1.0 + np.exp(-S0)) ** 2)))

    def apply(self, chords_out=(), chords_in=()):
        """Remove ``chords_out`` and add ``chords_in``; update the slope on the pixels they touch."""
        touched = []
        for chords, sign in ((chords_out, -1.0), (chords_in, 1.0)):
            for a, b in chords:
                flat, cov = self.footprint(a, b)
                np.add.at(self.S, flat, sign * cov)
                touched.append(flat)
        if touched:
            pix = np.unique(np.concatenate(touched))
            self.S[pix] = np.maximum(self.S[pix], 0.0)
            e = np.exp(-self.S[pix])
            self.g[pix] = self.w[pix] * (self.t[pix] - 1.0 + e) * e

    def slope(self):
        """The slope field ``w (t - D) exp(-S)``, flat float32 (a view: do not modify)."""
        return self.g


def residual_sequence(canvas, space, lines, *, start_pin=0, min_loop=3, pin_lines=None):
    """Choose a pin sequence by the darkness residual (see the module notes).

    Parameters
    ----------
    canvas : Canvas
        Modified: the chosen chords are drawn on it.
    space : ChordSpace
    lines : int or "auto"
        Chords to draw; ``"auto"`` stops when the next one would not lower the error.
    start_pin, min_loop : int
    pin_lines : _PinLines, optional
        Shared per-pin line points (built here when not given).

    Returns
    -------
    list of int
    """
    auto = lines == "auto"
    limit = 100_000 if auto else int(lines)
    pins = pin_lines or _PinLines(space, canvas.size, nearest=True)
    seq = [int(start_pin)]
    cur = int(start_pin)
    g = canvas.slope()
    for _ in range(limit):
        others, pix, starts, counts = pins.get_with_counts(cur)
        if not len(others):
            break
        score = np.add.reduceat(g.take(pix), starts) / counts
        for q in seq[-min_loop:]:
            k = int(np.searchsorted(others, q))
            if k < len(others) and others[k] == q:
                score[k] = -np.inf
        k = int(np.argmax(score))
        if not np.isfinite(score[k]):
            break
        nxt = int(others[k])
        if auto and canvas.delta(chords_in=[(cur, nxt)]) >= 0.0:
            log.info("residual: the next thread would not improve the picture; stopping after %d lines",
                     len(seq) - 1)
            break
        canvas.apply(chords_in=[(cur, nxt)])
        seq.append(nxt)
        cur = nxt
    return seq
