"""Planner: picture -> :class:`Plan` (the paper's fitness method and the greedy baseline)."""

from .plan_file import Plan, read_plan, write_plan

__all__ = ["Plan", "read_plan", "write_plan"]
