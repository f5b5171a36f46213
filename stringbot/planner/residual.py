"""The default planner: chords chosen with feedback from the picture as woven.

The picture is a target *darkness* ``t = 1 - gray / 255`` (0 outside the
frame).  The planner keeps the drawing as woven under the thread model
(:mod:`stringbot.planner.thread`): ``S``, the summed coverage of the threads
drawn so far at the working size (a thread ``thread_mm / diameter_mm * size``
pixels wide, anti-aliased, the same in every direction), and its darkness
``D = tanh(S)`` (coverage saturates: two threads on one spot are not twice
as dark; ``tanh`` is what the thread model's fine rendering gives at a coarse
pixel on average, see docs/planner.md).  The error is
``E = sum w (t - D)^2`` (``w``: 1 in the frame, up to 2 on important pixels,
0 outside).

*A chord drawn again* lies on the first thread between the same two pins:
it covers only what the threads already there leave uncovered *at the
thread's own scale*, where two threads on one spot are not twice as dark.
The ``k``-th copy of a chord adds :func:`repeat_gains` ``[k]`` times one
thread's coverage: the thread model's own cap, measured on a canvas whose
pixel is the thread's width (1, 0.8, 0.3, 0.18, ... : a second thread beside
the first still darkens, the tenth hardly at all).  At the working size the
copies fall on the same pixels, so without this the planner would believe a
chord drawn 20 times is 20 times as dark and pile thread there.

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

The sequence then goes to :mod:`stringbot.planner.refine` (a line count) or
:mod:`stringbot.planner.polish` (``lines="auto"``).
"""

import logging

import numpy as np

from .greedy import _PinLines
from .progress import report
from .thread import SegmentStamp

log = logging.getLogger(__name__)

__all__ = ["Canvas", "residual_sequence", "best_start", "repeat_gains", "sum_sparse", "PATIENCE"]

#: Threads in a row that may fail to lower the error before an automatic run ends.
PATIENCE = 40
MAX_AUTO = 60_000
#: copies of one chord whose gain :func:`repeat_gains` measures; later copies gain as the last
REPEATS = 24
_GAINS = None


def repeat_gains():
    """Coverage added by the k-th copy of a chord (k = 0, 1, ...), in units of one thread's coverage.

    Measured with the thread model (:mod:`stringbot.planner.thread`) on a
    canvas whose pixel is as wide as the thread, where the coverage is capped
    at 1: ``sum min((k + 1) c, 1) - sum min(k c, 1)`` over the footprint ``c``
    of one thread, divided by ``sum c``, averaged over a few directions.

    Returns
    -------
    ndarray of float64, shape (REPEATS,)
        ``gains[0] == 1``, non-increasing, > 0.
    """
    global _GAINS
    if _GAINS is None:
        size = 256
        stamp = SegmentStamp(size, 1.0)
        k = np.arange(REPEATS + 1, dtype=np.float64)[:, None]
        curves = []
        for ang in np.linspace(0.0, np.pi / 4, 7):
            d = np.array([np.cos(ang), np.sin(ang)]) * 0.45
            _, c = stamp(0.5 - d, 0.5 + d)
            curves.append(np.minimum(k * c[None, :], 1.0).sum(axis=1) / c.sum())
        total = np.mean(curves, axis=0)
        _GAINS = np.maximum(np.minimum.accumulate(np.diff(total)), 1e-3)
    return _GAINS


def sum_sparse(parts, acc, mark):
    """The sum of sparse vectors: ``(pix, total)``, each index once.

    Parameters
    ----------
    parts : list of (ndarray of int, ndarray of float)
        Indices (each once within a part) and their values.
    acc, mark : ndarray of float64 / int64
        Scratch as long as the dense vector; ``acc`` all zeros, and left so.
    """
    for idx, val in parts:
        acc[idx] += val
    every = np.concatenate([idx for idx, _ in parts])
    order = np.arange(len(every))
    mark[every] = order
    pix = every[mark[every] == order]
    total = acc[pix]
    acc[pix] = 0.0
    return pix, total


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
        self.D = np.zeros_like(self.t)  # tanh(S), kept in step with S
        self.pin_xy = np.asarray(pin_xy, dtype=np.float64)
        self.width = float(width_px)
        self._fp = {}
        self._stamp = SegmentStamp(self.size, self.width)
        n = len(self.pin_xy)
        #: how many times each chord is drawn (symmetric); the next copy adds ``gains[uses]`` of a thread
        self.uses = np.zeros((n, n), dtype=np.int32)
        self.gains = repeat_gains()
        self._acc = np.zeros_like(self.t)  # scratch: summed coverage change of several chords
        self._mark = np.zeros(self.t.size, dtype=np.int64)  # scratch: first occurrence of a pixel
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
        return float(np.sum(self.w * (self.t - self.D) ** 2))

    def gain(self, a, b, copies=0):
        """Share of a thread's coverage the next copy of chord ``(a, b)`` adds (``copies`` more drawn first)."""
        return float(self.gains[min(max(int(self.uses[a, b]) + copies, 0), len(self.gains) - 1)])

    def gain_row(self, a, others):
        """:meth:`gain` of the chords from pin ``a`` to each of ``others`` (an array)."""
        return self.gains[np.minimum(self.uses[a, others], len(self.gains) - 1)]

    def _changes(self, chords_out, chords_in):
        """``[(flat, cover * signed gain), ...]`` of removing then adding chords, copies counted."""
        more, parts = {}, []
        for chords, sign in ((chords_out, -1), (chords_in, 1)):
            for a, b in chords:
                key = (a, b) if a < b else (b, a)
                n = more.get(key, 0)
                if sign < 0:
                    n -= 1
                parts.append((self.footprint(a, b), sign * self.gain(a, b, n)))
                more[key] = more.get(key, 0) + sign
        return parts

    def _union(self, parts):
        """``(pix, dS)``: the pixels several signed footprints touch (each once) and their coverage change."""
        return sum_sparse([(flat, s * cov) for (flat, cov), s in parts], self._acc, self._mark)

    def delta(self, chords_out=(), chords_in=()):
        """Exact change of ``E`` if ``chords_out`` were removed and ``chords_in`` added (nothing changes)."""
        parts = self._changes(chords_out, chords_in)
        if not parts:
            return 0.0
        if len(parts) == 1:  # one thread: each pixel once
            (pix, cov), sign = parts[0]
            dS = sign * cov
        else:
            pix, dS = self._union(parts)
        S1 = np.maximum(self.S[pix] + dS, 0.0)
        t, w = self.t[pix], self.w[pix]
        return float(np.sum(w * ((t - np.tanh(S1)) ** 2 - (t - self.D[pix]) ** 2)))

    def apply(self, chords_out=(), chords_in=()):
        """Remove ``chords_out`` and add ``chords_in``; update the slope on the pixels they touch.

        Returns
        -------
        float
            The exact change of ``E`` (as :meth:`delta` would have said).
        """
        parts = self._changes(chords_out, chords_in)
        if not parts:
            return 0.0
        for chords, sign in ((chords_out, -1), (chords_in, 1)):
            for a, b in chords:
                self.uses[a, b] += sign
                if a != b:
                    self.uses[b, a] += sign
        if len(parts) == 1:
            (pix, cov), sign = parts[0]
            dS = sign * cov
        else:
            pix, dS = self._union(parts)
        S = np.maximum(self.S[pix] + dS, 0.0)
        self.S[pix] = S
        d = np.tanh(S)
        d0 = self.D[pix]
        self.D[pix] = d
        t, w = self.t[pix], self.w[pix]
        slope = 1.0 - d * d  # dD/dS
        # E's change for coverage c: -2 w (t - D) D' c + w D'^2 c^2; per unit of coverage of a thread
        # whose own c^2 / c is 2 kappa: 2 w D' ((t - D) - kappa D')
        r = t - d
        self.g[pix] = w * slope * (r - self.kappa * slope)
        return float(np.sum(w * (r * r - (t - d0) ** 2)))

    def slope(self):
        """The slope field ``w (t - D) dD/dS``, flat float32 (a view: do not modify)."""
        return self.g


def best_start(canvas, space, pin_lines):
    """The pin to start from: an end of the chord of highest score on the canvas (the lower pin on a tie)."""
    g = canvas.slope()
    best, pin = -np.inf, 0
    for a in range(space.pins):
        others, pix, starts, counts = pin_lines.get_with_counts(a)
        if len(others):
            top = float((np.add.reduceat(g.take(pix), starts) / counts).max())
            if top > best:
                best, pin = top, a
    return pin


def residual_sequence(canvas, space, lines, *, start_pin=None, min_loop=3, pin_lines=None, patience=PATIENCE,
                      on_chord=None):
    """Choose a pin sequence by the darkness residual (see the module notes).

    Parameters
    ----------
    canvas : Canvas
        Modified: the chosen chords are drawn on it.
    space : ChordSpace
    lines : int or "auto"
        Chords to draw; ``"auto"``: until ``patience`` chords in a row have not
        brought the error below its lowest, then back to where it was lowest.
    start_pin : int or None
        None: :func:`best_start`.
    min_loop : int
    pin_lines : _PinLines, optional
        Shared per-pin line points (built here when not given).
    patience : int
    on_chord : callable, optional
        ``on_chord((a, b))`` for each chord chosen, as it is (some may be cut
        back at the end).

    Returns
    -------
    list of int
    """
    auto = lines == "auto"
    limit = MAX_AUTO if auto else int(lines)
    pins = pin_lines or _PinLines(space, canvas.size, nearest=True)
    if start_pin is None:
        start_pin = best_start(canvas, space, pins)
    seq = [int(start_pin)]
    cur = int(start_pin)
    g = canvas.slope()
    err = best = canvas.error()
    best_len = 1
    for _ in range(limit):
        others, pix, starts, counts = pins.get_with_counts(cur)
        if not len(others):
            break
        score = np.add.reduceat(g.take(pix), starts) / counts * canvas.gain_row(cur, others)
        for q in seq[-min_loop:]:
            k = int(np.searchsorted(others, q))
            if k < len(others) and others[k] == q:
                score[k] = -np.inf
        k = int(np.argmax(score))
        if not np.isfinite(score[k]):
            break
        nxt = int(others[k])
        err += canvas.apply(chords_in=[(cur, nxt)])
        if on_chord is not None:
            on_chord((cur, nxt))
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
