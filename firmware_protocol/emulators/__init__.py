"""Simulated firmware: bytes in -> bytes out, no I/O of their own."""

__all__ = []
