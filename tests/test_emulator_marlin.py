"""The simulated Marlin 2.1: line numbers, checksums, Resend, busy, M400, as exchange tables."""

import pytest

from firmware_protocol import marlin as mc
from firmware_protocol.emulators.marlin import MarlinEmulator
from firmware_protocol.emulators.testing import run_exchange
from firmware_protocol.machine import load_machine
from firmware_protocol.world import World

pytestmark = pytest.mark.timeout(30)

OK = b"ok\n"


def N(n, command):
    return mc.numbered(n, command).encode() + b"\n"


def emulator(faults=None):
    m = load_machine("marlin-ring")
    emu = MarlinEmulator(m, world=World(m), faults=faults)
    banner = emu.transmit()
    assert banner.startswith(b"start\necho:Marlin 2.1.2.1\n")
    return emu


def test_checksum_is_the_xor_of_every_byte_before_the_star():
    assert mc.checksum("N1 G0 X1") == 0x4E ^ 0x31 ^ 0x20 ^ 0x47 ^ 0x30 ^ 0x20 ^ 0x58 ^ 0x31
    assert mc.numbered(0, "M110 N0") == "N0 M110 N0*125"
    assert mc.parse_numbered("N0 M110 N0*125") == (0, "M110 N0", True)
    assert mc.parse_resend("Resend: 7") == 7 and mc.parse_resend("ok") is None
    assert mc.parse_position("X:1.00 Y:2.50 Z:0.00 A:3.60 Count X:80 Y:200 Z:0 A:160") == \
        {"X": 1.0, "Y": 2.5, "Z": 0.0, "A": 3.6}


def test_numbered_lines_checksum_errors_and_resend():
    run_exchange(emulator(), [
        (N(0, "M110 N0"), OK),
        (N(1, "G0 Y19"), OK),
        (b"N2 G0 Y18*1\n", b"Error:checksum mismatch, Last Line: 1\nResend: 2\nok\n"),
        (N(2, "G0 Y18"), OK),
        (N(4, "G0 Y17"), b"Error:Line Number is not Last Line Number+1, Last Line: 2\nResend: 3\nok\n"),
        (b"N3 G0 Y17\n", b"Error:No Checksum with line number, Last Line: 2\nResend: 3\nok\n"),
        (N(3, "G0 Y17"), OK),
        (N(9, "M110 N41"), OK),                      # M110 sets the number whatever its own N
        (N(42, "G0 Y16"), OK),
        (b"G0 Y15\n", OK),                          # unnumbered lines are taken as they come
        (b"\n", b""),                               # empty lines get no answer
        (b"G0 Y14\r\n", OK),                        # CR LF: one line, one ok
        (b"G999 X1\n", b'echo:Unknown command: "G999 X1"\nok\n'),
        (b"M400 ; wait\n", OK),
    ])


def test_a_corrupted_line_flushes_what_followed_it():
    emu = emulator()
    # two lines in one write: the first is damaged, so Marlin drops the second with its buffer
    run_exchange(emu, [
        (N(0, "M110 N0"), OK),
        (b"N1 G0 Y10*0\n" + N(2, "G0 Y9"), b"Error:checksum mismatch, Last Line: 0\nResend: 1\nok\n"),
        (N(1, "G0 Y10") + N(2, "G0 Y9"), OK + OK),
    ])


def test_m400_answers_only_after_motion_and_busy_comes_every_two_seconds():
    emu = emulator()
    # 720 deg of A at 7200 deg/min (120 deg/s), 300 deg/s^2: ramps 0.4 s / 24 deg, cruise 672 deg
    run_exchange(emu, [(b"G0 A720 F7200\n", OK), (b"M400\n", b"")])
    run_exchange(emu, [(b"", (mc.BUSY_PROCESSING.encode() + b"\n") * 3 + OK)])
    assert emu.now == pytest.approx(0.8 + 672 / 120)
    assert emu.world.ring_deg == pytest.approx(720.0, abs=0.5 / 44.4444)     # 32000 steps
    run_exchange(emu, [(b"M114\n", b"X:0.00 Y:0.00 Z:0.00 A:720.00 Count X:0 Y:0 Z:0 A:32000\nok\n")])


def test_g28_homes_with_busy_and_g92_sets_the_logical_position():
    emu = emulator()
    run_exchange(emu, [
        (b"G0 A100 F7200\n", OK),
        (b"G28\n", b"echo:busy: processing\nok\n"),
        (b"M114\n", b"X:0.00 Y:20.00 Z:0.00 A:0.00 Count X:0 Y:1600 Z:0 A:0\nok\n"),
        (b"G92 A5\n", OK),
        (b"G0 A6\n", OK),
        (b"M400\n", OK),
        (b"M114\n", b"X:0.00 Y:20.00 Z:0.00 A:6.00 Count X:0 Y:1600 Z:0 A:44\nok\n"),
    ])
    assert emu.world.ring_deg == round(44.4444) / 44.4444   # home at A=0, then one degree: 44 steps


def test_m115_and_planner_of_15_blocks_withholds_ok():
    emu = emulator()
    emu.receive(b"M115\n")
    out = emu.transmit().decode()
    assert out.startswith("FIRMWARE_NAME:Marlin 2.1.2.1 ") and "Cap:EEPROM:1\n" in out   # M500 stores settings
    assert out.endswith("ok\n")
    for i in range(4):
        emu.receive(b"G0 A%d F7200\n" % (10 * (i + 1)))
    assert emu.transmit() == OK * 4
    emu.receive(b"".join(b"G0 A%d\n" % (100 + 10 * i) for i in range(14)))
    # 15 blocks fill the planner; the 16th command waits in the handler, 2 more wait in the queue
    assert emu.transmit() == OK * 11
    assert emu.motion.free == 0 and len(emu.queue) == 2
    run_exchange(emu, [(b"", OK)])                     # one block done: the next gets its ok


def test_receive_buffer_overflow_loses_bytes():
    emu = emulator()
    emu.receive(b"G0 A700 F7200\nM400\n")
    assert emu.transmit() == OK
    burst = b"".join(b"G0 Y%d\n" % (10 + i) for i in range(40))
    emu.receive(burst)
    assert emu.dropped_bytes == len(burst) - 127 + 0 and emu.dropped_bytes > 0


def test_error_fault_is_a_rejected_line_with_resend():
    emu = emulator(faults="error@2")
    run_exchange(emu, [
        (N(0, "M110 N0"), OK),
        (N(1, "G0 Y19"), b"Error:checksum mismatch, Last Line: 0\nResend: 1\nok\n"),
        (N(1, "G0 Y19"), OK),
    ])


def test_arcs_and_bad_arc_parameters():
    emu = emulator()
    run_exchange(emu, [
        (b"G2 X10 Y0\n", b"Error:G2/G3 bad parameters\nok\n"),
        (b"G2 X10 Y0 I5 F600\n", OK),
        (b"M400\n", OK),
        (b"M114\n", b"X:10.00 Y:0.00 Z:0.00 A:0.00 Count X:800 Y:0 Z:0 A:0\nok\n"),
    ])
    assert emu.world.moves > 10                  # 1 mm segments round a 5 mm radius
