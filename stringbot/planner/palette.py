"""Thread colours: names and ``#rrggbb``, the board, and a palette picked from a picture.

A colour is always handled as ``"#rrggbb"`` (lower case, sRGB).  Names come
from ``threads.toml`` beside this module (common thread shades); a board
(``--background``) also takes ``white`` (``#ffffff``) and ``black``
(``#000000``), the paint of a board rather than a thread.

Light mixes linearly: a pixel that a thread covers by ``a`` reflects
``board * (1 - a) + thread * a`` in *linear* RGB (:func:`to_linear`), which is
what the eye averages at a distance.  The planner, the renderer and the score
all mix there and convert back (:func:`to_srgb`) only to show or to measure.

``--colors auto:N`` (:func:`auto_palette`) picks ``N`` threads of the list
whose mixes with the board come nearest the picture's colours.
"""

import functools
import re
import tomllib
from pathlib import Path

import numpy as np

from ..errors import BadInput

__all__ = ["threads", "parse_color", "parse_colors", "parse_background", "to_linear", "to_srgb",
           "hex_to_rgb", "rgb_to_hex", "auto_palette", "color_name", "BLACK", "WHITE", "MAX_COLORS",
           "MIN_DELTA_E"]

BLACK, WHITE = "#000000", "#ffffff"
MAX_COLORS = 8
#: A thread closer to the board than this (CIEDE2000) would not be seen on it.
MIN_DELTA_E = 5.0
_BOARDS = {"white": WHITE, "black": BLACK}
_HEX = re.compile(r"^#?([0-9a-fA-F]{6}|[0-9a-fA-F]{3})$")


def _key(name):
    return re.sub(r"[\s_\-]+", "", str(name).strip().lower())


@functools.lru_cache(maxsize=1)
def threads():
    """The shipped thread colours: ``{name: "#rrggbb"}`` in file order."""
    with open(Path(__file__).with_name("threads.toml"), "rb") as f:
        doc = tomllib.load(f)
    return {str(k): str(v).lower() for k, v in doc["threads"].items()}


def color_name(hex_color):
    """The thread list's name of ``hex_color`` (the hex itself when it has none)."""
    for name, value in threads().items():
        if value == hex_color:
            return name
    return {WHITE: "white", BLACK: "black"}.get(hex_color, hex_color)


def hex_to_rgb(hex_color):
    """``"#rrggbb"`` -> sRGB floats in [0, 1], shape (3,)."""
    h = hex_color.lstrip("#")
    return np.array([int(h[i:i + 2], 16) for i in (0, 2, 4)], dtype=np.float64) / 255.0


def rgb_to_hex(rgb):
    """sRGB floats in [0, 1] -> ``"#rrggbb"``."""
    v = np.clip(np.rint(np.asarray(rgb, dtype=np.float64) * 255.0), 0, 255).astype(int)
    return "#" + "".join(f"{int(x):02x}" for x in v)


def to_linear(srgb):
    """sRGB values in [0, 1] -> linear light (IEC 61966-2-1)."""
    c = np.asarray(srgb, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def to_srgb(linear):
    """Linear light in [0, 1] -> sRGB values."""
    c = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


def parse_color(text, *, what="--colors", board=False):
    """A colour name or ``#rrggbb`` / ``#rgb`` -> ``"#rrggbb"``; BadInput naming what is wrong."""
    raw = str(text).strip()
    m = _HEX.match(raw)
    if m and (raw.startswith("#") or not raw.isalpha()):
        h = m.group(1).lower()
        if len(h) == 3:
            h = "".join(c * 2 for c in h)
        return "#" + h
    if raw.startswith("#"):
        raise BadInput(f"{what}: {raw!r} is not a colour; expected #rrggbb (six hex digits), e.g. #b22222")
    key = _key(raw)
    if board and key in _BOARDS:
        return _BOARDS[key]
    names = {_key(n): v for n, v in threads().items()}
    if key in names:
        return names[key]
    raise BadInput(f"{what}: unknown colour {raw!r}; expected #rrggbb or one of "
                   f"{', '.join(threads())}")


def parse_background(text):
    """``--background``: ``white``, ``black``, a thread name or ``#rrggbb``."""
    return parse_color(text, what="--background", board=True)


def delta_e(hex_a, hex_b):
    """CIEDE2000 between two colours."""
    from skimage.color import deltaE_ciede2000, rgb2lab

    lab = rgb2lab(np.stack([hex_to_rgb(hex_a), hex_to_rgb(hex_b)])[None])[0]
    return float(deltaE_ciede2000(lab[0], lab[1]))


def parse_colors(text, *, background=WHITE):
    """``--colors``: ``"black,#b22222,..."`` -> list of ``"#rrggbb"``, or ``"auto:N"`` -> ``("auto", N)``.

    Raises
    ------
    BadInput
        Unknown name, bad hex, an empty list, the same colour twice, more than
        :data:`MAX_COLORS` threads, ``auto:N`` with N outside 1..MAX_COLORS, a
        thread the board would hide (CIEDE2000 below :data:`MIN_DELTA_E`).
    """
    raw = str(text).strip()
    if raw.lower().startswith("auto"):
        m = re.fullmatch(r"auto:(\d+)", raw.lower())
        if not m:
            raise BadInput(f"--colors {raw!r}; expected auto:N with N in 1..{MAX_COLORS}, or a list of colours")
        n = int(m.group(1))
        if not 1 <= n <= MAX_COLORS:
            raise BadInput(f"--colors {raw!r}: {n} threads; expected auto:N with N in 1..{MAX_COLORS}")
        return ("auto", n)
    parts = [p for p in (x.strip() for x in raw.split(",")) if p]
    if not parts:
        raise BadInput(f"--colors {raw!r} names no colour; expected e.g. black,#b22222 or auto:3")
    if len(parts) > MAX_COLORS:
        raise BadInput(f"--colors gives {len(parts)} threads; expected at most {MAX_COLORS}")
    colors = [parse_color(p) for p in parts]
    for k, (name, c) in enumerate(zip(parts, colors)):
        if c in colors[:k]:
            raise BadInput(f"--colors names {name!r} ({c}) twice; expected each thread once")
        if delta_e(c, background) < MIN_DELTA_E:
            raise BadInput(f"--colors: {name!r} ({c}) is the colour of the board ({background}), so its "
                           "thread would not show; expected threads that differ from --background")
    return colors


def _kmeans(x, k, *, iters=20, rng=None):
    """Plain k-means (Lloyd) with k-means++ seeding; returns (centres, labels)."""
    rng = np.random.default_rng(0 if rng is None else rng)
    n = len(x)
    k = min(k, n)
    centres = [x[rng.integers(n)]]
    for _ in range(1, k):
        d2 = np.min(((x[:, None, :] - np.asarray(centres)[None]) ** 2).sum(-1), axis=1)
        p = d2 / d2.sum() if d2.sum() > 0 else None
        centres.append(x[rng.choice(n, p=p)])
    centres = np.asarray(centres)
    for _ in range(iters):
        labels = np.argmin(((x[:, None, :] - centres[None]) ** 2).sum(-1), axis=1)
        new = np.array([x[labels == j].mean(axis=0) if np.any(labels == j) else centres[j] for j in range(k)])
        if np.allclose(new, centres):
            break
        centres = new
    labels = np.argmin(((x[:, None, :] - centres[None]) ** 2).sum(-1), axis=1)
    return centres, labels


_SAMPLE = 800
_GRID = {2: 16, 3: 12, 4: 8, 5: 5, 6: 4}  # divisions of the mixing simplex, by its vertices


def _simplex_grid(vertices, steps):
    """Barycentric grid points of ``vertices`` vertices with ``steps`` divisions: (points, vertices)."""
    import itertools

    pts = [c for c in itertools.product(range(steps + 1), repeat=vertices - 1) if sum(c) <= steps]
    g = np.array([[steps - sum(c), *c] for c in pts], dtype=np.float64) / steps
    return g


def _gamut_distance(lab_pixels, vertices_linear, grid):
    """Mean distance (CIELAB, Euclidean) from each pixel to the nearest mix of the vertices."""
    from .colour import lab

    from scipy.spatial import cKDTree

    return cKDTree(lab(grid @ vertices_linear)).query(lab_pixels)[0]


def auto_palette(rgb, n, *, background=WHITE, mask=None, rng=None, method="gamut"):
    """``n`` thread colours for a picture.

    ``gamut`` (default): forward selection from the thread list.  Every
    colour a piece can show is a mix of the board and its threads (in linear
    light; any coverage of any layer order reaches the whole simplex of board
    and threads), so threads are added one at a time, each the one that
    brings the picture's pixels (a sample of 800 from the frame) nearest,
    on average in CIELAB, to the mixes of the board and the threads chosen so
    far; then each chosen thread is swapped for any other that lowers that
    distance, until none does.  ``kmeans``: the picture clustered into ``2 n``
    colours by k-means in CIELAB, each centre snapped to the nearest thread
    (CIEDE2000), the ``n`` threads covering the most pixels kept (the
    comparison in docs/planner.md, "Colour").

    Parameters
    ----------
    rgb : ndarray of float, shape (h, w, 3)
        The crop, sRGB in [0, 1].
    n : int
    background : str
        The board, ``"#rrggbb"``.
    mask : ndarray of bool, shape (h, w), optional
        Pixels that count (inside the frame).
    rng : None, int or numpy Generator
        Seeds the pixel sample (None: a fixed seed).
    method : {"gamut", "kmeans"}

    Returns
    -------
    list of str
        ``n`` distinct ``"#rrggbb"`` from the thread list, none the board's colour.
    """
    from skimage.color import deltaE_ciede2000, rgb2lab

    from .colour import lab

    rng = np.random.default_rng(0 if rng is None else rng)
    px = np.asarray(rgb, dtype=np.float64).reshape(-1, 3)
    if mask is not None:
        px = px[np.asarray(mask).ravel()]
    px = px[rng.choice(len(px), size=min(_SAMPLE, len(px)), replace=False)]
    names = list(threads())
    cand = np.array([hex_to_rgb(threads()[k]) for k in names])
    board_srgb = hex_to_rgb(background)
    visible = deltaE_ciede2000(np.broadcast_to(rgb2lab(board_srgb[None, None])[0, 0], (len(cand), 3)),
                               rgb2lab(cand[None])[0]) >= MIN_DELTA_E
    n = min(int(n), int(visible.sum()))
    if method == "kmeans":
        return _kmeans_palette(px, n, cand, names, visible, board_srgb, rng)
    if method != "gamut":
        raise ValueError(f"method {method!r}; expected 'gamut' or 'kmeans'")
    target = lab(to_linear(px))
    lin = to_linear(cand)
    board = to_linear(board_srgb)

    def cost(chosen):
        verts = np.vstack([board[None], lin[chosen]])
        grid = _simplex_grid(len(verts), _GRID.get(len(verts), 3))
        return float(_gamut_distance(target, verts, grid).mean())

    chosen = []
    for _ in range(n):
        best = min((cost(chosen + [i]), i) for i in range(len(names)) if visible[i] and i not in chosen)
        chosen.append(best[1])
    current = cost(chosen)
    for _ in range(2):               # swap passes: a thread for a better one, until none is
        improved = False
        for slot in range(n):
            for i in range(len(names)):
                if not visible[i] or i in chosen:
                    continue
                trial = chosen[:slot] + [i] + chosen[slot + 1:]
                c = cost(trial)
                if c < current - 1e-9:
                    chosen, current, improved = trial, c, True
        if not improved:
            break
    return [threads()[names[i]] for i in chosen]


def _kmeans_palette(px, n, cand, names, visible, board_srgb, rng):
    from skimage.color import deltaE_ciede2000, rgb2lab

    lab_px = rgb2lab(px[None])[0]
    cand_lab = rgb2lab(cand[None])[0]
    board_lab = rgb2lab(board_srgb[None, None])[0, 0]
    centres, labels = _kmeans(lab_px, 2 * n, rng=rng)
    score = np.zeros(len(names))
    for j, c in enumerate(centres):
        d = deltaE_ciede2000(np.broadcast_to(c, cand_lab.shape), cand_lab)
        d[~visible] = np.inf
        score[int(np.argmin(d))] += float(np.mean(labels == j)) * float(deltaE_ciede2000(c, board_lab))
    order = [i for i in np.argsort(-score, kind="stable") if score[i] > 0]
    chosen = order[:n]
    far = np.argsort(-deltaE_ciede2000(np.broadcast_to(board_lab, cand_lab.shape), cand_lab), kind="stable")
    for i in far:                    # a flat picture: fill with the threads farthest from the board
        if len(chosen) >= n:
            break
        if i not in chosen and visible[i]:
            chosen.append(int(i))
    return [threads()[names[i]] for i in chosen]
