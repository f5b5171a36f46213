"""Moved to :mod:`stringbot.planner.model.chords`: this old name is the same module, kept only while the colour
planner still imports it (import-linter forbids it to every other module)."""

import sys

from .model import chords

sys.modules[__name__] = chords
