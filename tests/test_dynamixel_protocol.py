"""Protocol 2.0 codec: the packet examples of the ROBOTIS e-Manual, byte for byte."""

import pytest

from firmware_protocol import dynamixel as dx

# (instruction packet, its status packet) from the e-Manual's Protocol 2.0 examples
PING_1 = bytes.fromhex("FF FF FD 00 01 03 00 01 19 4E")
PING_1_STATUS = bytes.fromhex("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D")   # model 1030, fw 38
READ_132_4 = bytes.fromhex("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")
READ_132_4_STATUS = bytes.fromhex("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0")  # 166
WRITE_116_512 = bytes.fromhex("FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89")
WRITE_STATUS = bytes.fromhex("FF FF FD 00 01 04 00 55 00 A1 0C")


def test_crc_table_is_the_spec_table():
    t = dx.CRC_TABLE
    assert (t[0], t[1], t[2], t[3], t[4]) == (0x0000, 0x8005, 0x800F, 0x000A, 0x801B)
    assert (t[128], t[254], t[255]) == (0x8303, 0x8207, 0x0202)


@pytest.mark.parametrize("packet", [PING_1, PING_1_STATUS, READ_132_4, READ_132_4_STATUS,
                                    WRITE_116_512, WRITE_STATUS])
def test_crc_of_the_manual_examples(packet):
    assert dx.crc16(packet[:-2]) == int.from_bytes(packet[-2:], "little")


def test_encoders_reproduce_the_manual_examples():
    assert dx.encode_instruction(1, dx.Instruction.PING) == PING_1
    assert dx.encode_status(1, 0, bytes([0x06, 0x04, 0x26])) == PING_1_STATUS
    assert dx.encode_instruction(1, dx.Instruction.READ, bytes([0x84, 0, 4, 0])) == READ_132_4
    assert dx.encode_status(1, 0, dx.to_bytes(166, 4)) == READ_132_4_STATUS
    goal = dx.CONTROL_TABLE["Goal Position"]
    params = dx.to_bytes(goal.address, 2) + dx.to_bytes(512, 4, signed=True)
    assert dx.encode_instruction(1, dx.Instruction.WRITE, params) == WRITE_116_512
    assert dx.encode_status(1) == WRITE_STATUS


def test_byte_stuffing_inserts_and_removes_fd():
    body = bytes([0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x00])
    assert dx.stuff(body) == bytes([0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x00])
    assert dx.unstuff(dx.stuff(body)) == body
    packet = dx.encode_instruction(1, dx.Instruction.WRITE, body[1:])
    # LEN counts the stuffed byte; the CRC covers the stuffed packet
    assert packet[5:7] == bytes([0x0A, 0x00])
    assert packet[7:15] == bytes([0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x00])
    assert dx.crc16(packet[:-2]) == int.from_bytes(packet[-2:], "little")
    [decoded] = dx.PacketReader().feed(packet)
    assert decoded == dx.Packet(1, dx.Instruction.WRITE, body[1:])


def test_stuffing_agrees_with_the_sdk():
    from dynamixel_sdk import Protocol2PacketHandler
    ph = Protocol2PacketHandler()
    params = [0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x01, 0xFF, 0xFF, 0xFD]
    sdk = [0xFF, 0xFF, 0xFD, 0x00, 0x05, len(params) + 3, 0, 0x03] + params + [0, 0]
    sdk = ph.addStuffing(sdk)
    ours = dx.encode_instruction(5, dx.Instruction.WRITE, bytes(params))
    assert bytes(sdk[:-2]) == ours[:-2]


def test_reader_splits_resyncs_and_flags_bad_crc():
    reader = dx.PacketReader()
    stream = b"\x00\x13" + PING_1_STATUS + READ_132_4_STATUS
    got = []
    for i in range(0, len(stream), 3):          # arrives in pieces
        got += reader.feed(stream[i:i + 3])
    assert got == [dx.Packet(1, 0x55, bytes([0x06, 0x04, 0x26]), 0),
                   dx.Packet(1, 0x55, dx.to_bytes(166, 4), 0)]
    broken = bytearray(READ_132_4_STATUS)
    broken[9] ^= 0x01
    assert reader.feed(bytes(broken) + WRITE_STATUS) == [
        dx.BadPacket(1, "CRC mismatch"), dx.Packet(1, 0x55, b"", 0)]


def test_error_and_hardware_error_names():
    assert dx.status_error_name(0x07) == "Access Error"
    assert dx.status_error_name(0x80) == "Alert (hardware error)"
    assert dx.status_error_name(0x84) == "Data Range Error + Alert (hardware error)"
    assert dx.hardware_error_names(0x20) == ["Overload Error"]
    assert dx.hardware_error_names(0x05) == ["Input Voltage Error", "Overheating Error"]
    assert dx.hardware_error_names(0) == []


def test_control_table_addresses_of_the_x_series():
    ct = dx.CONTROL_TABLE
    expect = {"Model Number": (0, 2), "Operating Mode": (11, 1), "Homing Offset": (20, 4),
              "Torque Enable": (64, 1), "Hardware Error Status": (70, 1),
              "Profile Acceleration": (108, 4), "Profile Velocity": (112, 4),
              "Goal Position": (116, 4), "Moving": (122, 1), "Present Position": (132, 4)}
    assert {k: (ct[k].address, ct[k].size) for k in expect} == expect
    assert dx.MODELS[1020] == "XM430-W350"
    assert (dx.EXTENDED_POSITION_MIN, dx.EXTENDED_POSITION_MAX) == (-1_048_575, 1_048_575)


def test_signed_values_round_trip():
    assert dx.to_bytes(-1, 4, signed=True) == b"\xFF\xFF\xFF\xFF"
    assert dx.from_bytes(b"\x01\x00\xF0\xFF", signed=True) == -1048575
