"""stringbot: plan a thread painting from a picture and wind it on a string-art machine.

The host side, in layers that each use only the ones after them::

    cli -> winding -> links -> motion -> planner

See docs/design.md for the contracts (plan file, machine file, physical model).
"""

__version__ = "0.1.0"
__all__ = ["__version__"]
