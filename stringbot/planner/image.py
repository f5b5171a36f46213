"""Moved to :mod:`stringbot.planner.picture.read`: this old name is the same module, kept only while the colour
planner still imports it (import-linter forbids it to every other module)."""

import sys

from .picture import read

sys.modules[__name__] = read
