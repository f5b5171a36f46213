"""Moved to :mod:`stringbot.planner.methods.fitness`: this old name is the same module, kept only while the colour
planner still imports it (import-linter forbids it to every other module)."""

import sys

from .methods import fitness

sys.modules[__name__] = fitness
