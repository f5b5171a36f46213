"""``--colors auto:N``: the threads whose mixes can reach the picture's colours.

A woven piece shows, at each spot, a mix in linear light of the threads on
top there and of the board between them (:mod:`.model`).  At the line counts
a colour piece needs the board shows little: 4605 lines of a 0.25 mm thread
on a 500 mm ring leave about 15 % of it bare (the threads' union covers
``1 - exp(-L a / A)``, ``a`` a chord's area, ``A`` the frame's), more where
the picture is light and less where it is dark.  So the colours a palette
can *reach* are the mixes of its threads with at most a share ``bare`` of
the board (:func:`bare_share`: twice the share the line count leaves bare on
average); a light area needs a light thread, not only the board.

The *reach* of a palette is how far, in CIELAB, the picture's colours lie
from the nearest colour it can reach: the root mean square over a sample of
the frame's pixels, so that colours it misses by far (the black of a pupil,
the white of a cup) count more than a small shift of many.  Threads are
chosen one at a time, each the one that brings the reach down most, then
each is swapped for any other that does better (two passes); the list is
``threads.toml`` or the user's (``auto:N:LIST``).  When a thread would bring
the reach down by less than :data:`NO_NEARER` the choice stops short of
``N`` and says why (:class:`Palette`).
"""

import itertools
from dataclasses import dataclass, field

import numpy as np

from .palette import MIN_DELTA_E, WHITE, describe_color, hex_to_rgb, lab, threads, to_linear

__all__ = ["Palette", "auto_palette", "reach", "bare_share", "NO_NEARER"]

#: a thread that brings the reach down by less than this (CIELAB) is not worth its spool
NO_NEARER = 0.25
_SAMPLE = 1200
_GRID = {1: 1, 2: 16, 3: 12, 4: 8, 5: 6, 6: 4, 7: 3, 8: 3}  # divisions of the threads' simplex, by their number
_BARE_LEVELS = 4


@dataclass
class Palette:
    """The threads ``auto:N`` picked, and how near each step brought the picture's colours.

    Attributes
    ----------
    colors : list of str
        The threads, ``"#rrggbb"``, in the order they were picked.
    asked : int
        N.
    reach : list of float
        The reach (RMS CIELAB distance to the nearest colour the palette can
        show) with the first 1, 2, ... threads.
    bare : float
        The most of the board a pixel shows, as assumed.
    why_fewer : str or None
        Why fewer than N (None when N).
    """

    colors: list
    asked: int
    reach: list = field(default_factory=list)
    bare: float = 1.0
    why_fewer: str | None = None


def bare_share(lines, mean_chord, width_fraction, frame="circle"):
    """The most of the board a pixel is taken to show: twice what ``lines`` chords of mean length
    ``mean_chord`` (frame diameters) and width ``width_fraction`` leave bare on average (at most 1)."""
    area = np.pi / 4.0 if frame == "circle" else 1.0
    covered = float(lines) * float(mean_chord) * float(width_fraction) / area
    return float(min(1.0, 2.0 * np.exp(-covered)))


def _simplex(vertices, steps):
    pts = [c for c in itertools.product(range(steps + 1), repeat=vertices - 1) if sum(c) <= steps]
    return np.array([[steps - sum(c), *c] for c in pts], dtype=np.float64) / steps


def reach(target_lab, board, colors_linear, bare):
    """The reach of threads ``colors_linear`` (k, 3) on ``board`` for pixels ``target_lab`` (n, 3), CIELAB."""
    from scipy.spatial import cKDTree

    mixes = _simplex(len(colors_linear), _GRID.get(len(colors_linear), 3)) @ np.asarray(colors_linear)
    pts = np.vstack([b * np.asarray(board) + (1.0 - b) * mixes for b in np.linspace(0.0, bare, _BARE_LEVELS)])
    d = cKDTree(lab(pts)).query(target_lab)[0]
    return float(np.sqrt(np.mean(d * d)))


def auto_palette(rgb, n, *, background=WHITE, mask=None, candidates=None, bare=1.0, rng=None):
    """Pick ``n`` threads for a picture by reach (see the module notes).

    Parameters
    ----------
    rgb : ndarray of float, shape (h, w, 3)
        The crop, sRGB in [0, 1].
    n : int
    background : str
        The board, ``"#rrggbb"``.
    mask : ndarray of bool, shape (h, w), optional
        Pixels that count (inside the frame).
    candidates : list of str, optional
        ``"#rrggbb"`` to pick among (default: every thread of ``threads.toml``).
    bare : float
        The most of the board a pixel shows (:func:`bare_share`).
    rng : None, int or numpy Generator
        Seeds the pixel sample (None: a fixed seed).

    Returns
    -------
    Palette
    """
    rng = np.random.default_rng(0 if rng is None else rng)
    px = np.asarray(rgb, dtype=np.float64).reshape(-1, 3)
    if mask is not None:
        px = px[np.asarray(mask).ravel()]
    px = px[rng.choice(len(px), size=min(_SAMPLE, len(px)), replace=False)]
    pool = list(dict.fromkeys(candidates if candidates is not None else threads().values()))
    lin = to_linear(np.array([hex_to_rgb(c) for c in pool]).reshape(-1, 3))
    board = to_linear(hex_to_rgb(background))
    visible = [i for i in range(len(pool)) if np.linalg.norm(lab(lin[i:i + 1]) - lab(board[None])) >= MIN_DELTA_E]
    target = lab(to_linear(px))

    def cost(chosen):
        return reach(target, board, lin[chosen], bare)

    out = Palette(colors=[], asked=int(n), bare=float(bare))
    chosen, now = [], reach(target, board, board[None], bare)   # the bare board: what no thread reaches
    while len(chosen) < n:
        options = [i for i in visible if i not in chosen]
        if not options:
            out.why_fewer = (f"only {len(chosen)} of the {len(pool)} threads to pick from differ from the board "
                             f"({background})")
            break
        best, i = min((cost(chosen + [i]), i) for i in options)
        if chosen and now - best < NO_NEARER:
            out.why_fewer = (f"a thread more would bring the picture's colours no nearer (reach {now:.2f} -> "
                             f"{best:.2f} CIELAB with the best one left, {describe_color(pool[i])}; less than "
                             f"{NO_NEARER})")
            break
        chosen.append(i)
        now = best
    for _ in range(2):               # swap passes: a thread for a better one, until none is
        improved = False
        for slot in range(len(chosen)):
            for i in visible:
                if i in chosen:
                    continue
                trial = chosen[:slot] + [i] + chosen[slot + 1:]
                c = cost(trial)
                if c < now - 1e-9:
                    chosen, now, improved = trial, c, True
        if not improved:
            break
    out.colors = [pool[i] for i in chosen]
    out.reach = [round(cost(chosen[:k + 1]), 3) for k in range(len(chosen))]
    return out
