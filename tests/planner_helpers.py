"""Small synthetic pictures for the planner tests."""

import numpy as np

from stringbot.planner.image import Picture


def picture(gray):
    """A :class:`Picture` of a square gray array (levels 0..255), as if read from a file."""
    n = gray.shape[0]
    return Picture(np.asarray(gray, dtype=np.float32), {"cx": n / 2, "cy": n / 2, "r": n / 2},
                   {"path": "synthetic", "sha256": "0" * 64, "width": n, "height": n}, "gray")
