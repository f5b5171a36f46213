"""Planner: picture -> :class:`Plan`.

Its parts: :mod:`.build` (``plan_picture``: the knobs checked by :mod:`.knobs`, the picture read,
one method run), :mod:`.methods` (the registry and each method behind it), :mod:`.picture`
(reading the picture), :mod:`.model` (pins and chords, the thread, the rendering, the scores),
:mod:`.calibration`, :mod:`.plan_file`, :mod:`.progress`; the colour planner.

``Plan``, ``read_plan`` and ``write_plan`` are loaded on first use, so that the
command line can read the method registry without numpy.
"""

__all__ = ["Plan", "read_plan", "write_plan"]


def __getattr__(name):
    if name in __all__:
        from . import plan_file

        return getattr(plan_file, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
