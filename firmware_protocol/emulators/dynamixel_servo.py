"""One emulated Dynamixel X-series servo: control table, shaft, profile motion, power.

The bus (:mod:`firmware_protocol.emulators.dynamixel`) owns the servos, the
clock and the faults; a servo owns its control table (the subset of
:mod:`firmware_protocol.dynamixel` with its access rules), its shaft (the
physical multi-turn position, which only motion changes) and the base that
makes Present Position read within one turn after a power-up, a reboot, a
CLEAR or a change of Operating Mode or Drive Mode.  Drive Mode's Reverse Mode
(bit 0) counts positions the other way round the shaft, and its Time-based
Profile (bit 2) reads Profile Velocity and Acceleration as milliseconds.
"""

import enum
import math

from firmware_protocol import dynamixel as dx

__all__ = ["XServo", "Profile", "Power", "RPM_PER_UNIT", "REV_PER_MIN2_PER_UNIT", "FIRMWARE_VERSION",
           "DRIVE_REVERSE", "DRIVE_TIME_BASED"]

RPM_PER_UNIT = 0.229            # Profile Velocity / Velocity Limit unit
REV_PER_MIN2_PER_UNIT = 214.577  # Profile Acceleration unit
VELOCITY_LIMIT_DEFAULT = 128     # XM430-W350 factory Velocity Limit (44)
DRIVE_REVERSE = 0x01             # Drive Mode (10) bit 0: Reverse Mode
DRIVE_TIME_BASED = 0x04          # Drive Mode (10) bit 2: Time-based Profile
FIRMWARE_VERSION = 46


class Power(enum.Enum):
    ON = "on"
    OFF = "off"


class Profile:
    """A trapezoidal (or triangular) move of the shaft, in ticks and seconds."""

    def __init__(self, start, goal, t0, vmax, amax):
        self.start, self.goal, self.t0 = float(start), float(goal), t0
        dist = abs(self.goal - self.start)
        self.sign = 1.0 if self.goal >= self.start else -1.0
        if math.isinf(amax):
            self.ta, self.v = 0.0, vmax
            self.duration = dist / vmax if dist else 0.0
            self.a = math.inf
            return
        self.a = amax
        ta = vmax / amax
        if amax * ta * ta >= dist:           # triangular: never reaches vmax
            ta = math.sqrt(dist / amax)
            vmax = amax * ta
        self.ta, self.v = ta, vmax
        self.duration = 2 * ta + (dist - amax * ta * ta) / vmax if dist else 0.0

    @property
    def end(self):
        return self.t0 + self.duration

    def at(self, now):
        """(position, velocity) at virtual time ``now``."""
        t = min(max(now - self.t0, 0.0), self.duration)
        if t >= self.duration:
            return self.goal, 0.0
        if self.ta == 0.0:
            return self.start + self.sign * self.v * t, self.sign * self.v
        cruise = self.duration - 2 * self.ta
        if t < self.ta:
            d, v = 0.5 * self.a * t * t, self.a * t
        elif t < self.ta + cruise:
            d, v = 0.5 * self.a * self.ta ** 2 + self.v * (t - self.ta), self.v
        else:
            r = self.duration - t
            d = abs(self.goal - self.start) - 0.5 * self.a * r * r
            v = self.a * r
        return self.start + self.sign * d, self.sign * v


class XServo:
    """One X-series servo: control table, shaft, profile motion, power."""

    RAM_DEFAULTS = {"Torque Enable": 0, "LED": 0, "Status Return Level": 2,
                    "Profile Acceleration": 0, "Profile Velocity": 0}

    def __init__(self, servo_id, *, model, ticks_per_turn, shaft=0, mode=dx.OperatingMode.POSITION):
        self.ticks_per_turn = ticks_per_turn
        self.table = bytearray(dx.TABLE_SIZE)
        self.shaft = float(shaft)      # physical position, ticks; moves only by motion
        self.base = 0                  # reported = shaft - base + homing offset
        self.motion = None
        self.power = Power.ON
        self.answering = True
        for name, value in {"Model Number": model, "Firmware Version": FIRMWARE_VERSION,
                            "ID": servo_id, "Baud Rate": 1, "Return Delay Time": 250,
                            "Operating Mode": mode, "Protocol Type": 2, "Moving Threshold": 10,
                            "Temperature Limit": 80, "Velocity Limit": VELOCITY_LIMIT_DEFAULT,
                            "Max Position Limit": ticks_per_turn - 1, "Shutdown": 0x34,
                            "Present Input Voltage": 120, "Present Temperature": 30}.items():
            self.set(name, value)
        self.power_up(0.0)

    # -- control table ----------------------------------------------------------------------
    def get(self, name):
        f = dx.CONTROL_TABLE[name]
        return dx.from_bytes(self.table[f.address:f.address + f.size], f.signed)

    def set(self, name, value):
        f = dx.CONTROL_TABLE[name]
        self.table[f.address:f.address + f.size] = dx.to_bytes(value, f.size, f.signed)

    @property
    def id(self):
        return self.get("ID")

    @property
    def direction(self):
        """-1 in Reverse Mode (Drive Mode bit 0): positions count the other way round the shaft."""
        return -1 if self.get("Drive Mode") & DRIVE_REVERSE else 1

    @property
    def counted(self):
        """The shaft as the servo counts it (reversed in Reverse Mode), in whole ticks."""
        return round(self.direction * self.shaft)

    @property
    def present(self):
        return self.counted - self.base + self.get("Homing Offset")

    def _rebase(self):
        """Present Position := the shaft's angle within one turn (+ Homing Offset)."""
        self.base = self.counted - self.counted % self.ticks_per_turn
        self.set("Goal Position", self.present)

    # -- time ---------------------------------------------------------------------------------
    def update(self, now):
        if self.motion is None:
            return
        self.shaft, _ = self.motion.at(now)
        if now >= self.motion.end:
            self.motion = None

    def stop(self, now):
        self.update(now)
        self.motion = None

    def _limits(self, distance):
        """(vmax, amax) of a move of ``distance`` ticks under the profile.

        Velocity-based (the default): Profile Velocity and Acceleration in 0.229 rpm and
        214.577 rev/min^2 units.  Time-based (Drive Mode bit 2): Profile Velocity is the
        move's time and Profile Acceleration its ramp time, in ms.
        """
        limit = (self.get("Velocity Limit") or 1023) * RPM_PER_UNIT / 60.0 * self.ticks_per_turn
        if self.get("Drive Mode") & DRIVE_TIME_BASED and self.get("Profile Velocity"):
            total = self.get("Profile Velocity") / 1000.0
            ramp = min(self.get("Profile Acceleration") / 1000.0, total / 2)
            vmax = min(abs(distance) / (total - ramp), limit) if distance else limit
            return vmax, (vmax / ramp if ramp else math.inf)
        vel = self.get("Profile Velocity") or self.get("Velocity Limit") or 1023
        vmax = vel * RPM_PER_UNIT / 60.0 * self.ticks_per_turn
        acc = self.get("Profile Acceleration")
        amax = acc * REV_PER_MIN2_PER_UNIT / 3600.0 * self.ticks_per_turn if acc else math.inf
        return vmax, amax

    # -- power ----------------------------------------------------------------------------------
    def power_down(self, now):
        self.stop(now)
        self.power = Power.OFF

    def power_up(self, now):
        """Power-on or reboot: RAM items at defaults, torque off, position within one turn."""
        self.stop(now)
        self.power = Power.ON
        for name, value in self.RAM_DEFAULTS.items():
            self.set(name, value)
        self.set("Hardware Error Status", 0)
        self._rebase()

    def hardware_error(self, now, bits):
        self.stop(now)
        self.set("Hardware Error Status", bits)
        self.set("Torque Enable", 0)

    @property
    def error_bits(self):
        return dx.ERRBIT_ALERT if self.get("Hardware Error Status") else 0

    # -- instructions ---------------------------------------------------------------------------
    def read(self, address, length, now):
        """-> (error number, data)"""
        if address + length > len(self.table) or length < 1:
            return 0x07, b""
        self.update(now)
        self.set("Present Position", self.present)
        velocity = self.motion.at(now)[1] if self.motion else 0.0
        self.set("Present Velocity", round(velocity * 60.0 / self.ticks_per_turn / RPM_PER_UNIT))
        self.set("Moving", 1 if self.motion else 0)
        self.set("Moving Status", 0x02 if self.motion else 0x01)
        self.set("Realtime Tick", int(now * 1000) % 32768)
        return 0, bytes(self.table[address:address + length])

    def write(self, address, data, now):
        """-> error number (0 = done).  All items are checked before any is written."""
        changes, i = [], 0
        while i < len(data):
            f = dx.FIELD_AT.get(address + i)
            if f is None or not f.writable:
                return 0x07
            if i + f.size > len(data):
                return 0x05
            value = dx.from_bytes(data[i:i + f.size], f.signed)
            if f.eeprom and self.get("Torque Enable"):
                return 0x07
            lo, hi = f.lo, f.hi
            if f.name == "Goal Position" and self._mode_after(changes) == dx.OperatingMode.POSITION:
                lo, hi = self.get("Min Position Limit"), self.get("Max Position Limit")
            if not lo <= value <= hi:
                return 0x04
            if f.name == "Operating Mode" and value not in (0, 1, 3, 4, 5, 16):
                return 0x04
            if f.name == "Profile Velocity" and value > self.get("Velocity Limit") \
                    and not self.get("Drive Mode") & DRIVE_TIME_BASED:     # time-based: milliseconds
                return 0x06
            if f.name == "Torque Enable" and value and self.get("Hardware Error Status"):
                return 0x01
            changes.append((f, value))
            i += f.size
        for f, value in changes:
            self._apply(f, value, now)
        return 0

    def _mode_after(self, changes):
        modes = [v for f, v in changes if f.name == "Operating Mode"]
        return modes[-1] if modes else self.get("Operating Mode")

    def _apply(self, f, value, now):
        old = self.get(f.name)
        self.set(f.name, value)
        if f.name in ("Operating Mode", "Drive Mode") and value != old:
            self._rebase()
        elif f.name == "Torque Enable":
            if value and not old:
                if self.get("Operating Mode") == dx.OperatingMode.POSITION:
                    self._rebase()
                self.set("Goal Position", self.present)
            elif not value:
                self.stop(now)
        elif f.name == "Homing Offset":
            self.set("Goal Position", self.present)
        elif f.name == "Goal Position" and self.get("Torque Enable"):
            self.stop(now)
            target = self.direction * (value - self.get("Homing Offset") + self.base)
            vmax, amax = self._limits(target - self.shaft)
            if target != round(self.shaft):
                self.motion = Profile(self.shaft, target, now, vmax, amax)

    def clear_multi_turn(self, now):
        if self.motion is not None or self.get("Torque Enable"):
            return 0x01
        self._rebase()
        return 0
