"""Winding: the wind loop, the journal, resume."""

__all__ = []
