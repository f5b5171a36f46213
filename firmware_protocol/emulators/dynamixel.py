"""A bus of two Dynamixel X-series servos speaking Protocol 2.0: the ring's and the head's.

Instructions: PING (also broadcast), READ, WRITE, SYNC READ, SYNC WRITE, BULK
READ, BULK WRITE, REBOOT, CLEAR (the turn count); others get Instruction Error.

Bytes in, bytes out, a virtual clock; no I/O.  Each servo keeps the
control-table subset of :mod:`firmware_protocol.dynamixel` with its access
rules (EEPROM items only with torque off, ranges, Data Range / Access /
Data Limit errors), moves under its trapezoidal profile (Profile Velocity and
Profile Acceleration) in virtual time, and behaves like the real one where the
winding depends on it:

- Present Position is re-based to within one turn (0..ticks_per_turn-1, plus
  Homing Offset) at power-up, after REBOOT, on CLEAR (multi-turn) and when the
  Operating Mode changes; in Extended Position mode it is multi-turn otherwise.
- A power loss stops the motion where it is; the servos answer nothing until
  the power is back, then come up with torque off and RAM items at defaults.
- Status packets answer at once; motion takes virtual time.  In realtime mode
  the transport runs the clock (``advance(dt)``).  In fast mode motion time
  passes only as the host polls: a read of Moving .. Present Position while a
  servo moves first runs the clock to the next event (the end of a motion, a
  fault), at most ``POLL_QUANTUM_S`` (a fraction of a servo turn), so a polling
  host sees each motion finish quickly, in order, and has a recent position
  when a fault strikes; ``advance(None)`` then only reaches a pending power-up.

The physical shaft positions drive the world (``world.move(ring_deg, head_mm)``):
ring degrees = shaft ticks / ticks_per_turn * 360 / gear_ratio; the head maps
linearly from head_in_ticks..head_out_ticks to head.in_mm..head.out_mm.

Faults (``faults="power_loss@move=40, corrupt@packet=12"``, comma-separated;
``move=N`` is the N-th Goal Position write that starts a motion, counted from
1 over both servos (the same goal written again while the servo moves to it, as a host's retry
does, is the same move); the fault strikes halfway through that motion):

- ``power_loss@move=N[:off=S]``: servo power is cut for S virtual seconds (default 0.5).
- ``silent@move=N[:id=I]``: servo I (default: the ring's) never answers again.
- ``hardware_error@move=N[:id=I][:bits=B]``: Hardware Error Status B (default 0x20,
  Overload), torque off, the Alert bit in every status packet until REBOOT.
- ``corrupt@packet=N``: the N-th status packet sent has a flipped byte (bad CRC).
- ``unplug@move=N[:off=S]``: the adapter's USB cable is pulled: the port goes away for S
  virtual seconds (default 0.5; the pty is closed, a host's read or write fails) while
  the servos, still powered, finish their motion; then the port is back.

Short forms as for the G-code simulator: ``power@N``, ``silent@N``, ``hardware@N``, ``corrupt@N``,
``unplug@N`` (``disconnect@N`` is the same).
"""

import enum
import logging
from dataclasses import dataclass

from firmware_protocol import dynamixel as dx
from firmware_protocol.emulators.base import Emulator
from firmware_protocol.emulators.dynamixel_servo import FIRMWARE_VERSION, Power, XServo

__all__ = ["DynamixelEmulator", "XServo", "Fault", "FaultKind", "FAULT_ALIASES", "parse_faults", "Power"]

log = logging.getLogger(__name__)

POLLED = range(122, 136)         # Moving, Moving Status, Present PWM/Current/Velocity/Position
#: Fast mode: the most virtual time one poll lets pass, so that no servo turns more than a
#: fraction of a turn between two polls (as with a real host polling at any sensible rate).
POLL_QUANTUM_S = 0.25


class FaultKind(enum.Enum):
    POWER_LOSS = "power_loss"
    SILENT = "silent"
    HARDWARE_ERROR = "hardware_error"
    CORRUPT = "corrupt"
    UNPLUG = "unplug"


@dataclass
class Fault:
    kind: FaultKind
    at: int                      # move number (or packet number for CORRUPT)
    servo_id: int | None = None
    bits: int = 0x20
    off_s: float = 0.5


FAULT_ALIASES = {"power": "power_loss", "hardware": "hardware_error", "disconnect": "unplug"}


def parse_faults(spec):
    """``"power_loss@move=3:off=1, corrupt@packet=7"`` (or a list of such items) -> [Fault].

    The short forms ``power@3``, ``silent@5``, ``hardware@2``, ``corrupt@7`` (N alone: the move,
    or for ``corrupt`` the status packet) match the G-code simulator's ``kind@N``.
    """
    if not spec:
        return []
    items = spec.replace(";", ",").split(",") if isinstance(spec, str) else list(spec)
    faults = []
    for item in (i.strip() for i in items):
        if not item:
            continue
        try:
            kind_text, _, rest = item.partition("@")
            kind = FaultKind(FAULT_ALIASES.get(kind_text.strip(), kind_text.strip()))
            where = "packet" if kind is FaultKind.CORRUPT else "move"
            parts = rest.split(":")
            if parts[0].isdigit():                    # the short form kind@N
                parts[0] = f"{where}={parts[0]}"
            opts = dict(part.split("=", 1) for part in parts)
            fault = Fault(kind, int(opts.pop(where)))
            if "id" in opts:
                fault.servo_id = int(opts.pop("id"))
            if "bits" in opts:
                fault.bits = int(opts.pop("bits"), 0)
            if "off" in opts:
                fault.off_s = float(opts.pop("off"))
            if opts or fault.at < 1:
                raise ValueError
        except (ValueError, KeyError):
            raise ValueError(
                f"bad Dynamixel fault {item!r}; expected power_loss@move=N[:off=S], "
                "silent@move=N[:id=I], hardware_error@move=N[:id=I][:bits=B], unplug@move=N[:off=S] or "
                "corrupt@packet=N") from None
        faults.append(fault)
    return faults


class DynamixelEmulator(Emulator):
    """Two X-series servos on one Protocol 2.0 bus (ids and geometry from the machine file)."""

    def __init__(self, machine, *, world=None, faults=None, realtime=False, presets=()):
        super().__init__()
        self.machine = machine
        self.world = world
        self.realtime = realtime
        self._clock_driven = realtime   # True once a transport runs the clock (advance(dt))
        self.faults = parse_faults(faults)
        c = lambda key: machine[f"controller.{key}"]
        self.tpt, self.gear = c("ticks_per_turn"), c("gear_ratio")
        self.ring_id, self.head_id = c("ring_id"), c("head_id")
        self.head_in, self.head_out = c("head_in_ticks"), c("head_out_ticks")
        model = c("model_number") or 1020
        ring0 = getattr(world, "ring_deg", 0.0) if world is not None else 0.0
        head0 = getattr(world, "head_mm", machine["head.in_mm"]) if world is not None else machine["head.in_mm"]
        self.ring = XServo(self.ring_id, model=model, ticks_per_turn=self.tpt,
                           shaft=round(ring0 / 360.0 * self.gear * self.tpt))
        self.head = XServo(self.head_id, model=model, ticks_per_turn=self.tpt,
                           shaft=round(self._head_ticks(head0)))
        self.servos = {self.ring_id: self.ring, self.head_id: self.head}
        self._reader = dx.PacketReader()
        self._out = bytearray()
        self._moves = 0            # Goal Position writes that started a motion
        self._packets = 0          # status packets sent
        self._events = []          # (time, action, fault) pending fault actions
        self._last_world = self._physical()
        self.log = []              # (now, text) notable events, for tests and debugging
        for preset in presets:     # control-table items as the servos were left (--set)
            self.preset(preset)

    def preset(self, preset):
        """Start with a control-table item of ``--set`` (``ring:Drive Mode=1``), as written with
        torque off; ValueError names an unknown servo."""
        who = preset.value.who
        servo_id = {"ring": self.ring_id, "head": self.head_id}.get(who, who)
        if servo_id not in self.servos:
            raise ValueError(f"--set {preset.text!r}: no servo {who!r} on this bus; expected "
                             f"'ring', 'head', {self.ring_id} or {self.head_id}")
        self.servos[servo_id]._apply(dx.CONTROL_TABLE[preset.value.item], preset.value.value, self.now)

    # -- geometry -------------------------------------------------------------------------------
    def _head_ticks(self, mm):
        m = self.machine
        return self.head_in + (mm - m["head.in_mm"]) * (self.head_out - self.head_in) / (
            m["head.out_mm"] - m["head.in_mm"])

    def _physical(self):
        m = self.machine
        ring_deg = self.ring.shaft / self.tpt * 360.0 / self.gear
        head_mm = m["head.in_mm"] + (self.head.shaft - self.head_in) * (m["head.out_mm"] - m["head.in_mm"]) / (
            self.head_out - self.head_in)
        return ring_deg, head_mm

    def _sync_world(self):
        for servo in self.servos.values():
            servo.update(self.now)
        pos = self._physical()
        if pos != self._last_world:
            self._last_world = pos
            if self.world is not None:
                self.world.move(*pos)

    # -- Emulator interface ------------------------------------------------------------------------
    def receive(self, data):
        if not self.port_up:                    # nobody is connected: the bytes go nowhere
            return
        for packet in self._reader.feed(bytes(data)):
            self._handle(packet)

    def transmit(self):
        out, self._out = bytes(self._out), bytearray()
        return out

    @property
    def busy(self):
        return bool(self._out) or self.next_event_in() is not None

    def _moving(self):
        return any(s.motion for s in self.servos.values())

    def _next_internal(self):
        """Virtual seconds to the next motion end or fault action, or None."""
        times = [t for t, *_ in self._events] + [s.motion.end for s in self.servos.values() if s.motion]
        return max(0.0, min(times) - self.now) if times else None

    def next_event_in(self):
        """Realtime: the next motion end or fault.  Fast mode: motion (and the faults due
        during it) advance only as the host polls, so only a pending power-up counts."""
        if self._clock_driven or not self._moving() or not self.port_up:
            return self._next_internal()      # (unplugged: no host polls, the servos go on)
        return None

    def advance(self, dt=None):
        """Run the clock ``dt`` seconds (the transport drives a realtime clock: from then on
        polls no longer advance it), or (None) to the next event of :meth:`next_event_in`."""
        if dt is not None and dt > 0:
            self._clock_driven = True
        step = self.next_event_in() if dt is None else max(0.0, dt)
        return 0.0 if step is None else self._run_to(self.now + step)

    def _run_to(self, target):
        start = self.now
        while True:
            due = [e for e in self._events if e[0] <= target]
            if not due:
                break
            event = min(due, key=lambda e: e[0])
            self._events.remove(event)
            self.now = max(self.now, event[0])
            self._sync_world()
            self._fire(event[1], event[2])
        self.now = target
        self._sync_world()
        return self.now - start

    def close(self):
        close = getattr(self.world, "close", None)
        if close is not None:
            close()

    # -- faults -------------------------------------------------------------------------------------
    def _fire(self, action, fault):
        self.log.append((self.now, f"{action} {fault.kind.value}"))
        log.info("dynamixel emulator: %s at t=%.3f", action, self.now)
        if action == "power_off":
            for s in self.servos.values():
                s.power_down(self.now)
            self._events.append((self.now + fault.off_s, "power_on", fault))
        elif action == "power_on":
            for s in self.servos.values():
                s.power_up(self.now)
        elif action == "silent":
            self.servos[fault.servo_id or self.ring_id].answering = False
        elif action == "hardware_error":
            self.servos[fault.servo_id or self.ring_id].hardware_error(self.now, fault.bits)
        elif action == "unplug":
            self.port_up = False
            self._out.clear()
            self._reader = dx.PacketReader()
            self._events.append((self.now + fault.off_s, "plug", fault))
        elif action == "plug":
            self.port_up = True

    def _motion_started(self, servo):
        self._moves += 1
        for fault in self.faults:
            if fault.kind is not FaultKind.CORRUPT and fault.at == self._moves:
                when = self.now + servo.motion.duration / 2 if servo.motion else self.now
                action = "power_off" if fault.kind is FaultKind.POWER_LOSS else fault.kind.value
                self._events.append((when, action, fault))

    # -- packets ------------------------------------------------------------------------------------
    def _send(self, servo, error=0, params=b""):
        if servo.power is Power.OFF or not servo.answering or not self.port_up:
            return False
        packet = bytearray(dx.encode_status(servo.id, error | servo.error_bits, params))
        self._packets += 1
        if any(f.kind is FaultKind.CORRUPT and f.at == self._packets for f in self.faults):
            packet[-3] ^= 0x5A
            self.log.append((self.now, f"corrupt status packet {self._packets}"))
        self._out += packet
        return True

    def _poll(self, address, length):
        """Fast mode: a host polling motion state sees time pass, up to the next event."""
        if self._clock_driven or address + length <= POLLED.start or address >= POLLED.stop:
            return
        step = self._next_internal()
        if step is not None and self._moving():
            self._run_to(self.now + min(step, POLL_QUANTUM_S))

    def _handle(self, p):
        if isinstance(p, dx.BadPacket):
            servo = self.servos.get(p.id)
            if servo is not None:
                self._send(servo, 0x03)
            return
        targets = list(self.servos.values()) if p.id == dx.BROADCAST_ID else (
            [self.servos[p.id]] if p.id in self.servos else [])
        powered = [s for s in targets if s.power is Power.ON]
        ins, prm = p.instruction, p.params
        if ins == dx.Instruction.PING:
            for s in powered:
                if not self._send(s, 0, dx.to_bytes(s.get("Model Number"), 2) + bytes([FIRMWARE_VERSION])):
                    break
        elif ins == dx.Instruction.READ and p.id != dx.BROADCAST_ID:
            for s in powered:
                if len(prm) != 4:
                    self._send(s, 0x05)
                    continue
                address, length = dx.from_bytes(prm[:2]), dx.from_bytes(prm[2:])
                self._poll(address, length)
                err, data = s.read(address, length, self.now)
                self._send(s, err, data)
        elif ins == dx.Instruction.WRITE:
            for s in powered:
                self._write(s, dx.from_bytes(prm[:2]), prm[2:], reply=p.id != dx.BROADCAST_ID)
        elif ins == dx.Instruction.SYNC_READ and p.id == dx.BROADCAST_ID and len(prm) >= 4:
            address, length = dx.from_bytes(prm[:2]), dx.from_bytes(prm[2:4])
            self._poll(address, length)
            for servo_id in prm[4:]:
                s = self.servos.get(servo_id)
                if s is None or s.power is Power.OFF:
                    break
                err, data = s.read(address, length, self.now)
                if not self._send(s, err, data):
                    break
        elif ins == dx.Instruction.SYNC_WRITE and p.id == dx.BROADCAST_ID and len(prm) >= 4:
            address, length = dx.from_bytes(prm[:2]), dx.from_bytes(prm[2:4])
            body = prm[4:]
            for i in range(0, len(body) - length, length + 1):
                s = self.servos.get(body[i])
                if s is not None and s.power is Power.ON:
                    self._write(s, address, body[i + 1:i + 1 + length], reply=False)
        elif ins == dx.Instruction.BULK_READ and p.id == dx.BROADCAST_ID:
            for i in range(0, len(prm) - 4, 5):        # [id, address, length] per servo
                s = self.servos.get(prm[i])
                address, length = dx.from_bytes(prm[i + 1:i + 3]), dx.from_bytes(prm[i + 3:i + 5])
                if s is None or s.power is Power.OFF:
                    break
                self._poll(address, length)
                err, data = s.read(address, length, self.now)
                if not self._send(s, err, data):
                    break
        elif ins == dx.Instruction.BULK_WRITE and p.id == dx.BROADCAST_ID:
            i = 0
            while i + 5 <= len(prm):                   # [id, address, length, data] per servo
                s = self.servos.get(prm[i])
                address, length = dx.from_bytes(prm[i + 1:i + 3]), dx.from_bytes(prm[i + 3:i + 5])
                if s is not None and s.power is Power.ON:
                    self._write(s, address, prm[i + 5:i + 5 + length], reply=False)
                i += 5 + length
        elif ins == dx.Instruction.REBOOT:
            for s in powered:                       # a broadcast REBOOT gets no status packet
                if p.id == dx.BROADCAST_ID or self._send(s):
                    s.power_up(self.now)
                    self.log.append((self.now, f"reboot {s.id}"))
        elif ins == dx.Instruction.CLEAR:
            for s in powered:
                self._send(s, s.clear_multi_turn(self.now) if prm == dx.CLEAR_MULTI_TURN else 0x04)
        else:
            for s in powered:
                if p.id != dx.BROADCAST_ID:
                    self._send(s, 0x02)

    def _write(self, servo, address, data, *, reply):
        before = servo.motion
        self._sync_world()
        err = servo.write(address, data, self.now)
        if reply:
            self._send(servo, err)
        if servo.motion is not None and servo.motion is not before and (before is None
                                                                        or servo.motion.goal != before.goal):
            self._motion_started(servo)     # the same goal written again (a host's retry) is the same move
