"""pyserial URL handlers; ``protocol_sim.py`` serves ``sim://``.

Call :func:`register` once (idempotent) and ``serial.serial_for_url("sim://...")``
opens the simulated machine.
"""

__all__ = ["register", "PACKAGE"]

PACKAGE = "firmware_protocol.urlhandler"


def register():
    """Add this package to ``serial.protocol_handler_packages`` (once)."""
    import serial
    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)
