"""A colour plan growing in winding order: frames for ``stringbot animate``.

As :func:`stringbot.planner.model.frames.growth_frames` draws a one-thread plan, but
each chord in its layer's colour over the plan's board: a pixel crossed ``m``
times by threads of colour ``C`` keeps ``(1 - s) ** m`` of what lay under it
and takes ``1 - (1 - s) ** m`` of ``C`` (``s``, a thread's share of a pixel),
in winding order, so a later layer covers an earlier one as on the board.
Composited in linear light, as ``render`` does.  The newest chord is drawn in
the opposite colour of its thread, the pins in gray.
"""

import numpy as np

from ..model.frames import chord_pixels, frame_ends
from .palette import hex_to_rgb, to_linear, to_srgb

__all__ = ["colour_growth_frames"]


def _linear(hex_color):
    return to_linear(np.asarray(hex_to_rgb(hex_color), dtype=float))


def colour_growth_frames(plan, *, frames=100, size=400):
    """RGB frames (uint8, ``size x size x 3``) of a colour ``plan``'s chords in winding order.

    Parameters
    ----------
    plan : Plan
        Any plan (a one-thread plan is one layer of its colour).
    frames : int
        Number of frames (at most one per chord).
    size : int
        Side in pixels.

    Yields
    ------
    (ndarray, int)
        The frame and the number of chords it shows.
    """
    flat, starts, ring = chord_pixels(plan, size)
    layer_of = np.concatenate([np.full(max(len(lay.sequence) - 1, 0), k, dtype=np.int64)
                               for k, lay in enumerate(plan.layers)] or [np.zeros(0, dtype=np.int64)])
    colors = [_linear(lay.color) for lay in plan.layers]
    keep = 1.0 - min(1.0, size / 1001.0)        # what a pixel keeps under one thread (as growth_frames)
    canvas = np.tile(_linear(plan.background), (size * size, 1))
    done = 0
    for end in frame_ends(len(starts) - 1, frames):
        a = done
        while a < end:                          # the new chords, layer by layer
            k = layer_of[a]
            b = a
            while b < end and layer_of[b] == k:
                b += 1
            m = np.bincount(flat[starts[a]:starts[b]], minlength=size * size)
            left = keep ** m
            canvas = canvas * left[:, None] + colors[k][None, :] * (1.0 - left)[:, None]
            a = b
        done = end
        frame = np.rint(np.clip(to_srgb(canvas), 0.0, 1.0) * 255.0).astype(np.uint8)
        frame[ring] = np.minimum(frame[ring], 170)
        if end:
            newest = hex_to_rgb(plan.layers[layer_of[end - 1]].color)        # sRGB in [0, 1]
            frame[flat[starts[end - 1]:starts[end]]] = np.rint(255.0 * (1.0 - newest)).astype(np.uint8)
        yield frame.reshape(size, size, 3), end
