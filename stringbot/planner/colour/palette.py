"""Thread colours: names and ``#rrggbb``, the board, and a palette picked from a picture.

A colour is always handled as ``"#rrggbb"`` (lower case, sRGB).  Names come
from ``threads.toml`` beside this module (common thread shades); a board
(``--background``) also takes ``white`` (``#ffffff``) and ``black``
(``#000000``), the paint of a board rather than a thread.

Light mixes linearly: a pixel that a thread covers by ``a`` reflects
``board * (1 - a) + thread * a`` in *linear* RGB (:func:`to_linear`), which is
what the eye averages at a distance.  The planner, the renderer and the score
all mix there and convert back (:func:`to_srgb`) only to show or to measure.

``--colors auto:N`` picks ``N`` threads of the list (or of ``auto:N:LIST``)
by what their mixes with the board can reach (:mod:`.reach`).
"""

import functools
import re
import tomllib
from pathlib import Path

import numpy as np

from ...errors import BadInput

__all__ = ["lab", "threads", "describe_color", "parse_color", "parse_colors", "parse_background", "to_linear",
           "to_srgb",
           "hex_to_rgb", "rgb_to_hex", "color_name", "delta_e", "BLACK", "WHITE", "MAX_COLORS",
           "MIN_DELTA_E"]

BLACK, WHITE = "#000000", "#ffffff"
MAX_COLORS = 8
#: A thread closer to the board than this (CIE76) would hardly be seen on it.
MIN_DELTA_E = 8.0
_BOARDS = {"white": WHITE, "black": BLACK}
_HEX = re.compile(r"^#?([0-9a-fA-F]{6}|[0-9a-fA-F]{3})$")


# linear sRGB -> XYZ (D65), normalised by the white point: t = Q rgb; Lab = P f(t) + (-16, 0, 0)
_XYZ = np.array([[0.4124564, 0.3575761, 0.1804375],
                 [0.2126729, 0.7151522, 0.0721750],
                 [0.0193339, 0.1191920, 0.9503041]])
_Q = _XYZ / _XYZ.sum(axis=1, keepdims=True)
_QT = np.ascontiguousarray(_Q.T)
_PT = np.array([[0.0, 116.0, 0.0], [500.0, -500.0, 0.0], [0.0, 200.0, -200.0]]).T
_LAB0 = np.array([-16.0, 0.0, 0.0])
_CUBE = (6.0 / 29.0) ** 3
_SLOPE = 1.0 / (3 * (6.0 / 29.0) ** 2)


def lab(linear):
    """Linear RGB (n, 3) -> CIELAB (n, 3), D65."""
    t = np.asarray(linear, dtype=np.float64) @ _QT
    f = np.where(t > _CUBE, np.cbrt(np.maximum(t, 1e-12)), t * _SLOPE + 4.0 / 29.0)
    return f @ _PT + _LAB0


def _key(name):
    """A colour name as looked up: case, spaces, dashes and underscores ignored, British "grey" as "gray"."""
    return re.sub(r"[\s_\-]+", "", str(name).strip().lower()).replace("grey", "gray")


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


def describe_color(hex_color):
    """``"crimson (#b22222)"`` for a listed thread, the hex alone otherwise: never raises (a
    damaged thread list costs the name, not the winding)."""
    try:
        name = color_name(hex_color)
    except Exception:  # noqa: BLE001 -- a name is a courtesy
        name = hex_color
    return hex_color if name == hex_color else f"{name} ({hex_color})"


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
    """CIE76 (Euclidean CIELAB) difference between two colours."""

    pair = lab(to_linear(np.stack([hex_to_rgb(hex_a), hex_to_rgb(hex_b)])))
    return float(np.linalg.norm(pair[0] - pair[1]))


def parse_colors(text, *, background=WHITE):
    """``--colors``: ``"black,#b22222,..."`` -> list of ``"#rrggbb"``; ``"auto:N"`` -> ``("auto", N)``;
    ``"auto:N:LIST"`` -> ``("auto", N, [candidates])`` (N threads picked among the ones listed).

    Raises
    ------
    BadInput
        Unknown name, bad hex, an empty list, the same colour twice, more than
        :data:`MAX_COLORS` threads, ``auto:N`` with N outside 1..MAX_COLORS (or
        more than its list names), a thread the board would hide (CIE76 below
        :data:`MIN_DELTA_E`).
    """
    raw = str(text).strip()
    if raw.lower().startswith("auto"):
        m = re.fullmatch(r"auto:(\d+)(?::(.*))?", raw, flags=re.IGNORECASE | re.DOTALL)
        if not m:
            raise BadInput(f"--colors {raw!r}; expected auto:N with N in 1..{MAX_COLORS} (or auto:N:LIST, N threads "
                           "picked among those listed), or a list of colours")
        n = int(m.group(1))
        if not 1 <= n <= MAX_COLORS:
            raise BadInput(f"--colors {raw!r}: {n} threads; expected auto:N with N in 1..{MAX_COLORS}")
        if m.group(2) is None:
            return ("auto", n)
        candidates = _color_list(m.group(2), background, whole=raw, most=None)
        if n > len(candidates):
            raise BadInput(f"--colors {raw!r}: {n} threads among {len(candidates)}; expected N at most the "
                           "number of colours listed")
        return ("auto", n, candidates)
    return _color_list(raw, background, whole=raw, most=MAX_COLORS)


def _color_list(raw, background, *, whole, most):
    """The colours of a comma-separated list (``whole``: the option's text, for the messages)."""
    parts = [x.strip() for x in raw.split(",")]
    if not any(parts):
        raise BadInput(f"--colors {whole!r} names no colour; expected e.g. black,#b22222 or auto:3")
    if not all(parts):
        raise BadInput(f"--colors {whole!r} has an empty item; expected colours separated by single commas, "
                       "e.g. black,#b22222")
    if most is not None and len(parts) > most:
        raise BadInput(f"--colors gives {len(parts)} threads; expected at most {most}")
    colors = [parse_color(p) for p in parts]
    for k, (name, c) in enumerate(zip(parts, colors)):
        if c in colors[:k]:
            raise BadInput(f"--colors names {name!r} ({c}) twice; expected each thread once")
        if delta_e(c, background) < MIN_DELTA_E:
            raise BadInput(f"--colors: {name!r} ({c}) is the colour of the board ({background}), so its "
                           "thread would not show; expected threads that differ from --background")
    return colors
