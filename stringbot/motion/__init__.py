"""Motion: plan + machine -> hooking moves -> G-code (pure; no I/O)."""

__all__ = []
