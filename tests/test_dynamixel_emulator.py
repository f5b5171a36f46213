"""The X-series bus emulator: exact Protocol 2.0 byte exchanges, motion in virtual time, faults."""

import pytest

from firmware_protocol import dynamixel as dx
from firmware_protocol.emulators.dynamixel import DynamixelEmulator, parse_faults
from firmware_protocol.machine import load_machine
from firmware_protocol.world import World

I = dx.Instruction
CT = dx.CONTROL_TABLE


@pytest.fixture
def machine():
    return load_machine("dynamixel-ring")


def exchange(emu, packet_id, instruction, params=b""):
    emu.receive(dx.encode_instruction(packet_id, instruction, params))
    return dx.PacketReader().feed(emu.transmit())


def read(emu, sid, name):
    f = CT[name]
    [status] = exchange(emu, sid, I.READ, dx.to_bytes(f.address, 2) + dx.to_bytes(f.size, 2))
    assert status.error & 0x7F == 0, dx.status_error_name(status.error)
    return dx.from_bytes(status.params, f.signed)


def write(emu, sid, name, value):
    f = CT[name]
    [status] = exchange(emu, sid, I.WRITE, dx.to_bytes(f.address, 2) + dx.to_bytes(value, f.size, f.signed))
    return status.error


def settle(emu):
    """Fast mode: poll Moving (as a host does) until no servo moves or the bus goes quiet."""
    for _ in range(10_000):
        states = []
        for sid in (1, 2):
            f = CT["Moving"]
            got = exchange(emu, sid, I.READ, dx.to_bytes(f.address, 2) + dx.to_bytes(1, 2))
            states.append(got[0].params[0] if got and isinstance(got[0], dx.Packet) and got[0].params else 0)
            if not got:
                return False
        if not any(states):
            return True
    raise AssertionError("motion never ended")


def test_ping_answers_with_model_and_firmware_exact_bytes(machine):
    emu = DynamixelEmulator(machine)
    emu.receive(bytes.fromhex("FF FF FD 00 01 03 00 01 19 4E"))
    reply = emu.transmit()
    # model 1020 = 0x03FC, firmware 46 = 0x2E
    body = bytes.fromhex("FF FF FD 00 01 07 00 55 00 FC 03 2E")
    assert reply == body + dx.crc16(body).to_bytes(2, "little")
    assert exchange(emu, 7, I.PING) == []            # nobody has id 7


def test_broadcast_ping_answers_both_servos(machine):
    emu = DynamixelEmulator(machine)
    got = exchange(emu, dx.BROADCAST_ID, I.PING)
    assert [(p.id, dx.from_bytes(p.params[:2])) for p in got] == [(1, 1020), (2, 1020)]


def test_read_present_position_exact_bytes(machine):
    emu = DynamixelEmulator(machine)
    emu.receive(bytes.fromhex("FF FF FD 00 02 07 00 02 84 00 04 00"))  # header and params of a read
    assert emu.transmit() == b""                                          # ... waits for its CRC
    packet = dx.encode_instruction(2, I.READ, bytes([0x84, 0, 4, 0]))
    emu.receive(packet[-2:])
    body = bytes.fromhex("FF FF FD 00 02 08 00 55 00") + dx.to_bytes(1800, 4)  # head at head_in_ticks
    assert emu.transmit() == body + dx.crc16(body).to_bytes(2, "little")


def test_bad_crc_gets_a_crc_error_status(machine):
    emu = DynamixelEmulator(machine)
    bad = bytearray(dx.encode_instruction(1, I.PING))
    bad[-1] ^= 0xFF
    emu.receive(bytes(bad))
    [status] = dx.PacketReader().feed(emu.transmit())
    assert status.error == 0x03 and dx.status_error_name(status.error) == "CRC Error"


def test_access_rules_and_ranges(machine):
    emu = DynamixelEmulator(machine)
    assert write(emu, 1, "Operating Mode", 4) == 0
    assert write(emu, 1, "Torque Enable", 1) == 0
    assert write(emu, 1, "Operating Mode", 3) == 0x07            # EEPROM with torque on: Access Error
    assert write(emu, 1, "Goal Position", 1_048_576) == 0x04     # outside the extended range
    assert write(emu, 1, "Goal Position", -1_048_575) == 0
    assert write(emu, 1, "Profile Velocity", 500) == 0x06        # above Velocity Limit: Data Limit
    [status] = exchange(emu, 1, I.WRITE, dx.to_bytes(132, 2) + b"\0\0\0\0")
    assert status.error == 0x07                                  # Present Position is read-only
    [status] = exchange(emu, 1, 0x7F)
    assert status.error == 0x02                                  # unknown instruction
    # position mode bounds Goal Position to one turn
    assert write(emu, 2, "Torque Enable", 1) == 0
    assert write(emu, 2, "Goal Position", 5000) == 0x04


def test_motion_takes_profile_time_and_moving_reads_advance_the_clock(machine):
    emu = DynamixelEmulator(machine)
    write(emu, 1, "Operating Mode", 4)
    write(emu, 1, "Profile Velocity", 100)          # 22.9 rpm: 1563 ticks/s
    write(emu, 1, "Profile Acceleration", 0)        # no ramp: exactly distance / speed
    write(emu, 1, "Torque Enable", 1)
    write(emu, 1, "Goal Position", 3 * 4096)        # 3 turns
    # fast mode: motion time passes as the host polls, not when the transport idles
    assert not emu.busy and emu.next_event_in() is None and emu.advance(None) == 0.0
    assert emu._next_internal() == pytest.approx(3 * 60 / (100 * 0.229))
    assert read(emu, 1, "Moving") == 1               # each poll lets up to 0.25 s pass
    assert emu.now == pytest.approx(0.25)
    polls = 1
    while read(emu, 1, "Moving"):
        polls += 1
    assert read(emu, 1, "Present Position") == 3 * 4096
    assert emu.now == pytest.approx(3 * 60 / (100 * 0.229))
    assert polls == 31


def test_trapezoid_takes_longer_than_cruise(machine):
    emu = DynamixelEmulator(machine)
    write(emu, 1, "Operating Mode", 4)
    write(emu, 1, "Profile Velocity", 100)
    write(emu, 1, "Profile Acceleration", 20)       # 4291 rev/min^2 = 1.19 rev/s^2
    write(emu, 1, "Torque Enable", 1)
    write(emu, 1, "Goal Position", 4096)
    v, a = 100 * 0.229 / 60, 20 * 214.577 / 3600     # rev/s, rev/s^2
    assert emu._next_internal() == pytest.approx(1 / v + v / a)


def test_extended_mode_is_multi_turn_and_reboot_rebases_to_one_turn(machine):
    emu = DynamixelEmulator(machine)
    write(emu, 1, "Operating Mode", 4)
    write(emu, 1, "Torque Enable", 1)
    write(emu, 1, "Goal Position", 5 * 4096 + 700)
    settle(emu)
    assert read(emu, 1, "Present Position") == 5 * 4096 + 700
    [status] = exchange(emu, 1, I.REBOOT)
    assert status.error == 0
    assert read(emu, 1, "Torque Enable") == 0
    assert read(emu, 1, "Present Position") == 700                # re-based to within one turn
    assert read(emu, 1, "Operating Mode") == 4                    # EEPROM survives
    write(emu, 1, "Homing Offset", 5 * 4096)                      # the host re-bases it back
    assert read(emu, 1, "Present Position") == 5 * 4096 + 700


def test_sync_write_and_sync_read_exact_exchange(machine):
    emu = DynamixelEmulator(machine)
    for sid in (1, 2):
        write(emu, sid, "Torque Enable", 1)
    params = dx.to_bytes(116, 2) + dx.to_bytes(4, 2) + bytes([1]) + dx.to_bytes(900, 4) \
        + bytes([2]) + dx.to_bytes(2300, 4)
    emu.receive(dx.encode_instruction(dx.BROADCAST_ID, I.SYNC_WRITE, params))
    assert emu.transmit() == b""                                   # sync write: no status
    settle(emu)
    emu.receive(dx.encode_instruction(dx.BROADCAST_ID, I.SYNC_READ, bytes([132, 0, 4, 0, 1, 2])))
    assert emu.transmit() == dx.encode_status(1, 0, dx.to_bytes(900, 4)) + \
        dx.encode_status(2, 0, dx.to_bytes(2300, 4))


def test_world_follows_the_shafts(machine):
    world = World(machine)
    emu = DynamixelEmulator(machine, world=world)
    write(emu, 1, "Operating Mode", 4)
    for sid in (1, 2):
        write(emu, sid, "Torque Enable", 1)
    write(emu, 1, "Goal Position", 4096)                           # one servo turn: 90 ring degrees
    settle(emu)
    write(emu, 2, "Goal Position", 2300)                           # head out
    settle(emu)
    assert (world.ring_deg, world.head_mm) == (pytest.approx(90.0), pytest.approx(12.0))


def test_power_loss_stops_motion_silences_the_bus_then_torque_off_and_rebased(machine):
    world = World(machine)
    emu = DynamixelEmulator(machine, world=world, faults="power_loss@move=1:off=2")
    write(emu, 1, "Operating Mode", 4)
    write(emu, 1, "Torque Enable", 1)
    write(emu, 1, "Profile Velocity", 100)
    write(emu, 1, "Goal Position", 8 * 4096)
    duration = emu.ring.motion.duration
    assert settle(emu) is False                                    # polled up to the fault, halfway
    assert emu.now == pytest.approx(duration / 2)
    assert world.ring_deg == pytest.approx(360.0, abs=0.1)         # 4 servo turns = 1 ring turn
    assert exchange(emu, 1, I.PING) == []                          # no power, no answer
    assert emu.busy and emu.advance(None) == pytest.approx(2.0)    # the transport idles: power back
    assert read(emu, 1, "Torque Enable") == 0
    assert read(emu, 1, "Hardware Error Status") == 0
    assert 0 <= read(emu, 1, "Present Position") < 4096
    assert read(emu, 1, "Profile Velocity") == 0                   # RAM back at defaults
    assert world.ring_deg == pytest.approx(360.0, abs=0.1)         # the ring did not move


def test_hardware_error_sets_alert_and_status_names_it(machine):
    emu = DynamixelEmulator(machine, faults="hardware_error@move=1:id=1:bits=0x20")
    write(emu, 1, "Torque Enable", 1)
    write(emu, 1, "Goal Position", 3000)
    settle(emu)
    f = CT["Hardware Error Status"]
    [status] = exchange(emu, 1, I.READ, dx.to_bytes(f.address, 2) + dx.to_bytes(1, 2))
    assert status.error == dx.ERRBIT_ALERT
    assert dx.hardware_error_names(status.params[0]) == ["Overload Error"]
    assert write(emu, 1, "Torque Enable", 1) == dx.ERRBIT_ALERT | 0x01   # Result Fail until reboot
    exchange(emu, 1, I.REBOOT)
    assert read(emu, 1, "Hardware Error Status") == 0


def test_silent_servo_and_corrupted_packet(machine):
    emu = DynamixelEmulator(machine, faults="silent@move=1:id=2, corrupt@packet=2")
    assert len(exchange(emu, 1, I.PING)) == 1
    [bad] = exchange(emu, 1, I.PING)
    assert isinstance(bad, dx.BadPacket)
    write(emu, 2, "Torque Enable", 1)
    write(emu, 2, "Goal Position", 2000)
    settle(emu)
    assert exchange(emu, 2, I.PING) == []
    assert len(exchange(emu, 1, I.PING)) == 1


def test_fault_syntax_errors_name_the_forms():
    assert [f.kind.value for f in parse_faults("power_loss@move=3, corrupt@packet=1")] == [
        "power_loss", "corrupt"]
    [a, b, c] = parse_faults("power@12, silent@3:id=2, corrupt@9")
    assert (a.kind.value, a.at, b.kind.value, b.at, b.servo_id, c.kind.value, c.at) == (
        "power_loss", 12, "silent", 3, 2, "corrupt", 9)
    with pytest.raises(ValueError, match="expected power_loss@move=N"):
        parse_faults("explode@move=1")


def test_broadcast_reboot_is_silent_and_clear_resets_the_turn_count(machine):
    emu = DynamixelEmulator(machine)
    write(emu, 1, "Operating Mode", 4)
    write(emu, 1, "Torque Enable", 1)
    write(emu, 1, "Goal Position", -3 * 4096 + 100)
    settle(emu)
    [status] = exchange(emu, 1, I.CLEAR, dx.CLEAR_MULTI_TURN)
    assert status.error == 0x01                                   # Result Fail: torque is on
    write(emu, 1, "Torque Enable", 0)
    [status] = exchange(emu, 1, I.CLEAR, dx.CLEAR_MULTI_TURN)
    assert status.error == 0 and read(emu, 1, "Present Position") == 100
    write(emu, 1, "Homing Offset", -3 * 4096)
    assert read(emu, 1, "Present Position") == -3 * 4096 + 100
    assert exchange(emu, dx.BROADCAST_ID, I.REBOOT) == []
    assert read(emu, 1, "Present Position") == -3 * 4096 + 100   # Homing Offset is EEPROM


def test_bulk_write_and_bulk_read_exact_exchange(machine):
    emu = DynamixelEmulator(machine)
    # bulk write: Torque Enable on servo 1, LED on servo 2; no status packets
    params = bytes([1]) + dx.to_bytes(64, 2) + dx.to_bytes(1, 2) + b"\x01" \
        + bytes([2]) + dx.to_bytes(65, 2) + dx.to_bytes(1, 2) + b"\x01"
    emu.receive(dx.encode_instruction(dx.BROADCAST_ID, I.BULK_WRITE, params))
    assert emu.transmit() == b""
    # bulk read: different items from each servo, answered in the order asked
    params = bytes([2]) + dx.to_bytes(65, 2) + dx.to_bytes(1, 2) + bytes([1]) + dx.to_bytes(132, 2) \
        + dx.to_bytes(4, 2)
    emu.receive(dx.encode_instruction(dx.BROADCAST_ID, I.BULK_READ, params))
    assert emu.transmit() == dx.encode_status(2, 0, b"\x01") + dx.encode_status(1, 0, dx.to_bytes(0, 4))
    assert read(emu, 1, "Torque Enable") == 1


def test_unplug_drops_the_port_while_the_powered_servos_finish_their_motion(machine):
    world = World(machine)
    emu = DynamixelEmulator(machine, world=world, faults="unplug@move=1:off=20")
    assert parse_faults("disconnect@4")[0].kind.value == "unplug"
    write(emu, 1, "Operating Mode", 4)
    write(emu, 1, "Torque Enable", 1)
    write(emu, 1, "Profile Velocity", 100)
    write(emu, 1, "Goal Position", 8 * 4096)
    duration = emu.ring.motion.duration
    assert settle(emu) is False                                    # polled up to the fault, halfway
    assert not emu.port_up and exchange(emu, 1, I.PING) == []      # the cable is out
    emu.advance(None)                                              # nobody polls: the motion goes on
    assert emu.now == pytest.approx(duration) and not emu.port_up
    assert world.ring_deg == pytest.approx(720.0, abs=0.1)         # the whole move: 8 turns = 2 ring turns
    emu.advance(None)
    assert emu.port_up and emu.now == pytest.approx(duration / 2 + 20.0)
    assert read(emu, 1, "Torque Enable") == 1                      # powered all along: nothing lost
    assert read(emu, 1, "Present Position") == 8 * 4096
