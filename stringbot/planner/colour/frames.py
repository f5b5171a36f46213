"""A colour plan growing in winding order: frames for ``stringbot animate``.

Each frame is the reference rendering in colour (:mod:`.render`) of the
chords wound by then, drawn as the preview is drawn (``PREVIEW_SAMPLES``
across a thread): the threads are painted one by one, in winding order, on
a fine canvas holding the colour on top at each sample (a later thread hides
what it covers), and each frame is the canvas box-filtered to the frame's
size, composited over the board in linear light.  So the last frame is the
preview drawn at that size, pixel for pixel (``tests/test_colour_wind.py``).
On every frame but the last the newest chord is marked in the opposite colour
of its thread and the pins in gray.
"""

import numpy as np

from ..model.frames import chord_pixels, frame_ends
from ..model.reference import fine_factor, thread_samples
from .palette import hex_to_rgb
from .render import PREVIEW_SAMPLES, compose, to_uint8

__all__ = ["colour_growth_frames"]


def colour_growth_frames(plan, *, frames=100, size=400):
    """RGB frames (uint8, ``size x size x 3``) of a colour ``plan``'s chords in winding order.

    Parameters and what it yields: as :func:`stringbot.planner.model.frames.growth_frames`'s (any plan:
    a one-thread plan is one layer of its colour).
    """
    fraction = plan.thread_model().fraction
    k = fine_factor(size, fraction, samples=PREVIEW_SAMPLES)
    F = size * k
    half = fraction * F / 2.0
    colors = list(dict.fromkeys(plan.colors))
    chords = [(colors.index(lay.color) + 1, a, b) for lay in plan.layers for a, b in lay.chords()]
    top = np.zeros(F * F, dtype=np.uint8)                      # the colour on top at each sample, 0 the board
    counts = np.zeros((len(colors) + 1, size * size), dtype=np.int32)
    counts[0] = k * k
    xy = np.asarray(plan.pin_xy, dtype=np.float64)
    flat, starts, ring = chord_pixels(plan, size)
    done = 0
    ends = frame_ends(len(chords), frames)
    for end in ends:
        lost, won = [], []                                    # (colour, pixel) of each sample that changed
        for c, a, b in chords[done:end]:
            s = thread_samples(xy[a], xy[b], F, half)
            old = top[s]
            moved = old != c
            s, old = s[moved], old[moved]
            cells = (s // (F * k)) * size + (s % F) // k
            lost.append(old.astype(np.int64) * (size * size) + cells)
            won.append(c * (size * size) + cells)
            top[s] = c
        if lost:
            n = counts.size
            counts -= np.bincount(np.concatenate(lost), minlength=n).reshape(counts.shape).astype(np.int32)
            counts += np.bincount(np.concatenate(won), minlength=n).reshape(counts.shape).astype(np.int32)
        done = end
        shares = counts[1:].astype(np.float32) * np.float32(1.0 / (k * k))   # as the reference box-filters
        frame = to_uint8(compose(colors, shares, plan.background), linear=True)
        if end and end != ends[-1]:
            frame[ring] = np.minimum(frame[ring], 170)
            newest = hex_to_rgb(colors[chords[end - 1][0] - 1])        # sRGB in [0, 1]
            frame[flat[starts[end - 1]:starts[end]]] = np.rint(255.0 * (1.0 - newest)).astype(np.uint8)
        yield frame.reshape(size, size, 3), end
