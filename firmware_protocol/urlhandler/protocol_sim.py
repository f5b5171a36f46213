"""``sim://``: a pyserial port onto a simulated machine in this process.

URL form::

    sim://[?machine=NAME|PATH][&record=FILE][&realtime=0|1][&faults=kind@N,...][&set=SETTING]...

``machine`` is a bundled machine name or a machine file (default
``grbl-ring``); ``record`` the world's JSON record; ``realtime=1`` runs the
firmware's clock at wall-clock speed (default: as fast as possible, in
order); ``faults`` as in :mod:`firmware_protocol.faults`; ``set`` (any
number of times) a firmware setting the machine starts with instead of the
machine file's (``set=$100=40``, ``set=M92+A40``, ``set=ring:Drive+Mode=1``;
:func:`firmware_protocol.settings.parse_preset`), to practise on a mis-set
machine.

Writes go straight to the emulator.  A read that finds nothing ready runs the
virtual clock to the next event (fast mode) or sleeps (realtime mode) until
bytes come or the port's timeout passes; an idle emulator still makes the
read wait its timeout in real time, as a quiet serial port does.

A ``disconnect`` or ``power`` fault drops the port like a pulled USB cable:
reads and writes raise :class:`serial.SerialException` until the host closes
the port and opens the same URL again.  For that the simulated machine (its
emulator and world) is kept per URL for the life of the process;
:func:`forget` drops it (tests that want a fresh machine use a fresh URL,
e.g. a fresh ``record`` file).
"""

import atexit
import logging
import threading
import time
import urllib.parse

import serial
from serial.serialutil import PortNotOpenError, SerialBase, SerialException, Timeout

__all__ = ["Serial", "FORM", "parse_url", "session", "forget", "tie_on"]

log = logging.getLogger(__name__)

FORM = ('expected a string in the form '
        '"sim://[?machine=NAME][&record=FILE][&realtime=0|1][&faults=kind@N,...][&set=SETTING]..."')

_SESSIONS = {}
_LOCK = threading.Lock()


class _Session:
    """One simulated machine: emulator, world, clock mode, and the wall time last synced."""

    def __init__(self, emulator, world, realtime):
        self.emulator, self.world, self.realtime = emulator, world, realtime
        self.wall = time.monotonic()
        self.lock = threading.RLock()

    def close(self):
        with self.lock:
            try:
                self.emulator.close()
            except OSError as exc:          # a record folder removed meanwhile: nothing to keep
                log.warning("sim: could not write the record: %s", exc)

    def sync(self):
        """Realtime mode: bring the virtual clock up to the wall clock."""
        now = time.monotonic()
        if self.realtime and now > self.wall:
            self.emulator.advance(now - self.wall)
        self.wall = now

    def bring_port_up(self):
        """Run the clock (virtual, or real in realtime mode) until the port is back."""
        emu = self.emulator
        while not emu.port_up:
            dt = emu.next_event_in()
            if dt is None:
                raise SerialException("simulated port is down and not coming back")
            if self.realtime:
                time.sleep(dt)
                self.sync()
            else:
                emu.advance(dt)


def parse_url(url):
    """``sim://?...`` -> dict of options; raises SerialException naming the bad part."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != "sim":
        raise SerialException(f"{FORM}: not starting with sim:// ({parts.scheme!r})")
    if parts.netloc or parts.path not in ("", "/"):
        raise SerialException(f"{FORM}: unexpected {parts.netloc + parts.path!r} before the '?'")
    opts = {"machine": "grbl-ring", "record": None, "realtime": False, "faults": "", "set": []}
    try:
        # a '+' is a plus (reset@230+0.4, a file name), never a space: write a space as %20
        query = urllib.parse.parse_qs(parts.query.replace("+", "%2B"), keep_blank_values=True,
                                      strict_parsing=bool(parts.query))
    except ValueError as exc:
        raise SerialException(f"{FORM}: {exc}") from None
    for option, values in query.items():
        if option == "set":
            if not all(values):
                raise SerialException(f"{FORM}: set is empty")
            opts["set"] = list(values)
            continue
        if len(values) != 1:
            raise SerialException(f"{FORM}: option {option!r} given {len(values)} times")
        value = values[0]
        if option == "machine":
            if not value:
                raise SerialException(f"{FORM}: machine is empty")
            opts["machine"] = value
        elif option == "record":
            if not value:
                raise SerialException(f"{FORM}: record is empty")
            opts["record"] = value
        elif option == "realtime":
            if value not in ("0", "1"):
                raise SerialException(f"{FORM}: realtime={value!r}; expected 0 or 1")
            opts["realtime"] = value == "1"
        elif option == "faults":
            opts["faults"] = value
        else:
            raise SerialException(f"{FORM}: unknown option {option!r}")
    return opts


def session(url):
    """The simulated machine behind ``url``, built on first use and kept for the process."""
    with _LOCK:
        s = _SESSIONS.get(url)
        if s is not None:
            return s
        opts = parse_url(url)
        from ..emulators.factory import SimulatorError, build_emulator
        from ..faults import parse_faults
        from ..kinds import kind_of
        from ..machine import MachineFileError, load_machine
        try:
            machine = load_machine(opts["machine"])
            if kind_of(machine).faults == "gcode":      # a servo bus checks its own
                parse_faults(opts["faults"])
            emulator, world = build_emulator(machine, record=opts["record"], faults=opts["faults"] or None,
                                             settings=opts["set"])
        except ValueError as exc:        # MachineFileError, SimulatorError, bad faults
            kind = "machine" if isinstance(exc, (MachineFileError, SimulatorError)) else "faults"
            if str(exc).startswith("--set "):
                kind, exc = "set", str(exc)[len("--set "):]
            raise SerialException(f"{FORM}: {kind}: {exc}") from None
        except OSError as exc:
            raise SerialException(f"{FORM}: record: {exc}") from None
        s = _Session(emulator, world, opts["realtime"])
        if not _SESSIONS:
            atexit.register(_close_all)
        _SESSIONS[url] = s
        log.info("sim: new %s machine for %s", machine.name, url)
        return s


def tie_on(url, color, pin=None):
    """The simulated operator ties a thread of ``color`` on the machine behind ``url`` (a spool change).

    No axis shows a spool change, so the operator's hands are simulated here:
    the world's later wraps carry ``color`` (:meth:`firmware_protocol.world.World.tie_on`).
    """
    s = session(url)
    with s.lock:
        s.world.tie_on(color, pin)


def look(url):
    """What the simulated operator sees of the machine behind ``url``: the world's physical
    ``(ring_deg, head_mm)`` (a dry run's operator answers where the head stands from it)."""
    s = session(url)
    with s.lock:
        return (float(s.world.ring_deg), float(s.world.head_mm))


def forget(url=None):
    """Drop the simulated machine of ``url`` (all of them if None); its record is written first."""
    with _LOCK:
        gone = list(_SESSIONS.values()) if url is None else [s for s in [_SESSIONS.get(url)] if s]
        if url is None:
            _SESSIONS.clear()
        else:
            _SESSIONS.pop(url, None)
    for s in gone:
        s.close()


def _close_all():
    """At exit: every simulated machine writes its record (the simulator exits with the process)."""
    with _LOCK:
        sessions = list(_SESSIONS.values())
    for s in sessions:
        s.close()


class Serial(SerialBase):
    """A serial port onto the simulated machine named by a ``sim://`` URL."""

    BAUDRATES = (9600, 19200, 38400, 57600, 115200, 230400, 250000, 500000, 1000000, 2000000,
                 3000000, 4000000)

    def __init__(self, *args, **kwargs):
        self._session = None
        self._in = bytearray()
        self._dropped = False
        super().__init__(*args, **kwargs)

    # ---- open / close --------------------------------------------------------------------
    def open(self):
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        self._session = session(self._port)
        with self._session.lock:
            self._session.sync()
            self._session.bring_port_up()
            self._session.emulator.port_opened()    # an Uno resets on DTR (reset_on_open)
        self._in.clear()
        self._dropped = False
        self.is_open = True

    def close(self):
        self.is_open = False
        self._in.clear()
        if self._session is not None:
            with self._session.lock:
                try:
                    self._session.world.flush()      # the record is current once the port is closed
                except OSError as exc:
                    log.warning("sim: could not write the record: %s", exc)
        self._session = None

    def from_url(self, url):
        """Check ``url`` (pyserial calls this style of method on its own handlers)."""
        return parse_url(url)

    def _reconfigure_port(self):
        """Baud rate and framing do not matter to the simulator."""

    # ---- the wire ----------------------------------------------------------------------------
    def _check(self):
        if not self.is_open:
            raise PortNotOpenError()
        if self._dropped:
            raise SerialException("device disconnected (simulated: the USB cable is out or power is "
                                  "off); close and reopen the port")

    def _pull(self):
        """Take the emulator's output; notice a dropped port."""
        emu = self._session.emulator
        self._in += emu.transmit()
        if not emu.port_up:
            self._dropped = True
            self._in.clear()
            raise SerialException("device disconnected (simulated: the USB cable is out or power is "
                                  "off); close and reopen the port")

    @property
    def in_waiting(self):
        self._check()
        s = self._session
        with s.lock:
            s.sync()
            self._pull()
            if not self._in and not s.realtime and s.emulator.busy:
                s.emulator.advance(None)     # fast mode: a polling host still sees time pass
                self._pull()
        return len(self._in)

    def read(self, size=1):
        self._check()
        s = self._session
        timeout = Timeout(self._timeout)
        out = bytearray()
        while len(out) < size:
            with s.lock:
                s.sync()
                self._pull()
                take = self._in[:size - len(out)]
                del self._in[:len(take)]
                out += take
                if len(out) >= size:
                    break
                nxt = s.emulator.next_event_in()
                if not s.realtime and nxt is not None and s.emulator.busy:
                    s.emulator.advance(None)
                    continue
            if self._timeout == 0 or timeout.expired():
                break
            with s.lock:
                s.emulator.idle()           # waiting in wall time: the record catches up if at rest
            wait = 0.005 if nxt is None else min(max(nxt, 0.0005), 0.02)
            left = timeout.time_left()
            time.sleep(wait if left is None else max(min(wait, left), 0.0))
        return bytes(out)

    def write(self, data):
        self._check()
        data = serial.to_bytes(data)
        s = self._session
        with s.lock:
            s.sync()
            s.emulator.receive(data)
            self._pull()
        return len(data)

    def flush(self):
        self._check()

    def reset_input_buffer(self):
        self._check()
        with self._session.lock:
            self._pull()
        self._in.clear()

    def reset_output_buffer(self):
        self._check()

    def cancel_read(self):
        """Nothing blocks for long enough to need cancelling."""

    def cancel_write(self):
        """Writes never block."""

    def _update_break_state(self):
        pass

    def _update_rts_state(self):
        pass

    def _update_dtr_state(self):
        pass

    @property
    def out_waiting(self):
        return 0

    @property
    def cts(self):
        self._check()
        return True

    @property
    def dsr(self):
        self._check()
        return True

    @property
    def ri(self):
        self._check()
        return False

    @property
    def cd(self):
        self._check()
        return True

    def fileno(self):
        raise SerialException("a sim:// port has no file descriptor; serve the simulator on a pty "
                              "(stringbot simulate --pty PATH) for programs that need one")
