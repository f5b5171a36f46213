"""The painting growing in winding order: frames for an animation, and GIF / MP4 bytes.

Frame ``k`` shows the chords wound by then, dark on white (a pixel crossed by
more threads is darker, as the real painting is), the newest in red and the
pins in gray.  GIFs are written by Pillow; MP4 by imageio's
ffmpeg plugin (``imageio-ffmpeg``), when it is installed.
"""

import io

import numpy as np

from .chords import line_pixels, pin_pixels
from ..._files import ANIMATION_COMMENT

__all__ = ["growth_frames", "gif_bytes", "mp4_bytes", "frame_ends", "chord_pixels", "Mp4Unavailable"]


class Mp4Unavailable(RuntimeError):
    """imageio's ffmpeg plugin is not installed."""


def frame_ends(chords, frames):
    """How many chords each frame shows: ``frames`` counts rising evenly to all of them."""
    frames = max(1, min(int(frames), chords)) if chords else 1
    return [int(round(chords * (k + 1) / frames)) for k in range(frames)]


def chord_pixels(plan, size):
    """Where ``plan``'s chords lie on a ``size``-px frame: ``(flat, starts, ring)``.

    ``flat[starts[i]:starts[i + 1]]`` are chord ``i``'s pixels (winding order), ``ring`` the pins' pixels.
    """
    c = np.asarray(plan.chord_list(), dtype=np.int64).reshape(-1, 2)
    rc = pin_pixels(plan.pin_xy, size)
    counts, flat = line_pixels(rc[c[:, 0], 0], rc[c[:, 0], 1], rc[c[:, 1], 0], rc[c[:, 1], 1], size)
    return flat, np.concatenate([[0], np.cumsum(counts)]), rc[:, 0] * size + rc[:, 1]


def growth_frames(plan, *, frames=100, size=400):
    """RGB frames (uint8, ``size x size x 3``) of ``plan``'s chords drawn in winding order.

    Parameters
    ----------
    plan : Plan
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
    # a thread covers about a pixel of the 1001 px drawing: smaller frames see it as a share of a pixel,
    # and a pixel crossed n times keeps (1 - share) ** n of its white
    share = min(1.0, size / 1001.0)
    shade = (255.0 * (1.0 - share) ** np.arange(256)).astype(np.uint8)
    crossed = np.zeros(size * size, dtype=np.int64)
    done = 0
    for end in frame_ends(len(starts) - 1, frames):
        np.add.at(crossed, flat[starts[done]:starts[end]], 1)
        done = end
        gray = shade[np.minimum(crossed, 255)]
        frame = np.repeat(gray[:, None], 3, axis=1)
        frame[ring] = np.minimum(frame[ring], 170)
        if end:
            frame[flat[starts[end - 1]:starts[end]]] = (220, 0, 0)
        yield frame.reshape(size, size, 3), end


def gif_bytes(frames, *, fps=10, hold_s=2.0):
    """An endlessly looping GIF of ``frames`` (the last one held ``hold_s`` seconds)."""
    from PIL import Image

    images = [Image.fromarray(f).quantize(colors=64, dither=Image.Dither.NONE) for f in frames]
    if not images:
        raise ValueError("no frames")
    step = max(20, int(round(1000.0 / fps)))
    durations = [step] * (len(images) - 1) + [max(step, int(hold_s * 1000))]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=durations, loop=0,
                   optimize=False, comment=ANIMATION_COMMENT)
    return buf.getvalue()


def mp4_bytes(frames, *, fps=10):
    """An H.264 MP4 of ``frames`` through imageio's ffmpeg plugin.

    Raises
    ------
    Mp4Unavailable
        When ``imageio-ffmpeg`` is not installed.
    """
    try:
        import imageio.v3 as iio
        import imageio_ffmpeg  # noqa: F401  (the plugin's binary)
    except ImportError:
        raise Mp4Unavailable("writing MP4 needs imageio's ffmpeg plugin: pip install imageio-ffmpeg "
                             "(or write a .gif)") from None
    stack = np.stack(list(frames))
    return iio.imwrite("<bytes>", stack, extension=".mp4", plugin="FFMPEG", fps=fps, codec="libx264",
                       macro_block_size=1, pixelformat="yuv420p",
                       output_params=["-metadata", "comment=" + ANIMATION_COMMENT.decode()])
