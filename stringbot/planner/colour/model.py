"""Colour thread paintings: a joint greedy over (thread colour, chord) against the woven piece.

Threads occlude rather than add.  The piece is modelled in linear light
(:func:`stringbot.planner.colour.palette.to_linear`): each layer ``k`` (one thread
colour ``c_k``, one continuous thread) covers a share ``a_k`` of each pixel,
and the layers lie in winding order, later ones on top, the board ``B``
showing through::

    U_0 = B,   U_k = U_{k-1} (1 - a_k) + c_k a_k,   piece = U_K.

A layer's threads cover a pixel as opaque threads lying across it at
unrelated places: each leaves ``1 - w`` of what was left uncovered, ``w`` its
width times its length in the pixel (the thread model's footprint summed
across the thread, :func:`chord_weights_px`); the render and the score combine
the thread model's footprints the same way
(:func:`stringbot.planner.colour_render.union_coverage`).

The error is the squared CIELAB difference between piece and picture, pixel
by pixel (CIE76; the CIEDE2000 weights were measured and lose, see
docs/planner.md, "Colour").  The piece is affine in each ``a_k`` on its own:
raising ``a_k`` by ``d`` moves the pixel by exactly ``d D_k``, ``D_k = T_k (c_k
- U_{k-1})`` with ``T_k`` the light the layers above let through.  For every
pixel and layer the model keeps the exact change of the pixel's error that a
typical thread would make (``d0 = (1 - a_k) nominal``), per unit of thread
share, and takes a chord's change as its share times the sum over its pixels:
one gather and one sum for the ~300 chords from a pin.  (A Gauss-Newton
expansion, the error's slope and curvature at the piece, fails where CIELAB
bends hard: near black its slope is 8 times that at mid gray, so a light
thread on a dark board looked too bright to lay.)

The joint greedy: every layer is its own thread, at its own current pin (a
layer starts at an end of the chord that lowers the error most, or where it
is told).  At each *decision* the best chord from every layer's current pin
is found and the (layer, chord) that lowers the error most is laid; that
layer then goes on for up to ``run - 1`` more chords (each its best from
where it stands) as long as they lower the error.  It stops when the line
budget is spent or no chord of any layer lowers the error.  The layers are
then wound in their order, each one continuous thread: one spool change
between two layers.
"""

import logging

import numpy as np

from .palette import apply_jacobian, hex_to_rgb, lab, lab_jacobian, to_linear
from ..progress import report

log = logging.getLogger(__name__)

__all__ = ["linear_colors", "first_pin", "unmix", "composite_jacobian", "ColourModel", "joint_greedy", "chord_weights_px"]

def chord_weights_px(space, size, width_px):
    """Share of each pixel of its 1-pixel line a chord covers: ``width_px * sqrt(1 + slope^2)`` (< 1)."""
    from ..chords import pin_pixels

    rc = pin_pixels(space.pin_xy, size).astype(np.float64)
    d = np.abs(rc[space.ends[:, 1]] - rc[space.ends[:, 0]])
    major, minor = d.max(axis=1), d.min(axis=1)
    w = width_px * np.sqrt(1.0 + (minor / np.maximum(major, 1.0)) ** 2)
    return np.minimum(w, 0.999).astype(np.float32)


class ColourModel:
    """The woven piece under construction: per-layer coverage and the error terms of every pixel.

    Coverage of a layer on a pixel: its threads cross the pixel at random
    places, so the share they leave uncovered is the product of what each
    leaves, ``1 - a = prod (1 - w_i)``; a thread of share ``w`` raises ``a`` by
    ``(1 - a) w``.  (On a canvas where a thread is a pixel wide or more, the
    thread model's capped sum is this union; at the working size a thread is a
    fifth of a pixel.)

    Parameters
    ----------
    target : ndarray of float, shape (n, 3)
        The picture, linear RGB, flat pixels.
    weight : ndarray of float, shape (n,)
        Pixel weights (0 outside the frame).
    board : sequence of float
        The board, linear RGB.
    colors : ndarray of float, shape (K, 3)
        The layers' thread colours, linear RGB, in winding order (later on top).
    nominal : float
        A typical thread's share of a pixel (the median chord's): the change of
        the error is computed exactly for it (see :meth:`refresh`).
    """

    def __init__(self, target, weight, board, colors, *, nominal=0.2):
        self.target = np.asarray(target, dtype=np.float64)
        self.target_lab = lab(self.target)
        self.n = len(self.target)
        self.weight = np.asarray(weight, dtype=np.float64)
        self.board = np.asarray(board, dtype=np.float64)
        self.colors = np.asarray(colors, dtype=np.float64)
        self.K = len(self.colors)
        self.nominal = float(nominal)
        self.A = np.zeros((self.K, self.n), dtype=np.float32)   # coverage per layer, in [0, 1)
        # per layer and pixel, the error's change per unit of thread share (weighted): a thread of
        # share w changes a pixel's error by w S, so judging a chord is one gather and one sum
        self.S = np.zeros((self.K, self.n), dtype=np.float32)
        for lo in range(0, self.n, 65536):
            self.refresh(np.arange(lo, min(lo + 65536, self.n)))

    def piece(self, pixels=None):
        """The woven colour (linear RGB) of ``pixels`` (all when None), shape (m, 3)."""
        p = np.arange(self.n) if pixels is None else pixels
        a = self.A[:, p].astype(np.float64)
        u = np.empty((len(p), 3))
        u[:] = self.board
        for k in range(self.K):
            u += a[k][:, None] * (self.colors[k] - u)
        return u

    def refresh(self, p):
        """Recompute the error terms of pixels ``p``.

        A thread raising layer ``k``'s coverage by ``d`` moves the pixel along
        ``D_k`` (exactly: the piece is affine in each layer's coverage), so its
        error changes by exactly ``E(d) - E(0)``; that is computed for a typical
        thread (``d0 = (1 - a) nominal``) and taken in proportion for a thread
        of another width (at the working size widths differ by at most 41 %).
        """
        K, m = self.K, len(p)
        a = self.A[:, p].astype(np.float64)
        u = np.empty((m, 3))
        u[:] = self.board
        under = np.empty((K, m, 3))
        for k in range(K):
            under[k] = u
            u += a[k][:, None] * (self.colors[k] - u)
        left = 1.0 - a
        t = np.ones((K, m))                                    # light the layers above let through
        for k in range(K - 2, -1, -1):
            t[k] = t[k + 1] * left[k + 1]
        pts = np.empty((K + 1, m, 3))
        pts[0] = u
        pts[1:] = u + (t * left * self.nominal)[..., None] * (self.colors[:, None, :] - under)
        d = lab(pts.reshape(-1, 3)).reshape(K + 1, m, 3) - self.target_lab[p]
        e = (d * d).sum(axis=-1)
        self.S[:, p] = (e[1:] - e[0]) * (self.weight[p] / self.nominal)

    def error(self):
        """Sum over pixels of the weighted squared CIELAB difference."""
        d = lab(self.piece()) - self.target_lab
        return float((self.weight * (d * d).sum(axis=1)).sum())


def composite_jacobian(alpha, board, colors):
    """The piece (linear RGB) for coverages ``alpha`` (K, m) and its derivative by each layer's coverage.

    Returns
    -------
    piece : ndarray, shape (m, 3)
    d : ndarray, shape (K, m, 3)
        ``d[k]``: the change of the piece per unit of ``alpha[k]`` (``T_k (c_k - U_{k-1})``).
    """
    K, m = alpha.shape
    u = np.empty((m, 3))
    u[:] = board
    under = np.empty((K, m, 3))
    for k in range(K):
        under[k] = u
        u = u + alpha[k][:, None] * (colors[k] - u)
    left = 1.0 - alpha
    t = np.ones((K, m))
    for k in range(K - 2, -1, -1):
        t[k] = t[k + 1] * left[k + 1]
    return u, t[..., None] * (colors[:, None, :] - under)


def unmix(target, board, colors, *, iterations=15, top=0.97, chunk=65536):
    """The coverages of the layers that make each pixel nearest the picture, and the error's curvature there.

    Per pixel, ``alpha* = argmin |Lab(piece(alpha)) - Lab(target)|^2`` over ``alpha`` in
    ``[0, top]^K``, by projected Gauss-Newton from ``alpha = 0`` (the per-channel baseline of
    ``benchmarks/bench_colour.py`` plans each layer against its ``alpha*``).

    Returns
    -------
    alpha : ndarray of float32, shape (K, n)
    hess : ndarray of float32, shape (n, K, K)
        ``J^T J`` at ``alpha*`` (``J`` the Lab change per unit of each layer's coverage).
    residual : ndarray of float32, shape (n,)
        The squared difference left at ``alpha*`` (what no coverage can make).
    """
    target = np.asarray(target, dtype=np.float64)
    n, K = len(target), len(colors)
    out_a = np.zeros((K, n), np.float32)
    out_h = np.zeros((n, K, K), np.float32)
    out_r = np.zeros(n, np.float32)
    eye = np.eye(K) * 1e-6
    for lo in range(0, n, chunk):
        hi = min(lo + chunk, n)
        tl = lab(target[lo:hi])
        a = np.zeros((K, hi - lo))
        for _ in range(iterations):
            u, d = composite_jacobian(a, board, colors)
            now, fp = lab_jacobian(u)
            r = now - tl                                             # (m, 3)
            j = apply_jacobian(fp, d)                                # (K, m, 3)
            jtj = np.einsum("kmi,lmi->mkl", j, j) + eye
            jtr = np.einsum("kmi,mi->mk", j, r)
            step = np.linalg.solve(jtj, -jtr[..., None])[..., 0]      # (m, K)
            a = np.clip(a + step.T, 0.0, top)
        u, d = composite_jacobian(a, board, colors)
        now, fp = lab_jacobian(u)
        r = now - tl
        j = apply_jacobian(fp, d)
        out_a[:, lo:hi] = a
        out_h[lo:hi] = np.einsum("kmi,lmi->mkl", j, j)
        out_r[lo:hi] = (r * r).sum(axis=1)
    return out_a, out_h, out_r


class _PinFans:
    """The chords from each pin with (every ``sample``-th of) their pixels and coverage, built lazily."""

    def __init__(self, space, indptr, indices, weights, sample=1):
        self.space, self.indptr, self.indices, self.weights = space, indptr, indices, weights
        self.sample = int(sample)
        self.cache = {}

    def get(self, p):
        fan = self.cache.get(p)
        if fan is None:
            row = self.space.index[p]
            others = np.flatnonzero(row >= 0)
            chords = row[others]
            lo = self.indptr[chords]
            counts = (self.indptr[chords + 1] - lo + self.sample - 1) // self.sample
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            pos = (np.arange(counts.sum()) - np.repeat(starts, counts)) * self.sample + np.repeat(lo, counts)
            pix = self.indices[pos].astype(np.int64)
            w = self.weights[chords].astype(np.float64)
            fan = self.cache[p] = (others, chords, pix, starts, w)
        return fan


def joint_greedy(space, indptr, indices, model, weights, lines, *, run=25, start_pins=None, min_loop=3, sample=1):
    """Lay up to ``lines`` threads over the layers of ``model`` (see the module notes).

    Parameters
    ----------
    space : ChordSpace
    indptr, indices : ndarray
        Chord pixels (:func:`stringbot.planner.chords.chord_pixels`).
    model : ColourModel
        Updated in place.
    weights : ndarray of float, shape (m,)
        Coverage per pixel of each chord (:func:`chord_weights_px`).
    lines : int
        Line budget over all layers.
    run : int
        Chords a layer lays in a row once chosen (at most; fewer when they stop lowering the error).
    start_pins : sequence of int or None, optional
        First pin of each layer (None, the default: one end of the chord that
        lowers the error most at the start, :func:`first_pin`).
    min_loop : int
        A layer never goes back to its last ``min_loop`` pins.
    sample : int
        Judge a chord by every ``sample``-th of its pixels (it is laid on all of them).

    Returns
    -------
    list of list of int
        The pin sequence of each layer (a layer that laid nothing has one pin).
    """
    K = model.K
    fans = _PinFans(space, indptr, indices, weights, sample)
    starts = list(start_pins) if start_pins is not None else [None] * K
    seqs = [[int(p) if p is not None else first_pin(space, indptr, indices, model, weights, k)]
            for k, p in enumerate(starts)]

    def best(k):
        others, chords, pix, starts, w = fans.get(seqs[k][-1])
        gain = w * np.add.reduceat(model.S[k].take(pix), starts)
        for q in seqs[k][-min_loop:]:
            i = int(np.searchsorted(others, q))
            if i < len(others) and others[i] == q:
                gain[i] = np.inf
        i = int(np.argmin(gain))
        return float(gain[i]), int(others[i]), int(chords[i])

    def lay(k, nxt, chord):
        p = indices[indptr[chord]:indptr[chord + 1]].astype(np.int64)
        model.A[k, p] += (1.0 - model.A[k, p]) * weights[chord]
        model.refresh(p)
        seqs[k].append(nxt)

    total = 0
    while total < lines:
        if total % 200 < 1:
            report("colour", total, lines)
        (gain, nxt, chord), k = min((best(k), k) for k in range(K))
        if gain >= 0:
            # a layer that has laid nothing yet may start elsewhere: where its best chord is now
            idle = [j for j in range(K) if len(seqs[j]) == 1 and starts[j] is None]
            for j in idle:
                seqs[j][0] = first_pin(space, indptr, indices, model, weights, j)
                starts[j] = seqs[j][0]          # once
            if idle:
                (gain, nxt, chord), k = min((best(j), j) for j in range(K))
        if gain >= 0:
            break
        lay(k, nxt, chord)
        total += 1
        for _ in range(run - 1):
            if total >= lines:
                break
            gain, nxt, chord = best(k)
            if gain >= 0:
                break
            lay(k, nxt, chord)
            total += 1
            if total % 200 == 0:
                report("colour", total, lines)
    return seqs


def first_pin(space, indptr, indices, model, weights, k, *, chunk=4000):
    """Where layer ``k`` should start: an end of the chord, of all, that lowers the error most now."""
    best, where = np.inf, 0
    for a in range(0, space.m, chunk):
        b = min(a + chunk, space.m)
        lo, hi = int(indptr[a]), int(indptr[b])
        gain = weights[a:b] * np.add.reduceat(model.S[k].take(indices[lo:hi]), indptr[a:b] - lo)
        i = int(np.argmin(gain))
        if gain[i] < best:
            best, where = float(gain[i]), a + i
    return int(space.ends[where, 0])


def linear_colors(hex_colors):
    """``"#rrggbb"`` colours -> linear RGB, shape (K, 3)."""
    return np.array([to_linear(hex_to_rgb(c)) for c in hex_colors])
