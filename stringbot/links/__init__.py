"""Links: moves -> bytes on a port (pyserial, dynamixel-sdk); the only code that opens ports."""

__all__ = []
