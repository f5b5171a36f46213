"""Opening a port: the one place that turns a URL into an open pyserial port.

``open_port(url)`` takes anything :func:`serial.serial_for_url` takes
(``/dev/ttyUSB0``, ``COM3``, ``socket://host:port``, ``sim://?machine=...``)
and maps every way opening can fail to one clear line: a port that does not
exist, is busy or is not permitted is the user's input (:class:`BadInput`,
exit 2); anything else the port itself reports is a :class:`MachineFailure`.
"""

import errno
import logging
import os
import socket
import stat
import sys

import serial
from serial.urlhandler import protocol_socket

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
    from urllib.parse import quote, urlencode
    query = {"machine": machine_name}
    if record:
        query["record"] = str(record)
    if faults:
        query["faults"] = faults
    if realtime:
        query["realtime"] = "1"
    # sim:// reads '+' as a plus (reset@230+0.4): a space goes as %20, a plus as %2B
    return "sim://?" + urlencode(query, safe="/,@:", quote_via=quote)


class _TcpSerial(protocol_socket.Serial):
    """pyserial's ``socket://`` port, tuned for a line protocol's round trips.

    * TCP_NODELAY: a short line goes out at once, not held by Nagle's algorithm
      until the machine has acknowledged the previous one;
    * TCP_QUICKACK (Linux), re-armed before every read: what the machine sends is
      acknowledged at once, so a machine whose own TCP stack holds small answers
      back until then (Nagle on its side, e.g. a plain ``socat`` bridge, many
      embedded stacks) is not kept waiting by our delayed ACK (40 ms each);
    * ``in_waiting`` reports the bytes really waiting (FIONREAD) instead of 0 or 1,
      so an answer is read in one call, not a byte at a time.
    """

    def open(self):
        super().open()
        sock = self._socket
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._quickack()

    def _quickack(self):
        if _QUICKACK is not None and self._socket is not None:
            try:
                self._socket.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)
            except OSError:
                pass

    @property
    def in_waiting(self):
        if not self.is_open:
            raise serial.PortNotOpenError()
        try:
            import fcntl                # POSIX only, imported here: stringbot.links loads on Windows too
            import termios
            buf = fcntl.ioctl(self._socket.fileno(), termios.FIONREAD, b"\0\0\0\0")
            return int.from_bytes(buf, sys.byteorder)
        except (ImportError, OSError):
            return super().in_waiting

    def read(self, size=1):
        self._quickack()
        data = super().read(size)
        self._quickack()
        return data


_QUICKACK = getattr(socket, "TCP_QUICKACK", None)


def _open_url(url, **kw):
    """``serial_for_url`` with our tuned TCP port for ``socket://``; the RFC 2217 client takes no
    write timeout (pyserial raises NotImplementedError for one), so it gets none."""
    scheme = url.split("://", 1)[0].lower() if "://" in url else ""
    if scheme in ("socket", "rfc2217"):
        _check_network_url(url, scheme)
    if scheme == "socket":
        port = _TcpSerial(None, **kw)
        port.port = url
        port.open()
        return port
    if scheme == "rfc2217":
        kw["write_timeout"] = None
    return serial.serial_for_url(url, **kw)


def _check_network_url(url, scheme):
    """``socket://HOST:PORT`` / ``rfc2217://HOST:PORT[?options]`` with a port 1..65535, or BadInput."""
    from urllib.parse import urlsplit
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError:
        port = None
        parts = None
    if parts is None or not parts.hostname or port is None or not 1 <= port <= 65535 \
            or (scheme == "socket" and parts.query and not parts.query.startswith("logging=")):
        raise BadInput(f"port {url!r} is not a usable URL; expected {scheme}://HOST:PORT with a TCP port "
                       f"1..65535 (e.g. {scheme}://192.168.1.50:23)")


#: What the network says when the machine is not there: the user's input to check (exit 2).
_UNREACHABLE = (("connection refused", "the connection was refused: nothing listens there"),
                ("name or service not known", "the host name is unknown"),
                ("nodename nor servname", "the host name is unknown"),
                ("temporary failure in name resolution", "the host name cannot be resolved"),
                ("no address associated", "the host name is unknown"),
                ("timed out", "the connection timed out"),
                ("network is unreachable", "the network is unreachable"),
                ("no route to host", "there is no route to the host"),
                ("host is down", "the host is down"))


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
    _check_device(url)
    try:
        return _open_url(url, baudrate=baudrate, timeout=timeout, write_timeout=write_timeout, exclusive=True)
    except BadInput:
        raise
    except TypeError:
        # URL handlers that do not take ``exclusive``
        pass
    except (serial.SerialException, OSError, ValueError, NotImplementedError) as exc:
        raise _explain(url, exc) from None
    try:
        return _open_url(url, baudrate=baudrate, timeout=timeout, write_timeout=write_timeout)
    except BadInput:
        raise
    except (serial.SerialException, OSError, ValueError, NotImplementedError) as exc:
        raise _explain(url, exc) from None


_EXPECTED = "expected a serial device (e.g. /dev/ttyUSB0, COM3) or a URL (socket://host:port, sim://)"
_NOT_DEVICES = ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
                (stat.S_ISSOCK, "a socket"), (stat.S_ISBLK, "a block device (a disk)"))


def _check_device(url):
    """A path that exists and is not a character device (a file, a folder, a FIFO...) is the user's
    input, not a machine that failed: BadInput naming what it is, before it is opened."""
    if "://" in url:
        return
    try:
        mode = os.stat(url).st_mode
    except (OSError, ValueError):
        return                          # absent (or a name like COM3): opening it says why
    kind = next((name for test, name in _NOT_DEVICES if test(mode)), None)
    if kind is not None:
        raise BadInput(f"port {url!r} is {kind}, not a serial device; {_EXPECTED}")


def _explain(url, exc):
    """One line for why ``url`` could not be opened."""
    code = getattr(exc, "errno", None)
    text = str(exc)
    low = text.lower()
    if "://" in url and not url.lower().startswith("sim://"):
        for words, meaning in _UNREACHABLE:
            if words in low:
                return BadInput(f"port {url!r}: {meaning}; check the machine is on the network and the "
                                "host and port (a FluidNC or grblHAL telnet server listens on port 23)")
    if isinstance(exc, FileNotFoundError) or code == errno.ENOENT or "no such file" in low \
            or "could not find" in low or "filenotfounderror" in low:
        return BadInput(f"port {url!r} does not exist; give --port a serial device "
                        "(e.g. /dev/ttyUSB0, COM3) or a URL (socket://host:port, sim://)")
    if isinstance(exc, PermissionError) or code in (errno.EACCES, errno.EPERM) \
            or "permission denied" in low:
        return BadInput(f"port {url!r} is not permitted for this user; "
                        "add yourself to the port's group (e.g. dialout) and log in again")
    if code == errno.ENOTTY or "inappropriate ioctl" in low:
        return BadInput(f"port {url!r} is not a serial device (it takes no serial settings); {_EXPECTED}")
    if code == errno.EISDIR or "is a directory" in low:
        return BadInput(f"port {url!r} is a folder, not a serial device; {_EXPECTED}")
    if code == errno.EBUSY or "busy" in low or "could not exclusively lock" in low \
            or "resource temporarily unavailable" in low:
        return BadInput(f"port {url!r} is busy: another program has it open; close it first")
    if isinstance(exc, ValueError) or "invalid url" in low or "expected" in low \
            or "unknown url" in low or "not a valid" in low:
        first = text.splitlines()[0] if text else type(exc).__name__
        return BadInput(f"port {url!r} is not a usable URL: {first}")
    first = text.splitlines()[0] if text else type(exc).__name__
    return MachineFailure(f"could not open port {url!r}: {first}")
