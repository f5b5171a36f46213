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

*Stopping* (``lines="auto"``).  Each chord's exact change of ``E`` is
computed on its own pixels.  A chord that does not lower ``E`` may still
lead the thread to where the next ones do, so the run goes on until
``patience`` chords in a row have not brought ``E`` below its lowest, and the
sequence is cut back to where ``E`` was lowest: another thread would no
longer improve the picture as woven.

The sequence then goes to :mod:`stringbot.planner.refine`.
"""

import logging

import numpy as np

from .greedy import _PinLines
from .progress import report
from .thread import SegmentStamp

log = logging.getLogger(__name__)

__all__ = ["Canvas", "residual_sequence", "PATIENCE"]

#: Threads in a row that may fail to lower the error before an automatic run ends.
PATIENCE = 40
MAX_AUTO = 60_000


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
        self._stamp = SegmentStamp(self.size, self.width)
        # a thread's own overlap: half its sum of squared coverage per unit of coverage (measured on a
        # horizontal and a diagonal thread); the second-order cost of its darkness where none is wanted
        kap = []
        for xy1 in ((0.9, 0.5), (0.9, 0.9)):
            _, c = self._stamp(np.array([0.1, 0.5 if xy1[1] == 0.5 else 0.1]), np.array(xy1))
            kap.append(float(np.sum(c * c) / (2.0 * np.sum(c))))
        self.kappa = float(np.mean(kap))
        # how much one more thread's coverage lowers the error, per unit of coverage (see apply)
        self.g = (self.w * (self.t - self.kappa)).astype(np.float32)

    def footprint(self, a, b):
        """``(flat, cover)`` of the chord between pins ``a`` and ``b`` (cached)."""
        key = (a, b) if a < b else (b, a)
        fp = self._fp.get(key)
        if fp is None:
            fp = self._fp[key] = self._stamp(self.pin_xy[key[0]], self.pin_xy[key[1]])  # each pixel once
            if len(self._fp) > 200_000:
                self._fp.clear()
        return fp

    def error(self):
        """``E = sum w (t - D)^2``."""
        return float(np.sum(self.w * (self.t - np.tanh(self.S)) ** 2))

    def delta(self, chords_out=(), chords_in=()):
        """Exact change of ``E`` if ``chords_out`` were removed and ``chords_in`` added (nothing changes)."""
        parts = [(self.footprint(a, b), -1.0) for a, b in chords_out] + [(self.footprint(a, b), 1.0)
                                                                          for a, b in chords_in]
        if not parts:
            return 0.0
        if len(parts) == 1:  # one thread: each pixel once
            (pix, dS), sign = parts[0]
            dS = sign * dS
        else:
            flat = np.concatenate([fp[0] for fp, _ in parts])
            cov = np.concatenate([fp[1] * s for fp, s in parts])
            pix, inv = np.unique(flat, return_inverse=True)
            dS = np.bincount(inv, weights=cov, minlength=len(pix))
        S0 = self.S[pix]
        S1 = np.maximum(S0 + dS, 0.0)
        t, w = self.t[pix], self.w[pix]
        return float(np.sum(w * ((t - np.tanh(S1)) ** 2 - (t - np.tanh(S0)) ** 2)))

    def apply(self, chords_out=(), chords_in=()):
        """Remove ``chords_out`` and add ``chords_in``; update the slope on the pixels they touch."""
        touched = []
        for chords, sign in ((chords_out, -1.0), (chords_in, 1.0)):
            for a, b in chords:
                flat, cov = self.footprint(a, b)
                self.S[flat] += sign * cov  # each pixel once per thread
                touched.append(flat)
        if touched:
            pix = touched[0] if len(touched) == 1 else np.unique(np.concatenate(touched))
            self.S[pix] = np.maximum(self.S[pix], 0.0)
            d = np.tanh(self.S[pix])
            slope = 1.0 - d * d  # dD/dS
            # E's change for coverage c: -2 w (t - D) D' c + w D'^2 c^2; per unit of coverage of a thread
            # whose own c^2 / c is 2 kappa: 2 w D' ((t - D) - kappa D')
            self.g[pix] = self.w[pix] * slope * ((self.t[pix] - d) - self.kappa * slope)

    def slope(self):
        """The slope field ``w (t - D) dD/dS``, flat float32 (a view: do not modify)."""
        return self.g


def residual_sequence(canvas, space, lines, *, start_pin=0, min_loop=3, pin_lines=None, patience=PATIENCE):
    """Choose a pin sequence by the darkness residual (see the module notes).

    Parameters
    ----------
    canvas : Canvas
        Modified: the chosen chords are drawn on it.
    space : ChordSpace
    lines : int or "auto"
        Chords to draw; ``"auto"``: until ``patience`` chords in a row have not
        brought the error below its lowest, then back to where it was lowest.
    start_pin, min_loop : int
    pin_lines : _PinLines, optional
        Shared per-pin line points (built here when not given).
    patience : int

    Returns
    -------
    list of int
    """
    auto = lines == "auto"
    limit = MAX_AUTO if auto else int(lines)
    pins = pin_lines or _PinLines(space, canvas.size, nearest=True)
    seq = [int(start_pin)]
    cur = int(start_pin)
    g = canvas.slope()
    err = best = canvas.error()
    best_len, chords = 1, []
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
        if auto:
            err += canvas.delta(chords_in=[(cur, nxt)])
        canvas.apply(chords_in=[(cur, nxt)])
        seq.append(nxt)
        cur = nxt
        if len(seq) % 200 == 0:
            report("choosing threads", len(seq) - 1, None if auto else limit)
        if auto:
            if err < best:
                best, best_len = err, len(seq)
            elif len(seq) - best_len >= patience:
                break
    if auto and len(seq) > best_len:
        extra = list(zip(seq[best_len - 1:-1], seq[best_len:]))
        canvas.apply(chords_out=extra)
        log.info("residual: %d more threads did not improve the picture; keeping %d lines",
                 len(seq) - best_len, best_len - 1)
        seq = seq[:best_len]
    return seq
