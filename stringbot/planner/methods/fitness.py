"""The fitness of every chord (section 3.2): a regularised least-squares solve.

Minimise ``E(f) = ||W (A f - b)||^2 + ||V f||^2`` where

* ``A`` (pixels x chords) has ``A[p, c] = 1`` when chord ``c`` covers pixel ``p``;
* ``b = (1 - alpha) I + alpha |g|``, ``I`` the reversed (inverted) gray image
  in [0, 255] and ``|g|`` its gradient magnitude;
* ``W = diag(w)``: 1 inside the frame (2 on important pixels), 0 outside;
* ``V = diag(v)``, ``v_c = beta exp(-s_c / P) + gamma d_c / max(d)``, ``s_c``
  the chord's span in pins and ``d_c`` the mean over its pixels of the cross
  product of the chord's unit direction ``e_c`` with the edge at the pixel.

The edge term follows the paper's words: "the cross product gives larger
result if the chord is not aligned with the edges.  Such chords are
suppressed".  For that, the vector crossed with ``e_c`` must lie *along* the
edge: the edge tangent ``t_p`` (the gradient ``g_p`` turned by 90 degrees,
same length), so ``|t_p x e_c| = |g_p . e_c|``: zero for a chord running
along an edge, ``|g_p|`` for one crossing it.  (Crossed with the gradient
itself, the formula would suppress the chords that follow edges, the
opposite of what the paper says the term is for.)

The solve is :func:`scipy.sparse.linalg.lsqr` on the stacked system
``[W A; V] f = [W b; 0]`` as a LinearOperator with the columns scaled to unit
norm (a Jacobi preconditioner), its sparse products in float32.  The scaling
changes the iterates, not the minimiser: ``f`` comes back in the units of
``b`` (levels of the reversed picture per chord).
"""

import logging

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["frame_mask", "gradients", "edge_consistency", "chord_weights", "solve_fitness"]


def frame_mask(size, frame):
    """Pixels inside the frame.

    Returns
    -------
    ndarray of bool, shape (size, size)
    """
    if frame == "square":
        return np.ones((size, size), dtype=bool)
    c = (size - 1) / 2.0
    yy, xx = np.ogrid[:size, :size]
    return (yy - c) ** 2 + (xx - c) ** 2 <= (c + 0.5) ** 2


def gradients(image):
    """Central-difference gradient of an image.

    Returns
    -------
    gy, gx : ndarray of float32, shape image.shape
        Derivatives along rows (down) and columns (right), in levels per pixel.
    """
    gy, gx = np.gradient(np.asarray(image, dtype=np.float32))
    return gy.astype(np.float32), gx.astype(np.float32)


def edge_consistency(space, rowptr, chords, gy, gx):
    """``d_c``: mean ``|t_p x e_c| = |g_p . e_c|`` over the pixels of each chord.

    ``t_p`` is the edge tangent (the gradient turned by 90 degrees); chords
    crossing edges get large ``d``, chords along edges small (see the module notes).

    Parameters
    ----------
    space : ChordSpace
    rowptr, chords : ndarray
        Pixel-major incidence (:func:`stringbot.planner.model.chords.pixel_chords`).
    gy, gx : ndarray of float, shape (size, size)

    Returns
    -------
    ndarray of float64, shape (m,)
    """
    xy = space.pin_xy[space.ends]  # (m, 2, 2): chord, end, (x, y)
    e = xy[:, 1] - xy[:, 0]
    e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12)
    ex, ey = e[:, 0].astype(np.float32), e[:, 1].astype(np.float32)
    gxf, gyf = np.asarray(gx, np.float32).ravel(), np.asarray(gy, np.float32).ravel()
    per_pixel = np.diff(rowptr)
    sums = np.zeros(space.m)
    counts = np.zeros(space.m)
    n = len(per_pixel)
    step = max(1, int(n * 4_000_000 // max(1, rowptr[-1])))  # ~4M entries per chunk
    for a in range(0, n, step):
        b = min(a + step, n)
        cid = chords[rowptr[a]:rowptr[b]]
        k = per_pixel[a:b]
        val = np.repeat(gxf[a:b], k) * ex[cid]
        val += np.repeat(gyf[a:b], k) * ey[cid]
        np.abs(val, out=val)
        sums += np.bincount(cid, weights=val, minlength=space.m)
        counts += np.bincount(cid, minlength=space.m)
    return sums / np.maximum(counts, 1)


def chord_weights(space, d, *, beta, gamma):
    """``v_c = beta exp(-s_c / P) + gamma d_c / max(d)``.

    Returns
    -------
    ndarray of float64, shape (m,)
    """
    dmax = float(d.max()) if len(d) else 0.0
    edge = d / dmax if dmax > 0 else np.zeros_like(d)
    return beta * np.exp(-space.span / space.pins) + gamma * edge


def solve_fitness(rowptr, chords, b, w, v, *, iterations=25, tol=1e-4):
    """Least-squares fitness ``argmin ||W (A f - b)||^2 + ||V f||^2`` by LSQR.

    Parameters
    ----------
    rowptr, chords : ndarray
        Pixel-major incidence: ``A`` has a 1 at ``(p, c)`` for ``c`` in
        ``chords[rowptr[p]:rowptr[p + 1]]``.
    b : ndarray of float, shape (n_pixels,)
    w : ndarray of float, shape (n_pixels,)
        Pixel weights (0 outside the frame).
    v : ndarray of float, shape (m,)
        Chord weights.
    iterations : int
        Iteration limit.
    tol : float
        LSQR's ``atol`` and ``btol`` (at least 1e-5: the products are float32).

    Returns
    -------
    f : ndarray of float64, shape (m,)
    info : dict
        ``iterations`` used, the final ``residual`` norm ``||[W (A f - b); V f]||``
        and LSQR's ``stop`` code.
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import LinearOperator, lsqr

    n_pixels = len(rowptr) - 1
    m = len(v)
    data = np.ones(len(chords), dtype=np.float32)
    A = sp.csr_matrix((data, chords, rowptr), shape=(n_pixels, m), copy=False)
    AT = A.T  # csc view: the transposed product without a copy
    w32 = np.asarray(w, dtype=np.float32)
    v = np.asarray(v, dtype=np.float64)
    colnorm2 = np.asarray(AT @ (w32 * w32), dtype=np.float64) + v * v
    dscale = 1.0 / np.sqrt(np.maximum(colnorm2, 1e-12))  # unit columns: a Jacobi preconditioner
    dv = dscale * v

    def matvec(x):  # [W A D; V D] x
        x = np.ravel(x)
        top = (w32 * (A @ (dscale * x).astype(np.float32))).astype(np.float64)
        return np.concatenate([top, dv * x])

    def rmatvec(r):
        r = np.ravel(r)
        top = (AT @ (w32 * r[:n_pixels].astype(np.float32))).astype(np.float64)
        return dscale * top + dv * r[n_pixels:]

    M = LinearOperator((n_pixels + m, m), matvec=matvec, rmatvec=rmatvec, dtype=np.float64)
    rhs = np.concatenate([np.asarray(w, dtype=np.float64) * np.asarray(b, dtype=np.float64), np.zeros(m)])
    t = max(float(tol), 1e-5)  # float32 products: no point (and no stability) beyond this
    y, istop, itn, r1norm = lsqr(M, rhs, atol=t, btol=t, iter_lim=int(iterations))[:4]
    log.debug("lsqr: %d iterations, residual %.4g, stop %d", itn, r1norm, istop)
    return dscale * y, {"iterations": int(itn), "residual": float(r1norm), "stop": int(istop)}
