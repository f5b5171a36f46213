"""Planner: picture -> :class:`Plan` (the methods: :mod:`stringbot.planner.methods`).

``Plan``, ``read_plan`` and ``write_plan`` are loaded on first use, so that the
command line can read the method registry without numpy.
"""

__all__ = ["Plan", "read_plan", "write_plan"]


def __getattr__(name):
    if name in __all__:
        from . import plan_file

        return getattr(plan_file, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
