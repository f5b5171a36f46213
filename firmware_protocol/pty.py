"""Serve any emulator on a pseudo-terminal, behind a stable symlink.

Programs that open serial ports by path (stringbot itself, bCNC, UGS, a
terminal, the Dynamixel SDK) open ``path``; it is a symlink to the slave side
of a pty whose master side this server reads and writes.  Bytes from the
host go to :meth:`Emulator.receive`; the emulator's output is written back.

Time: in realtime mode the emulator's clock follows the wall clock; in fast
mode it jumps to the next event whenever the host has nothing for it and
nothing is waiting to be read (as fast as possible, in order).

One simulator per path: while a server runs it holds an exclusive ``flock`` on
``path + ".lock"`` (holding its process id), so a second server on the same path
is refused (:class:`PtyPathError`) instead of taking the path over and leaving
the first one running and unreachable.  The lock dies with its process (even a
killed one): a path left by a dead simulator is taken over, its leftovers replaced.

When the emulator reports its port down (a ``disconnect`` or ``power``
fault), the server closes the pty and removes ``path``: the host sees its port
fail and the path vanish, as with a pulled USB cable (a path left pointing at
the closed pty would name whatever pty the system opens next under its
number).  Once the emulator's port is back, and not before
``reopen_delay`` seconds, a new pty is opened and ``path`` re-pointed to it
(atomically), so the host can reopen the same path.

The operator's hands: a spool change shows on no axis, so beside the pty, at
``path + ".operator"``, the server listens on a Unix datagram socket for what
the operator did (:func:`tell_operator`): ``{"tie_on": "#rrggbb", "pin": N}``
ties a thread on in the emulator's world, whose record then gives every later
wrap that colour (as ``sim://``'s ``tie_on`` does in-process).  Messages are
read before the pty's bytes, so a tie-on sent before the next line applies to it.
"""

import errno
import json
import logging
import os
import select
import socket
import stat
import time

__all__ = ["PtyServer", "PtyPathError", "check_pty_path", "tell_operator", "OPERATOR_SUFFIX", "LOCK_SUFFIX"]

#: The operator's socket lives at the pty's path plus this.
OPERATOR_SUFFIX = ".operator"
#: The running server's lock file (its pid inside) lives at the pty's path plus this.
LOCK_SUFFIX = ".lock"

log = logging.getLogger(__name__)

# where os.ttyname puts a pty's slave side (Linux; macOS)
_PTY_PREFIXES = ("/dev/pts/", "/dev/ttys")


class PtyPathError(ValueError):
    """``path`` exists and is not a symlink to a pseudo-terminal: it is never replaced."""


def check_pty_path(path):
    """Raise :class:`PtyPathError` unless ``path`` is absent or a (live or dangling) symlink to a pty
    that no running simulator holds."""
    pid = holder(path)
    if pid is not None:
        raise PtyPathError(_held(path, pid))
    _check_kind(path)


def holder(path):
    """The process id of the running simulator that holds ``path`` (-1 when it cannot be read), or None."""
    import fcntl

    try:
        fd = os.open(os.fspath(path) + LOCK_SUFFIX, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                return None
            try:
                return int(os.read(fd, 32).decode().strip() or -1)
            except ValueError:
                return -1
        return None                     # nobody holds it: a leftover of a simulator that died
    finally:
        os.close(fd)


def _held(path, pid):
    who = f" (process {pid})" if pid > 0 else ""
    stop = f"stop that one first (Ctrl-C in its terminal, or kill {pid})" if pid > 0 else "stop that one first"
    return f"{os.fspath(path)!r} is in use by a running simulator{who}; expected another path, or {stop}"


def _check_kind(path):
    if not os.path.lexists(path):
        return
    if os.path.islink(path) and os.readlink(path).startswith(_PTY_PREFIXES):
        return
    kind = "a folder" if os.path.isdir(path) else "a symlink elsewhere" if os.path.islink(path) else "a file"
    raise PtyPathError(f"{path!r} exists and is {kind}, not a symlink to a pseudo-terminal; "
                       "expected a new path (it is never replaced)")


def tell_operator(path, message):
    """Send ``message`` (a dict) to the operator socket of the simulator whose pty is at ``path``.

    Returns False (nothing sent) when there is no such socket: a real port, or a simulator gone.
    """
    sock_path = os.fspath(path) + OPERATOR_SUFFIX
    if not hasattr(socket, "AF_UNIX"):  # Windows: no simulator on a pty there
        return False
    try:
        if not stat.S_ISSOCK(os.stat(sock_path).st_mode):
            return False
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as s:
            s.sendto(json.dumps(message).encode(), sock_path)
        return True
    except OSError:
        return False


class PtyServer:
    """One emulator on one pty at ``path``.

    Parameters
    ----------
    emulator : firmware_protocol.emulators.base.Emulator
    path : str or path-like
        Where the symlink to the pty lives.  It must not exist, or be a symlink to a pty (a
        leftover of an earlier server, dangling or not); anything else raises :class:`PtyPathError`
        and is left untouched.
    realtime : bool
        Run the emulator's clock at wall-clock speed (default: as fast as possible).
    reopen_delay : float
        Wall-clock seconds the port stays gone after a fault before it comes back.
    """

    def __init__(self, emulator, path, *, realtime=False, reopen_delay=0.3):
        self.emulator = emulator
        self.path = os.fspath(path)
        self.realtime = realtime
        self.reopen_delay = reopen_delay
        self.master = None
        self.slave_name = None
        self._poll = None
        self._client_since = None
        self.generation = 0            # how many ptys have been opened
        self._pending = bytearray()
        self._down_since = None
        self._wall = time.monotonic()
        self._operator = None           # the operator's datagram socket (see the module's notes)
        self._lock = None               # fd of the held lock file (see the module's notes)

    # ---- the pty ----------------------------------------------------------------------------
    def start(self):
        """Open the first pty and point ``path`` at it; returns ``self``.

        Raises
        ------
        PtyPathError
            If ``path`` exists and is not a symlink to a pty, or a running simulator holds it
            (nothing is opened or changed).
        """
        _check_kind(self.path)
        self._take_lock()               # before anything at the path is touched
        try:
            self._open_operator()       # before the pty's path appears: whoever waits for it finds both
            self._open()
        except BaseException:
            self._drop_lock()
            raise
        return self

    def _take_lock(self):
        """Hold ``path + LOCK_SUFFIX`` exclusively for the server's life, or raise PtyPathError."""
        import fcntl

        lock = self.path + LOCK_SUFFIX
        while True:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise PtyPathError(_held(self.path, holder(self.path) or -1)) from None
                raise
            try:                        # the file its last holder removed on its way out: lock anew
                same = os.path.samestat(os.fstat(fd), os.stat(lock))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._lock = fd

    def _drop_lock(self):
        if self._lock is None:
            return
        try:
            os.unlink(self.path + LOCK_SUFFIX)   # while still held: nobody locks a file on its way out
        except OSError:
            pass
        os.close(self._lock)
        self._lock = None

    def _open_operator(self):
        if getattr(self.emulator, "world", None) is None:
            return
        sock_path = self.path + OPERATOR_SUFFIX
        try:
            if stat.S_ISSOCK(os.lstat(sock_path).st_mode):
                os.unlink(sock_path)        # a leftover of an earlier server
        except FileNotFoundError:
            pass
        s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        try:
            s.bind(sock_path)
        except OSError as exc:              # e.g. a file there: the simulator runs without it
            log.warning("no operator socket at %s: %s", sock_path, exc)
            s.close()
            return
        s.setblocking(False)
        self._operator = s

    def _hear_operator(self):
        """Apply what the operator did (messages waiting on the operator socket)."""
        while self._operator is not None:
            try:
                data = self._operator.recv(4096)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            try:
                msg = json.loads(data)
                if "tie_on" in msg:
                    self.emulator.world.tie_on(str(msg["tie_on"]), msg.get("pin"))
                    log.info("operator: tied %s on at pin %s", msg["tie_on"], msg.get("pin"))
            except (ValueError, TypeError, AttributeError) as exc:
                log.warning("operator socket: ignored %r (%s)", data[:80], exc)

    def _open(self):
        import tty

        _check_kind(self.path)      # also on a reopen: a file put there meanwhile is not clobbered
        master, slave = os.openpty()
        tty.setraw(slave)
        name = os.ttyname(slave)
        os.close(slave)                 # the host's open is then visible (no POLLHUP on the master)
        os.set_blocking(master, False)
        self.master, self.slave_name = master, name
        self._poll = select.poll()
        self._poll.register(master, select.POLLIN | select.POLLHUP | select.POLLERR)
        self._client_since = None
        tmp = f"{self.path}.{os.getpid()}.tmp"
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        os.symlink(name, tmp)
        os.replace(tmp, self.path)
        self.generation += 1
        log.info("pty %s -> %s", self.path, name)

    def _close_pty(self):
        if self.master is not None:
            try:
                os.close(self.master)
            except OSError:
                pass
        self.master = None
        self._pending.clear()

    def _unlink_path(self):
        """Remove ``path`` if it still points at this server's pty.  Left in place, it would name a
        closed pty whose number the system hands to the next pty opened: a host opening ``path``
        then would talk to some other program."""
        try:
            if os.path.islink(self.path) and os.readlink(self.path) == self.slave_name:
                os.unlink(self.path)
        except OSError:
            pass

    def close(self):
        """Close the pty, remove the symlink (if it is still ours) and let the emulator write its
        records."""
        self._close_pty()
        if self._operator is not None:
            self._operator.close()
            self._operator = None
            try:
                os.unlink(self.path + OPERATOR_SUFFIX)
            except OSError:
                pass
        self.emulator.close()
        self._unlink_path()
        self._drop_lock()               # last: the path is free once its leftovers are gone

    # ---- the loop ---------------------------------------------------------------------------
    def serve(self, stop=None, *, poll=0.02):
        """Move bytes and time until ``stop`` (a threading.Event) is set, or forever."""
        while stop is None or not stop.is_set():
            self.step(poll)

    def step(self, timeout=0.02):
        """One round: sync the clock, handle the port, move bytes, maybe advance time."""
        emu = self.emulator
        self._sync_clock()
        if self.master is None:
            self._while_down(timeout)
            return
        if not emu.port_up:
            log.info("port dropped: closing %s", self.slave_name)
            emu.idle()
            self._close_pty()
            self._unlink_path()         # a pulled USB cable: the device node goes with it
            self._down_since = time.monotonic()
            return
        self._flush_out()
        fast_busy = not self.realtime and emu.busy and not self._pending
        wait = 0.0 if fast_busy else timeout
        if wait:
            emu.idle()              # about to wait for the host: the record catches up if at rest
        if self.realtime:
            nxt = emu.next_event_in()
            if nxt is not None:
                wait = min(wait, max(nxt, 0.001))
        self._hear_operator()
        events = self._poll.poll(wait * 1000.0)
        self._hear_operator()               # sent before the bytes that woke us: applies to them
        flags = events[0][1] if events else 0
        if flags & select.POLLHUP:
            self._client_since = None       # nobody has the port open: hold the output
            if not events or wait:
                time.sleep(0 if fast_busy else min(timeout, 0.01))
        elif self._client_since is None:
            self._client_since = time.monotonic()
            if emu.port_opened():           # an Uno resets on DTR: what it said before is gone
                self._pending.clear()
        if flags & select.POLLIN and not flags & select.POLLHUP:
            try:
                data = os.read(self.master, 4096)
            except (BlockingIOError, OSError):
                data = b""
            if data:
                self._sync_clock()
                emu.receive(data)
                self._flush_out()
                return
        if not self.realtime and emu.busy and not self._pending:
            emu.advance(None)
        self._flush_out()

    def _while_down(self, timeout):
        emu = self.emulator
        if not emu.port_up:
            if self.realtime:
                time.sleep(timeout)
                return
            emu.advance(None)
            if emu.port_up:
                self._down_since = self._down_since or time.monotonic()
            return
        if time.monotonic() - (self._down_since or 0.0) < self.reopen_delay:
            time.sleep(min(timeout, self.reopen_delay))
            return
        self._open()
        self._down_since = None

    def _sync_clock(self):
        now = time.monotonic()
        if self.realtime and now > self._wall:
            self.emulator.advance(now - self._wall)
        self._wall = now

    def _flush_out(self):
        if self.master is None:
            return
        self._pending += self.emulator.transmit()
        # hold output until a host has had the port open a moment (pyserial flushes input on open)
        if self._client_since is None or time.monotonic() - self._client_since < 0.05:
            return
        while self._pending:
            try:
                n = os.write(self.master, self._pending)
            except BlockingIOError:
                return
            except OSError as exc:
                if exc.errno == errno.EIO:
                    return
                raise
            del self._pending[:n]
