"""The device side: what a string-art machine's firmware speaks, and a simulated machine.

Never imports :mod:`stringbot`; the host may use the constants and codecs here.
"""

__all__ = []
