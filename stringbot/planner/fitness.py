"""The frame mask the colour planner imports from here moved to :mod:`stringbot.planner.model.chords`; this
old name is kept only while the colour planner still imports it (import-linter forbids it to every other
module)."""

from .model.chords import frame_mask  # noqa: F401
