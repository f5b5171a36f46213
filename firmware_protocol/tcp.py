"""Serve a serial port (the simulator's ``sim://`` port, or any pyserial port) on TCP.

Like a network-attached controller (FluidNC's telnet server, grblHAL's, a
serial-to-Ethernet box), :class:`TcpBridge` accepts one client at a time and
moves bytes both ways between it and the port.  With ``rfc2217=True`` it speaks
RFC 2217 through pyserial's own :class:`serial.rfc2217.PortManager` (the
``rfc2217://`` URL), as ``ser2net`` or pyserial's ``rfc2217_server.py`` do.

``nodelay`` sets TCP_NODELAY on the accepted socket (the default, as
network firmware does); ``nodelay=False`` lets Nagle's algorithm hold small
answers back, which is how a plain ``socat`` bridge behaves.
"""

import logging
import select
import socket
import threading

__all__ = ["TcpBridge"]

log = logging.getLogger(__name__)


class TcpBridge:
    """A TCP server in a daemon thread, bridging each client to ``port``.

    Parameters
    ----------
    port : an open pyserial port (``read``, ``write``, ``in_waiting``)
    host : str
    tcp_port : int
        0 picks a free port; see :attr:`address`.
    rfc2217 : bool
        Speak RFC 2217 (telnet with COM-port control) instead of raw bytes.
    nodelay : bool
        TCP_NODELAY on the client socket.
    """

    def __init__(self, port, *, host="127.0.0.1", tcp_port=0, rfc2217=False, nodelay=True):
        self.port = port
        self.rfc2217 = rfc2217
        self.nodelay = nodelay
        self.server = socket.create_server((host, tcp_port))
        self.address = self.server.getsockname()[:2]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="tcp-bridge", daemon=True)
        self.clients = 0
        #: seconds to wait for the client when the port had nothing to say (give the port a short
        #: read timeout, e.g. 0: a sim:// read then runs its clock and returns at once)
        self.idle_wait = 0.001

    @property
    def url(self):
        """The URL a host opens: ``socket://host:port`` or ``rfc2217://host:port``."""
        scheme = "rfc2217" if self.rfc2217 else "socket"
        return f"{scheme}://{self.address[0]}:{self.address[1]}"

    def start(self):
        self._thread.start()
        return self

    def close(self):
        self._stop.set()
        try:
            self.server.close()
        except OSError:
            pass
        self._thread.join(timeout=2.0)

    def _serve(self):
        while not self._stop.is_set():
            ready, _, _ = select.select([self.server], [], [], 0.1)
            if not ready:
                continue
            try:
                conn, _addr = self.server.accept()
            except OSError:
                return
            self.clients += 1
            if self.nodelay:
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            try:
                self._bridge(conn)
            except OSError as exc:
                log.info("client gone: %s", exc)
            finally:
                conn.close()

    def _bridge(self, conn):
        manager = None
        if self.rfc2217:
            import serial.rfc2217

            class _Writer:                       # PortManager writes telnet answers through this
                def write(self, data):
                    conn.sendall(data)
            manager = serial.rfc2217.PortManager(self.port, _Writer())
        conn.setblocking(False)
        idle = 0.0
        while not self._stop.is_set():
            ready, _, _ = select.select([conn], [], [], idle)
            idle = self.idle_wait
            if ready:
                try:
                    data = conn.recv(4096)
                except BlockingIOError:
                    data = b""
                if ready and not data:
                    return                       # the client closed
                if manager is not None:
                    data = b"".join(manager.filter(data))
                if data:
                    self.port.write(data)
                continue
            # nothing from the client: let the port answer (a sim:// read runs its clock)
            n = self.port.in_waiting
            out = self.port.read(n if n else 1)
            if out:
                idle = 0.0
                if manager is not None:
                    out = b"".join(manager.escape(out))
                conn.setblocking(True)
                conn.sendall(out)
                conn.setblocking(False)
            elif manager is not None:
                manager.check_modem_lines()
