"""Progress of long planner work, for whoever shows it (the command line).

The planner calls :func:`report` at its stages (``"reading the picture"``,
``"chords"``, ``"solving (detail)"``, ``"sampling (detail)"`` with ``done`` of
``total`` lines, ...); nothing happens unless a caller wraps the work in
:func:`reporting`::

    with reporting(lambda stage, done, total: ...):
        plan = plan_picture(...)

The callback runs in the planner's thread and must return quickly.
"""

import contextlib
import contextvars

__all__ = ["reporting", "report"]

_callback = contextvars.ContextVar("stringbot_planner_progress", default=None)


@contextlib.contextmanager
def reporting(callback):
    """Send the planner's progress to ``callback(stage, done, total)`` inside the block."""
    token = _callback.set(callback)
    try:
        yield
    finally:
        _callback.reset(token)


def report(stage, done=None, total=None):
    """Tell the caller (if any) that ``stage`` is under way, ``done`` of ``total`` where known."""
    cb = _callback.get()
    if cb is not None:
        cb(stage, done, total)
