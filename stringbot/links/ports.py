"""Opening a port: the one place that turns a URL into an open pyserial port.

``open_port(url)`` takes anything :func:`serial.serial_for_url` takes
(``/dev/ttyUSB0``, ``COM3``, ``socket://host:port``, ``sim://?machine=...``)
and maps every way opening can fail to one clear line: a port that does not
exist, is busy or is not permitted is the user's input (:class:`BadInput`,
exit 2); anything else the port itself reports is a :class:`MachineFailure`.
"""

import errno
import logging

import serial

from ..errors import BadInput, MachineFailure

__all__ = ["open_port", "sim_url"]

log = logging.getLogger(__name__)

_registered = False


def _register_sim():
    """Make ``sim://`` known to pyserial (the simulated machine), once."""
    global _registered
    if _registered:
        return
    try:
        from firmware_protocol import urlhandler
        register = getattr(urlhandler, "register", None)
        if register is not None:
            register()
        elif "firmware_protocol.urlhandler" not in serial.protocol_handler_packages:
            serial.protocol_handler_packages.append("firmware_protocol.urlhandler")
    except ImportError:  # pragma: no cover - the package ships with stringbot
        pass
    _registered = True


def sim_url(machine_name, *, record=None, faults=None, realtime=False):
    """The ``sim://`` URL of the simulated ``machine_name`` (options in the query string)."""
    from urllib.parse import urlencode
    query = {"machine": machine_name}
    if record:
        query["record"] = str(record)
    if faults:
        query["faults"] = faults
    if realtime:
        query["realtime"] = "1"
    return "sim://?" + urlencode(query, safe="/,@:")


def open_port(url, *, baudrate=115200, timeout=0.05, write_timeout=2.0):
    """Open ``url`` and return the pyserial port object.

    Raises
    ------
    BadInput
        The port does not exist, is busy, is not permitted, or the URL is malformed.
    MachineFailure
        The port exists but could not be opened for another reason.
    """
    _register_sim()
    try:
        return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout,
                                     write_timeout=write_timeout, exclusive=True)
    except TypeError:
        # URL handlers that do not take ``exclusive``
        pass
    except (serial.SerialException, OSError, ValueError) as exc:
        raise _explain(url, exc) from None
    try:
        return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout,
                                     write_timeout=write_timeout)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise _explain(url, exc) from None


def _explain(url, exc):
    """One line for why ``url`` could not be opened."""
    code = getattr(exc, "errno", None)
    text = str(exc)
    low = text.lower()
    if isinstance(exc, FileNotFoundError) or code == errno.ENOENT or "no such file" in low \
            or "could not find" in low or "filenotfounderror" in low:
        return BadInput(f"port {url!r} does not exist; give --port a serial device "
                        "(e.g. /dev/ttyUSB0, COM3) or a URL (socket://host:port, sim://)")
    if isinstance(exc, PermissionError) or code in (errno.EACCES, errno.EPERM) \
            or "permission denied" in low:
        return BadInput(f"port {url!r} is not permitted for this user; "
                        "add yourself to the port's group (e.g. dialout) and log in again")
    if code == errno.EBUSY or "busy" in low or "could not exclusively lock" in low \
            or "resource temporarily unavailable" in low:
        return BadInput(f"port {url!r} is busy: another program has it open; close it first")
    if isinstance(exc, ValueError) or "invalid url" in low or "expected" in low \
            or "unknown url" in low or "not a valid" in low:
        first = text.splitlines()[0] if text else type(exc).__name__
        return BadInput(f"port {url!r} is not a usable URL: {first}")
    first = text.splitlines()[0] if text else type(exc).__name__
    if code == errno.ECONNREFUSED or "refused" in low:
        return MachineFailure(f"port {url!r} refused the connection: check that the serial server there "
                              "(e.g. ser2net) runs and listens on that host and port number")
    if code in (errno.ETIMEDOUT, errno.EHOSTUNREACH, errno.ENETUNREACH) or "timed out" in low \
            or "unreachable" in low:
        return MachineFailure(f"port {url!r} could not be reached ({first}): check the host name, the "
                              "network and that the serial server is on")
    return MachineFailure(f"could not open port {url!r}: {first}")
