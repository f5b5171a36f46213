"""Servo operations on a Protocol 2.0 bus through the official ``dynamixel_sdk``, errors by name.

:class:`ServoBus` wraps the SDK's ``PortHandler`` and ``Protocol2PacketHandler``
(with ``GroupSyncWrite`` / ``GroupSyncRead`` where one packet does the work of
two): ping, control-table reads and writes by item name, reboot, clearing the
turn count, sync-written goals and one sync-read poll of Torque Enable ..
Present Position.  A failed exchange (``COMM_RX_TIMEOUT``, ``COMM_RX_CORRUPT``,
...) is retried, each retry waiting longer for the answer (:data:`RETRY_GRACE_MS`: a
servo, a USB adapter or a simulator on a loaded computer may answer late, and a
retry that waits no longer than the first attempt would miss it the same way), then becomes one line naming the servo, the operation and
the ``COMM_*`` result; a status packet's error field and the Hardware Error
Status are reported by name.  The link above (:mod:`.dynamixel`) gives the
bus a ``fail(message) -> Exception`` that adds the step and the pin.
"""

import logging

import dynamixel_sdk as sdk
import serial

from firmware_protocol import dynamixel as dx

from .ports import open_port

__all__ = ["ServoBus", "comm_name", "POLL_START", "POLL_LENGTH", "poll_field"]

log = logging.getLogger(__name__)

CT = dx.CONTROL_TABLE
#: One sync read per poll covers Torque Enable (64) .. Present Position (132..135).
POLL_START = CT["Torque Enable"].address
POLL_LENGTH = CT["Present Position"].address + 4 - POLL_START
#: Extra milliseconds each attempt waits for an answer beyond the SDK's own packet timeout
#: (about 35 ms): the first attempt none, then more (worst case 0.75 s more before a failure).
RETRY_GRACE_MS = (0.0, 50.0, 200.0, 500.0)
#: After an exchange that needed retries: how long to wait for late answers before dropping them.
LATE_ANSWER_S = 0.05
_COMM = {getattr(sdk, name): name for name in dir(sdk) if name.startswith("COMM_")}
_HINTS = {sdk.COMM_RX_TIMEOUT: "it does not answer: check its power, cable, id and baud rate",
          sdk.COMM_RX_CORRUPT: "its answers arrive corrupted: check the cable and termination",
          sdk.COMM_PORT_BUSY: "the port is busy"}


try:                                    # POSIX only: stringbot.links loads on Windows too
    from termios import error as _TermiosError
except ImportError:                     # pragma: no cover - Windows
    _TermiosError = OSError
#: What the SDK's port raises when the adapter or its cable is gone (pyserial, the OS, termios).
PORT_ERRORS = (serial.SerialException, OSError, _TermiosError)


def _first_line(exc):
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text


def comm_name(result):
    """``-3001`` -> ``'COMM_RX_TIMEOUT'``."""
    return _COMM.get(result, f"COMM result {result}")


def poll_field(data, name):
    """The value of control-table item ``name`` in one servo's poll data."""
    f = CT[name]
    start = f.address - POLL_START
    return dx.from_bytes(data[start:start + f.size], f.signed)


class _PatientPortHandler(sdk.PortHandler):
    """The SDK's port handler; its packet timeouts are longer by ``grace_ms`` (set per attempt)."""

    grace_ms = 0.0

    def setPacketTimeout(self, packet_length):
        super().setPacketTimeout(packet_length)
        self.packet_timeout += self.grace_ms

    def setPacketTimeoutMillis(self, msec):
        super().setPacketTimeoutMillis(msec + self.grace_ms)


class _UrlPortHandler(_PatientPortHandler):
    """The SDK's port handler, opening URLs (``sim://``, ``socket://``) through :func:`open_port`."""

    def setupPort(self, cflag_baud):
        if self.is_open:
            self.closePort()
        self.ser = open_port(self.port_name, baudrate=self.baudrate, timeout=0)
        self.is_open = True
        self.ser.reset_input_buffer()
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True


class ServoBus:
    """The servos on one port.

    Parameters
    ----------
    url : str
        A serial device (opened by the SDK's own ``PortHandler``) or a pyserial URL.
    roles : dict
        servo id -> role ("ring", "head"), for messages.
    fail : callable(str) -> Exception
        Builds the exception to raise (the link adds step and pin).
    retries : int
        Extra attempts after a failed exchange.
    """

    def __init__(self, url, roles, fail, *, protocol=2.0, retries=3):
        self.url, self.roles, self.fail, self.retries = url, dict(roles), fail, retries
        self.port = (_UrlPortHandler if "://" in url else _PatientPortHandler)(url)
        self.ph = sdk.PacketHandler(protocol)
        self.polls = 0          # sync reads sent
        self.packets = 0        # other instruction packets sent
        self.retried = 0        # exchanges repeated after a COMM_* failure
        self.lost = None        # why the port is gone (a pulled cable): every exchange then fails at once

    def name(self, servo_id):
        return f"{self.roles.get(servo_id, 'unknown')} servo (id {servo_id})"

    # ---- port -------------------------------------------------------------------------------
    def open(self, baud):
        """Open the port; False when the SDK does not know ``baud``.  Port errors propagate."""
        self.lost = None
        if not self.port.openPort():
            return False
        if not self.port.setBaudRate(baud):
            self.port.closePort()
            return False
        return True

    def drop_input(self, settle_s=0.0):
        """Forget an interrupted exchange: the port is free again and stale bytes are dropped."""
        import time
        if settle_s:
            time.sleep(settle_s)
        self.port.is_using = False
        if self.port.ser is not None and self.lost is None:
            self._call(None, "clearing the input", self.port.clearPort)

    def close(self):
        if self.port.ser is not None and self.port.is_open:
            self.port.closePort()

    # ---- exchanges ----------------------------------------------------------------------------
    def _call(self, servo_id, what, call, *args, attempt=0):
        """One SDK call, waiting longer for its answer on a retry (:data:`RETRY_GRACE_MS`); the
        port raising (a pulled cable, a dead adapter) becomes one failure naming the operation,
        and every later exchange fails at once with the same reason."""
        if self.lost is not None:
            raise self.fail(self.lost)
        self._grace(attempt)
        try:
            return call(*args)
        except PORT_ERRORS as exc:
            who = f"the {self.name(servo_id)}, " if servo_id is not None else ""
            self.lost = (f"lost the port {self.url} at {who}{what} ({_first_line(exc)}): check the servo "
                         "adapter, its USB cable and the servos' power")
            log.debug("port error", exc_info=True)
            raise self.fail(self.lost) from None
        finally:
            self.port.grace_ms = 0.0

    def _retry(self, servo_id, what, call, *args, expect=None):
        """Run an SDK call whose result is ``out[-2]``; retry COMM failures; return its output.

        ``expect``: the number of data bytes ``out[0]`` must hold (a read); an answer of
        another length is a late answer to an earlier request, and is retried.
        """
        for attempt in range(self.retries + 1):
            self.port.is_using = False        # an interrupted exchange must not leave the port "busy"
            try:
                out = self._call(servo_id, what, call, *args, attempt=attempt)
                result = out[-2] if isinstance(out, tuple) else out
            except IndexError:                    # the SDK parsing a short (late) answer as this one's
                self.port.is_using = False
                out, result = None, sdk.COMM_RX_CORRUPT
            self.packets += 1
            if result == sdk.COMM_SUCCESS and expect is not None and len(out[0]) != expect:
                result = sdk.COMM_RX_CORRUPT      # an answer of another length: not this request's
            if result == sdk.COMM_SUCCESS:
                if attempt:
                    self._drop_late_answers()
                return out
            self.retried += 1
            # a first ping may go unanswered while a port settles, a first answer may come late
            # (the retry waits longer): not worth a warning
            log.log(logging.INFO if what == "ping" or attempt == 0 else logging.WARNING, "%s: %s %s (attempt %d of %d)",
                    self.name(servo_id), what, comm_name(result), attempt + 1, self.retries + 1)
        raise self.comm_failure(servo_id, what, result)

    def _drop_late_answers(self):
        """After an exchange that needed retries, the answers to the attempts that timed out
        may still arrive: wait for them and drop them, so the next request does not take one
        of them for its own answer (Protocol 2.0 status packets carry no sequence number)."""
        import time
        time.sleep(LATE_ANSWER_S)
        self.port.is_using = False
        if self.port.ser is not None:
            self.port.clearPort()

    def _grace(self, attempt):
        self.port.grace_ms = RETRY_GRACE_MS[min(attempt, len(RETRY_GRACE_MS) - 1)]

    def comm_failure(self, servo_id, what, result):
        hint = _HINTS.get(result, self.ph.getTxRxResult(result))
        return self.fail(f"{self.name(servo_id)} failed {what}: {comm_name(result)} "
                         f"after {self.retries + 1} attempts; {hint}")

    def _checked(self, servo_id, what, error, *, alert_ok=False):
        if error & 0x7F:
            raise self.fail(f"{self.name(servo_id)} refused {what}: {dx.status_error_name(error & 0x7F)}")
        if error & dx.ERRBIT_ALERT and not alert_ok:
            raise self.hardware_failure(servo_id)

    def hardware_failure(self, servo_id, bits=None):
        if bits is None:
            try:
                bits = self.read(servo_id, "Hardware Error Status")
            except Exception:  # the bus may be gone; the Alert bit is reason enough
                bits = 0
        names = ", ".join(dx.hardware_error_names(bits)) or "Alert bit set"
        return self.fail(f"{self.name(servo_id)} reports a hardware error: {names}; torque is off "
                         "until the servo is rebooted (power cycle, or resume which reboots it)")

    def ping(self, servo_id):
        """-> model number."""
        model, _, error = self._retry(servo_id, "ping", self.ph.ping, self.port, servo_id)
        self._checked(servo_id, "ping", error, alert_ok=True)
        return model

    def read(self, servo_id, name, *, alert_ok=False):
        """Read item ``name``; the Alert bit (a hardware error) fails it unless ``alert_ok``."""
        f = CT[name]
        what = f"reading {name}"
        data, _, error = self._retry(servo_id, what, self.ph.readTxRx, self.port, servo_id, f.address, f.size,
                                     expect=f.size)
        self._checked(servo_id, what, error, alert_ok=alert_ok or name == "Hardware Error Status")
        value = int.from_bytes(bytes(data), "little")
        if f.signed and value >= 1 << (8 * f.size - 1):
            value -= 1 << (8 * f.size)
        return value

    def write(self, servo_id, name, value):
        f = CT[name]
        call = {1: self.ph.write1ByteTxRx, 2: self.ph.write2ByteTxRx, 4: self.ph.write4ByteTxRx}[f.size]
        what = f"writing {name} = {value}"
        raw = value & ((1 << (8 * f.size)) - 1)
        _, error = self._retry(servo_id, what, call, self.port, servo_id, f.address, raw)
        self._checked(servo_id, what, error)

    def reboot(self, servo_id):
        _, error = self._retry(servo_id, "reboot", self.ph.reboot, self.port, servo_id)
        self._checked(servo_id, "reboot", error, alert_ok=True)

    def clear_multi_turn(self, servo_id):
        what = "clearing the turn count"
        _, error = self._retry(servo_id, what, self.ph.clearMultiTurn, self.port, servo_id)
        self._checked(servo_id, what, error)

    def write_goals(self, goals):
        """Goal Position for each ``{id: ticks}``: one confirmed write, or one sync write (no status)."""
        if len(goals) == 1:
            [(servo_id, goal)] = goals.items()
            self.write(servo_id, "Goal Position", goal)
            return
        group = sdk.GroupSyncWrite(self.port, self.ph, CT["Goal Position"].address, 4)
        for servo_id, goal in goals.items():
            group.addParam(servo_id, list(dx.to_bytes(goal, 4, signed=True)))
        first = next(iter(goals))
        self._retry(first, "sync-writing Goal Position", lambda: (group.txPacket(), 0))

    def poll(self, ids):
        """Torque Enable .. Present Position of ``ids``: ``{id: bytes}`` (one read, or one sync read)."""
        if len(ids) == 1:
            [servo_id] = ids
            what = "polling its position"
            data, _, error = self._retry(servo_id, what, self.ph.readTxRx, self.port, servo_id,
                                         POLL_START, POLL_LENGTH, expect=POLL_LENGTH)
            self.packets -= 1
            self.polls += 1
            self._checked(servo_id, what, error, alert_ok=True)   # the caller reads the error status
            return {servo_id: bytes(data)}
        group = sdk.GroupSyncRead(self.port, self.ph, POLL_START, POLL_LENGTH)
        for servo_id in ids:
            group.addParam(servo_id)
        for attempt in range(self.retries + 1):
            self.port.is_using = False
            result = self._call(ids[0], "polling the positions", group.txRxPacket, attempt=attempt)
            self.polls += 1
            if result == sdk.COMM_SUCCESS and all(len(group.data_dict[i]) == POLL_LENGTH for i in ids):
                if attempt:
                    self._drop_late_answers()
                return {servo_id: bytes(group.data_dict[servo_id]) for servo_id in ids}
            if result == sdk.COMM_SUCCESS:
                result = sdk.COMM_RX_CORRUPT
            self.retried += 1
            culprit = next((i for i in ids if not group.data_dict.get(i)), ids[0])
            log.log(logging.INFO if attempt == 0 else logging.WARNING,
                    "%s: polling %s (attempt %d of %d)", self.name(culprit), comm_name(result),
                        attempt + 1, self.retries + 1)
            for servo_id in ids:
                group.data_dict[servo_id] = []
        raise self.comm_failure(culprit, "polling its position", result)
