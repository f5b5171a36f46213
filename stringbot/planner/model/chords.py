"""The chord space of section 3.1 and the chord-pixel matrix.

Pins sit on a circle (or on the border of a square) in a ``size x size``
working image.  Pin 0 is at the top, pins are numbered clockwise; positions
are normalised to the cropped square (x right, y down, in [0, 1]).

A chord is an unordered pin pair ``{i, j}``, ``i != j``; chord ``c`` is the
``c``-th pair ``(i, j)`` with ``i < j`` in row-major order of the upper
triangle, restricted to the *valid* pairs (on a square frame, pairs lying
along one side are not chords: they draw nothing inside the frame).

The pixels of every chord are found by sampling it at ``max(|dx|, |dy|) + 1``
points between pin pixels (one pixel per step of the major axis, so no pixel
twice and no gap) and kept as a compressed column layout: chord ``c`` covers
the flat pixel indices ``indices[indptr[c]:indptr[c + 1]]`` (``row * size + col``).
Building it is vectorised and chunked; the result is cached on disk per
``(frame, pins, size)`` (see :func:`cache_dir`).
"""

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["pin_positions", "ChordSpace", "chord_space", "chord_pixels", "pixel_chords", "cache_dir",
           "neighbour_offsets", "line_pixels", "frame_mask", "thread_length"]

FRAMES = ("circle", "square")
_CACHE_VERSION = 1
_CHUNK = 4_000_000  # samples per vectorised chunk: bounds the temporaries (~100 MB)


def pin_positions(pins, frame="circle"):
    """Pin positions normalised to the cropped square.

    Parameters
    ----------
    pins : int
        Number of pins, >= 3.
    frame : {"circle", "square"}
        Circle: pin k at angle ``2 pi k / pins`` clockwise from the top.
        Square: pins evenly spaced along the border, pin 0 at the middle of
        the top side, clockwise.

    Returns
    -------
    ndarray of float, shape (pins, 2)
        ``(x, y)`` per pin, x right, y down, in [0, 1].
    """
    k = np.arange(pins, dtype=float)
    if frame == "circle":
        a = 2 * np.pi * k / pins
        return np.stack([0.5 + 0.5 * np.sin(a), 0.5 - 0.5 * np.cos(a)], axis=1)
    if frame != "square":
        raise ValueError(f"frame {frame!r}; expected one of {FRAMES}")
    # arc length along the border, in sides, starting at the top middle, clockwise
    s = (k * 4.0 / pins + 0.5) % 4.0
    side = np.floor(s).astype(int)
    t = s - side
    x = np.select([side == 0, side == 1, side == 2, side == 3], [t, np.ones_like(t), 1 - t, np.zeros_like(t)])
    y = np.select([side == 0, side == 1, side == 2, side == 3], [np.zeros_like(t), t, np.ones_like(t), 1 - t])
    return np.stack([x, y], axis=1)


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


def thread_length(pin_xy, chords):
    """Total chord length in ring diameters (the side for a square frame)."""
    if not len(chords):
        return 0.0
    c = np.asarray(chords)
    return float(np.linalg.norm(pin_xy[c[:, 0]] - pin_xy[c[:, 1]], axis=1).sum())


def pin_pixels(pin_xy, size):
    """Pin positions in pixels of a ``size x size`` image, rounded to pixel centres.

    Returns
    -------
    ndarray of int, shape (pins, 2)
        ``(row, col)`` per pin.
    """
    rc = np.rint(np.asarray(pin_xy)[:, ::-1] * (size - 1)).astype(np.int64)
    return np.clip(rc, 0, size - 1)


def _same_side(pin_xy, i, j, tol=1e-9):
    """True where pins i and j lie on the same side of the square."""
    xi, yi = pin_xy[i, 0], pin_xy[i, 1]
    xj, yj = pin_xy[j, 0], pin_xy[j, 1]
    out = np.zeros(np.shape(i), dtype=bool)
    for coord_i, coord_j in ((xi, xj), (yi, yj)):
        for edge in (0.0, 1.0):
            out |= (np.abs(coord_i - edge) < tol) & (np.abs(coord_j - edge) < tol)
    return out


@dataclass
class ChordSpace:
    """The discrete chord set of section 3.1.

    Attributes
    ----------
    pins : int
    frame : str
    pin_xy : ndarray of float, shape (pins, 2)
    ends : ndarray of int, shape (m, 2)
        ``(i, j)`` with ``i < j`` for each chord.
    index : ndarray of int, shape (pins, pins)
        Chord number of the pair ``{i, j}`` (symmetric), -1 where it is not a chord.
    span : ndarray of int, shape (m,)
        ``s = min(|i - j|, pins - |i - j|)``, the paper's chord length in pins.
    """

    pins: int
    frame: str
    pin_xy: np.ndarray
    ends: np.ndarray
    index: np.ndarray
    span: np.ndarray

    @property
    def m(self):
        """Number of chords."""
        return len(self.ends)


def chord_space(pins, frame="circle"):
    """Build the chord set for ``pins`` pins on ``frame``; see :class:`ChordSpace`."""
    xy = pin_positions(pins, frame)
    i, j = np.triu_indices(pins, k=1)
    if frame == "square":
        keep = ~_same_side(xy, i, j)
        i, j = i[keep], j[keep]
    index = np.full((pins, pins), -1, dtype=np.int64)
    c = np.arange(len(i))
    index[i, j] = c
    index[j, i] = c
    d = np.abs(i - j)
    span = np.minimum(d, pins - d)
    return ChordSpace(pins=pins, frame=frame, pin_xy=xy, ends=np.stack([i, j], axis=1),
                      index=index, span=span)


def line_pixels(r0, c0, r1, c1, size):
    """Pixels of many segments between integer pixel ends, vectorised.

    Each segment is sampled at ``max(|dr|, |dc|) + 1`` points, one per step
    of its major axis.

    Parameters
    ----------
    r0, c0, r1, c1 : ndarray of int, shape (k,)
        End pixels ``(row, col)``.
    size : int
        Image side; flat index is ``row * size + col``.

    Returns
    -------
    counts : ndarray of int64, shape (k,)
        Pixels per segment.
    flat : ndarray of int32, shape (counts.sum(),)
        Flat pixel indices, segment after segment.
    """
    r0, c0, r1, c1 = (np.asarray(a, dtype=np.int64) for a in (r0, c0, r1, c1))
    if size > 4096:
        raise ValueError("size > 4096: flat indices would not be exact in float32")
    dr, dc = r1 - r0, c1 - c0
    steps = np.maximum(np.abs(dr), np.abs(dc))
    counts = steps + 1
    total = int(counts.sum())
    flat = np.empty(total, dtype=np.int32)
    starts = np.concatenate([[0], np.cumsum(counts)])
    # per segment: flat = base + t * major + rint(t * slope) * minor, t = 0..steps
    # (float32 is exact here: every flat index < 2**24)
    row_major = np.abs(dr) >= np.abs(dc)
    major = np.where(row_major, np.sign(dr) * size, np.sign(dc)).astype(np.float32)
    minor = np.where(row_major, 1, size).astype(np.float32)
    slope = (np.where(row_major, dc, dr) / np.maximum(steps, 1)).astype(np.float32)
    base = (r0 * size + c0).astype(np.float32)
    k = len(counts)
    a = 0
    while a < k:  # chunks over segments bound the temporaries
        b = int(np.searchsorted(starts, starts[a] + _CHUNK, side="right")) - 1
        b = min(max(b, a + 1), k)
        n = counts[a:b]
        lo, hi = int(starts[a]), int(starts[b])
        seg = np.repeat(np.arange(a, b, dtype=np.int32), n)
        t = np.arange(hi - lo, dtype=np.float32)
        t -= np.repeat((starts[a:b] - lo).astype(np.float32), n)
        m = np.rint(t * slope[seg])
        m *= minor[seg]
        t *= major[seg]
        t += base[seg]
        t += m
        flat[lo:hi] = t
        a = b
    return counts, flat


def cache_dir():
    """Folder of the chord-pixel cache, or None when caching is off.

    ``$STRINGBOT_CACHE`` (``off``, ``0`` or empty string: no cache), else
    ``$XDG_CACHE_HOME/stringbot``, else ``~/.cache/stringbot``.
    """
    env = os.environ.get("STRINGBOT_CACHE")
    if env is not None:
        return None if env.strip().lower() in ("", "0", "off", "no") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "stringbot"


def _cache_file(space, size, kind="chords"):
    d = cache_dir()
    if d is None:
        return None
    return d / f"{kind}-v{_CACHE_VERSION}-{space.frame}-{space.pins}-{size}.npz"


def _read_cache(path, n_ptr):
    if path is None or not path.is_file():
        return None
    try:
        with np.load(path) as z:
            indptr, indices = z["indptr"], z["indices"]
        if len(indptr) == n_ptr and indptr[-1] == len(indices):
            log.debug("read %s", path)
            return indptr, indices
        log.warning("cache %s does not fit; rebuilding", path)
    except (OSError, ValueError, KeyError, EOFError) as exc:  # a damaged cache is rebuilt
        log.warning("cache %s unreadable (%s); rebuilding", path, exc)
    return None


def chord_pixels(space, size, *, cache=True, write=True):
    """Pixels of every chord of ``space`` in a ``size x size`` image.

    Parameters
    ----------
    space : ChordSpace
    size : int
        Working image side in pixels.
    cache : bool
        Read and write the on-disk cache (see :func:`cache_dir`).
    write : bool
        Write the cache when it was missing (only with ``cache``).

    Returns
    -------
    indptr : ndarray of int64, shape (m + 1,)
    indices : ndarray of int32, shape (indptr[-1],)
        Chord ``c`` covers flat pixels ``indices[indptr[c]:indptr[c + 1]]``.
    """
    path = _cache_file(space, size) if cache else None
    hit = _read_cache(path, space.m + 1)
    if hit is not None:
        return hit
    rc = pin_pixels(space.pin_xy, size)
    i, j = space.ends[:, 0], space.ends[:, 1]
    counts, indices = line_pixels(rc[i, 0], rc[i, 1], rc[j, 0], rc[j, 1], size)
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    if path is not None and write:
        _write_cache(path, indptr, indices)
    return indptr, indices


def pixel_chords(space, size, *, cache=True):
    """The chord-pixel incidence, pixel by pixel (the transpose of :func:`chord_pixels`).

    Pixel-major order makes both sparse products of the solve gathers over
    small vectors, about twice as fast as the chord-major layout.

    Returns
    -------
    rowptr : ndarray of int64, shape (size * size + 1,)
    chords : ndarray of int32, shape (rowptr[-1],)
        Pixel ``p`` is covered by chords ``chords[rowptr[p]:rowptr[p + 1]]``.
    """
    path = _cache_file(space, size, "pixels") if cache else None
    hit = _read_cache(path, size * size + 1)
    if hit is not None:
        return hit
    import scipy.sparse as sp

    indptr, indices = chord_pixels(space, size, cache=cache, write=False)  # the solve needs only this one
    ones = np.ones(len(indices), dtype=np.int8)
    csr = sp.csc_matrix((ones, indices, indptr), shape=(size * size, space.m)).tocsr()
    rowptr, chords = csr.indptr.astype(np.int64), csr.indices.astype(np.int32, copy=False)
    del csr, ones
    if path is not None:
        _write_cache(path, rowptr, chords)
    return rowptr, chords


def _write_cache(path, indptr, indices):
    """Write the cache atomically; a failure only costs speed next time."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        with open(tmp, "wb") as f:  # straight to the file: no in-memory copy of a large array
            np.savez(f, indptr=indptr, indices=indices)
        os.replace(tmp, path)
        log.debug("chord pixels cached in %s", path)
    except OSError as exc:
        log.warning("cannot write chord cache %s (%s); continuing without it", path, exc)
        if tmp is not None:
            try:
                tmp.unlink()
            except OSError:
                pass


def neighbour_offsets(epsilon):
    """Offsets ``(a, b)`` with ``max(|a|, |b|) <= epsilon`` in pin-index space.

    The epsilon-neighbourhood of chord ``{i, j}`` under the paper's distance
    (the minimal L-infinity distance over the equivalences ``(i, j) ~ (j, i)``
    and wrap-around by ``pins``) is the set of unordered pairs
    ``{(i + a) mod P, (j + b) mod P}`` over these offsets.

    Returns
    -------
    ndarray of int, shape ((2 epsilon + 1)**2, 2)
    """
    e = int(epsilon)
    a, b = np.meshgrid(np.arange(-e, e + 1), np.arange(-e, e + 1), indexing="ij")
    return np.stack([a.ravel(), b.ravel()], axis=1)
