"""Dynamixel Protocol 2.0 (X series): constants, the control-table subset and the packet codec.

Written from the ROBOTIS e-Manual (Protocol 2.0 and the XM430-W350 control
table).  The emulator builds and parses packets with these; the host talks to
real and simulated servos through the official ``dynamixel_sdk`` and uses this
module only for names (addresses, error bits, models).

Packet layout (all multi-byte fields little-endian)::

    FF FF FD 00 | ID | LEN_L LEN_H | INSTR | PARAMS ... | CRC_L CRC_H

``LEN`` counts INSTR, the (stuffed) parameters and the two CRC bytes.  A status
packet has INSTR 0x55 and an ERROR byte before its parameters.  Wherever
``FF FF FD`` would appear from INSTR on, a ``FD`` is inserted after it (byte
stuffing); the CRC-16 (polynomial 0x8005, initial value 0, no reflection) is
computed over the stuffed packet from the first header byte to the last
parameter byte.
"""

from dataclasses import dataclass

__all__ = [
    "HEADER", "BROADCAST_ID", "MAX_ID", "Instruction", "ERROR_NAMES", "ERRBIT_ALERT",
    "HARDWARE_ERRORS", "hardware_error_names", "status_error_name", "Field", "CONTROL_TABLE",
    "FIELD_AT", "OperatingMode", "EXTENDED_POSITION_MIN", "EXTENDED_POSITION_MAX", "MODELS",
    "CLEAR_MULTI_TURN", "crc16", "CRC_TABLE", "stuff", "unstuff", "encode_instruction",
    "encode_status", "Packet", "BadPacket", "PacketReader", "to_bytes", "from_bytes",
]

HEADER = b"\xFF\xFF\xFD\x00"
BROADCAST_ID = 0xFE
MAX_ID = 0xFC


class Instruction:
    """Instruction codes (the INSTR byte)."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    BULK_READ = 0x92
    BULK_WRITE = 0x93


#: The ERROR byte of a status packet: bit 7 is the Alert (see Hardware Error
#: Status), bits 0-6 carry one error number.
ERRBIT_ALERT = 0x80
ERROR_NAMES = {
    0x01: "Result Fail",
    0x02: "Instruction Error",
    0x03: "CRC Error",
    0x04: "Data Range Error",
    0x05: "Data Length Error",
    0x06: "Data Limit Error",
    0x07: "Access Error",
}

#: Hardware Error Status (70): bit -> name.
HARDWARE_ERRORS = {
    0: "Input Voltage Error",
    2: "Overheating Error",
    3: "Motor Encoder Error",
    4: "Electrical Shock Error",
    5: "Overload Error",
}

#: CLEAR instruction parameters that reset the multi-turn count (Present Position within one turn).
CLEAR_MULTI_TURN = b"\x01\x44\x58\x4C\x22"


def hardware_error_names(bits):
    """Names of the bits set in a Hardware Error Status byte, e.g. ``['Overload Error']``."""
    names = [name for bit, name in HARDWARE_ERRORS.items() if bits & (1 << bit)]
    unknown = bits & ~sum(1 << b for b in HARDWARE_ERRORS) & 0xFF
    if unknown:
        names.append(f"unknown bits 0x{unknown:02X}")
    return names


def status_error_name(error):
    """Describe a status packet's ERROR byte, e.g. ``'Access Error'`` or ``'Alert'``."""
    parts = []
    number = error & 0x7F
    if number:
        parts.append(ERROR_NAMES.get(number, f"error 0x{number:02X}"))
    if error & ERRBIT_ALERT:
        parts.append("Alert (hardware error)")
    return " + ".join(parts)


@dataclass(frozen=True)
class Field:
    """One control-table item: address, size in bytes, access, memory area, sign, range."""

    name: str
    address: int
    size: int
    writable: bool = False
    eeprom: bool = False
    signed: bool = False
    lo: int | None = None
    hi: int | None = None


def _fields(*rows):
    return {row[0]: Field(*row) for row in rows}


#: The X-series control-table subset the emulator keeps and the host uses (XM430-W350 layout).
CONTROL_TABLE = _fields(
    ("Model Number", 0, 2),
    ("Model Information", 2, 4),
    ("Firmware Version", 6, 1),
    ("ID", 7, 1, True, True, False, 0, 252),
    ("Baud Rate", 8, 1, True, True, False, 0, 7),
    ("Return Delay Time", 9, 1, True, True, False, 0, 254),
    ("Drive Mode", 10, 1, True, True, False, 0, 13),
    ("Operating Mode", 11, 1, True, True, False, 0, 16),
    ("Protocol Type", 13, 1, True, True, False, 1, 2),
    ("Homing Offset", 20, 4, True, True, True, -1_044_479, 1_044_479),
    ("Moving Threshold", 24, 4, True, True, False, 0, 1023),
    ("Temperature Limit", 31, 1, True, True, False, 0, 100),
    ("Velocity Limit", 44, 4, True, True, False, 0, 1023),
    ("Max Position Limit", 48, 4, True, True, False, 0, 4095),
    ("Min Position Limit", 52, 4, True, True, False, 0, 4095),
    ("Shutdown", 63, 1, True, True, False, 0, 255),
    ("Torque Enable", 64, 1, True, False, False, 0, 1),
    ("LED", 65, 1, True, False, False, 0, 1),
    ("Status Return Level", 68, 1, True, False, False, 0, 2),
    ("Registered Instruction", 69, 1),
    ("Hardware Error Status", 70, 1),
    ("Profile Acceleration", 108, 4, True, False, False, 0, 32767),
    ("Profile Velocity", 112, 4, True, False, False, 0, 32767),
    ("Goal Position", 116, 4, True, False, True, -1_048_575, 1_048_575),
    ("Realtime Tick", 120, 2),
    ("Moving", 122, 1),
    ("Moving Status", 123, 1),
    ("Present Velocity", 128, 4, False, False, True),
    ("Present Position", 132, 4, False, False, True),
    ("Present Input Voltage", 144, 2),
    ("Present Temperature", 146, 1),
)
#: address -> Field
FIELD_AT = {f.address: f for f in CONTROL_TABLE.values()}
#: Size of the control table the emulator keeps (through Present Temperature).
TABLE_SIZE = 147


class OperatingMode:
    """Operating Mode (11) values."""

    CURRENT = 0
    VELOCITY = 1
    POSITION = 3
    EXTENDED_POSITION = 4
    CURRENT_BASED_POSITION = 5
    PWM = 16


#: Goal Position range in Extended Position Control Mode (+-256 turns).
EXTENDED_POSITION_MIN = -1_048_575
EXTENDED_POSITION_MAX = 1_048_575

#: Model numbers (Ping, Model Number (0)) of some X-series servos.
MODELS = {
    1000: "XH430-W210",
    1010: "XH430-W350",
    1020: "XM430-W350",
    1030: "XM430-W210",
    1060: "XL430-W250",
    1090: "2XL430-W250",
    1120: "XM540-W270",
    1130: "XM540-W150",
    1190: "XL330-M077",
    1200: "XL330-M288",
}


def _make_crc_table(poly=0x8005):
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ poly) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


#: The spec's CRC-16 lookup table (generated from the polynomial).
CRC_TABLE = _make_crc_table()


def crc16(data, crc=0):
    """CRC-16 of Protocol 2.0 (poly 0x8005, MSB first, init 0) over ``data``."""
    for b in data:
        crc = ((crc << 8) ^ CRC_TABLE[((crc >> 8) ^ b) & 0xFF]) & 0xFFFF
    return crc


def stuff(body):
    """Insert ``FD`` after every ``FF FF FD`` in ``body`` (instruction and parameters)."""
    out = bytearray()
    for b in body:
        out.append(b)
        if b == 0xFD and out[-3:-1] == b"\xFF\xFF" and len(out) >= 3:
            out.append(0xFD)
    return bytes(out)


def unstuff(body):
    """Remove the ``FD`` that :func:`stuff` inserted after every ``FF FF FD``."""
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if body[i] == 0xFD and out[-3:-1] == b"\xFF\xFF" and len(out) >= 3 \
                and i + 1 < len(body) and body[i + 1] == 0xFD:
            i += 1
        i += 1
    return bytes(out)


def _frame(packet_id, body):
    body = stuff(body)
    head = HEADER + bytes([packet_id]) + (len(body) + 2).to_bytes(2, "little")
    packet = head + body
    return packet + crc16(packet).to_bytes(2, "little")


def encode_instruction(packet_id, instruction, params=b""):
    """An instruction packet, stuffed, with its CRC."""
    return _frame(packet_id, bytes([instruction]) + bytes(params))


def encode_status(packet_id, error=0, params=b""):
    """A status packet (INSTR 0x55) with ``error`` and ``params``, stuffed, with its CRC."""
    return _frame(packet_id, bytes([Instruction.STATUS, error]) + bytes(params))


def to_bytes(value, size, signed=False):
    """Little-endian bytes of ``value`` (two's complement when ``signed``)."""
    return int(value).to_bytes(size, "little", signed=signed)


def from_bytes(data, signed=False):
    """The integer in little-endian ``data``."""
    return int.from_bytes(bytes(data), "little", signed=signed)


@dataclass(frozen=True)
class Packet:
    """A decoded packet: ``params`` are unstuffed; ``error`` only for status packets."""

    id: int
    instruction: int
    params: bytes
    error: int | None = None


@dataclass(frozen=True)
class BadPacket:
    """A framed packet whose CRC does not match (``id`` as received)."""

    id: int
    reason: str


class PacketReader:
    """Incremental decoder: :meth:`feed` bytes, get complete packets (and bad ones) back.

    Bytes before a header are skipped; a frame with a wrong CRC is returned as
    :class:`BadPacket` and dropped; an absurd length drops the header byte and
    resynchronises.
    """

    MAX_LENGTH = 1024

    def __init__(self):
        self._buf = bytearray()

    def feed(self, data):
        self._buf += data
        out = []
        while True:
            start = self._buf.find(b"\xFF\xFF\xFD")
            if start < 0:
                keep = 2 if self._buf.endswith(b"\xFF\xFF") else 1 if self._buf.endswith(b"\xFF") else 0
                del self._buf[:len(self._buf) - keep]
                return out
            del self._buf[:start]
            if len(self._buf) < 7:
                return out
            if self._buf[3] != 0x00:          # FF FF FD FD is stuffing, not a header
                del self._buf[:3]
                continue
            length = from_bytes(self._buf[5:7])
            if length < 3 or length > self.MAX_LENGTH:
                del self._buf[:1]
                continue
            total = 7 + length
            if len(self._buf) < total:
                return out
            frame = bytes(self._buf[:total])
            del self._buf[:total]
            out.append(self._decode(frame))

    @staticmethod
    def _decode(frame):
        packet_id = frame[4]
        if crc16(frame[:-2]) != from_bytes(frame[-2:]):
            return BadPacket(packet_id, "CRC mismatch")
        body = unstuff(frame[7:-2])
        instruction = body[0]
        if instruction == Instruction.STATUS:
            if len(body) < 2:
                return BadPacket(packet_id, "status packet without an error byte")
            return Packet(packet_id, instruction, body[2:], body[1])
        return Packet(packet_id, instruction, body[1:])
