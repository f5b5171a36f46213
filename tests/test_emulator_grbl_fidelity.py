"""Where the GRBL emulator follows GRBL 1.1h's source rather than a simpler reading of its docs:
the receive buffer's overflow, error codes of odd words, jogging's checks, feed hold states, WCO
after an offset change, ``$RST=``.  Exchange tables, byte for byte."""

import pytest

from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.emulators.testing import run_exchange

pytestmark = pytest.mark.timeout(30)

OK = b"ok\r\n"
BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"


#: steps per unit of the bundled G-code machines' ring (44.4444/deg) and head (80/mm) axes:
#: the simulated firmware stands and reports on whole steps
RING_SPU, HEAD_SPU = 44.4444, 80.0
HALF_RING_STEP = 0.5 / RING_SPU


def on_step(x, spu=RING_SPU):
    """``x`` on the nearest whole step, as the firmware plans it (``lround(x * steps)``)."""
    return round(x * spu) / spu


def emulator(machine="grbl-ring"):
    emu, world = build_emulator(machine)
    emu.transmit()
    return emu, world


def drain(emu):
    """Run the clock until nothing is pending; all the output."""
    out = bytearray(emu.transmit())
    while emu.busy:
        emu.advance(None)
        out += emu.transmit()
    return bytes(out)


def fill_planner(emu, blocks):
    """``blocks`` slow moves: all but the last are queued at once; the last waits for room."""
    lines = b"".join(b"G1X%dF1\n" % (i + 1) for i in range(blocks + 1))
    emu.receive(lines)
    assert emu.transmit() == OK * blocks


def test_rx_overflow_drops_bytes_and_a_later_line_arrives_truncated():
    emu, world = emulator()
    run_exchange(emu, [(b"$10=3\n", OK)])
    fill_planner(emu, 15)                                   # line 16 waits in the main loop
    burst = b"G1X1.5F100\n" * 14                            # 154 bytes: 11 lines and 7 bytes fit
    emu.receive(burst)
    assert emu.dropped_bytes == 154 - 128
    run_exchange(emu, [(b"?", b"<Run|MPos:0.000,0.000,0.000|Bf:0,0|FS:0,0|WCO:0.000,0.000,0.000>\r\n")])
    emu.advance(emu.next_event_in())                       # a block ends: line 16 goes in, ok
    assert emu.transmit() == OK
    out = b""
    while emu.busy and out.count(b"\n") < 11:
        emu.advance(None)
        out += emu.transmit()
    assert out == OK * 11                                   # the 11 whole lines
    # "G1X1.5F" waits for its line end; the host's next line completes it: "G1X1.5FG0X0"
    run_exchange(emu, [(b"G0X0\n", b"error:2\r\n")])        # F without a number


def test_rx_overflow_loses_whole_lines_when_it_fills_at_a_line_end():
    emu, world = emulator()
    fill_planner(emu, 15)
    emu.receive(b"G4P0\n" * 25 + b"M5")                     # 125 + 2 = 127 bytes fit: nothing lost
    emu.receive(b"\nM9\nM5\n")                             # "\n" fits, the rest is dropped
    assert emu.dropped_bytes == 6
    assert drain(emu) == OK * (1 + 25 + 1)                  # line 16, the 25 syncs, "M5" -- no M9


def test_grblhal_receive_buffer_is_1024():
    emu, world = emulator("grblhal-ring")
    run_exchange(emu, [(b"$X\n", b"[MSG:Caution: Unlocked]\r\nok\r\n")])
    fill_planner(emu, 100)
    emu.receive(b"G4P0\n" * 204 + b"G4P0\n")              # 1025 bytes
    assert emu.dropped_bytes == 1
    run_exchange(emu, [(b"?", b"<Run|MPos:0.000,0.000,0.000,0.000|Bf:0,0|FS:0,0|WCO:0.000,0.000,0.000,0.000>\r\n")])


def test_jog_errors_come_in_grbls_order():
    emu, world = emulator()
    run_exchange(emu, [
        (b"$J=G4P1\n", b"error:22\r\n"),              # no F: checked before what a jog may hold
        (b"$J=G4P1F100\n", b"error:16\r\n"),
        (b"$J=X1F100S5\n", b"error:36\r\n"),          # S is an unused word
        (b"$J=G91X1F100M3\n", b"error:16\r\n"),
        (b"$J=G1X1F100\n", b"error:16\r\n"),
        (b"$J=X1.2.3F1\n", b"error:1\r\n"),
        (b"$J=G91X1F-100\n", b"error:4\r\n"),
        (b"$J=G91G20X1F10\n", OK),                    # inches, like a G-code line
    ])
    assert drain(emu) == b""
    assert world.ring_deg == on_step(25.4)


def test_feed_hold_decelerates_in_hold_1_then_holds_in_hold_0():
    emu, world = emulator()
    run_exchange(emu, [(b"G1 X100 F3000\n", OK)])           # 50 deg/s, 360 deg/s^2: cruising at t=0.5
    emu.advance(0.5)
    run_exchange(emu, [
        (b"!?", b"<Hold:1|MPos:21.533,0.000,0.000|FS:3000,0|WCO:0.000,0.000,0.000>\r\n"),   # 957 steps
    ])
    emu.advance(0.1)
    run_exchange(emu, [(b"?", b"<Hold:1|MPos:24.728,0.000,0.000|FS:840,0|Ov:100,100,100>\r\n")])  # 1099
    emu.advance(1.0)                                         # stopped 50^2 / (2 * 360) deg later
    run_exchange(emu, [(b"?", b"<Hold:0|MPos:24.998,0.000,0.000|FS:0,0>\r\n"),            # 1111 steps
                       (b"~?", b"<Run|MPos:24.998,0.000,0.000|FS:0,0>\r\n")])
    assert drain(emu) == b""
    assert world.ring_deg == on_step(100.0)


def test_offset_changes_wait_for_motion_and_report_wco_at_once():
    emu, world = emulator()
    run_exchange(emu, [(b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n"),
                       (b"G0 X10\n", OK)])
    emu.receive(b"G10 L20 P1 X0\n")                          # GRBL syncs before an EEPROM write
    assert emu.transmit() == b"" and not emu.motion.empty
    run_exchange(emu, [(b"", OK),
                       # 444 steps; the offset comes from the parser's exact 10 (gc_state.position)
                       (b"?", b"<Idle|MPos:9.990,0.000,0.000|FS:0,0|WCO:10.000,0.000,0.000>\r\n"),
                       (b"?", b"<Idle|MPos:9.990,0.000,0.000|FS:0,0|Ov:100,100,100>\r\n"),
                       (b"G92 X1\n", OK),
                       (b"?", b"<Idle|MPos:9.990,0.000,0.000|FS:0,0|WCO:9.000,0.000,0.000>\r\n"),
                       (b"G92.1\n", OK),
                       (b"?", b"<Idle|MPos:9.990,0.000,0.000|FS:0,0|WCO:10.000,0.000,0.000>\r\n")])
    assert world.ring_deg == on_step(10.0)


def test_restore_prints_its_message_answers_and_resets():
    emu, world = emulator()
    run_exchange(emu, [(b"G0 X5\nG4 P0\n", OK + OK), (b"G10 L2 P1 X3\n", OK), (b"$100=10\n", OK),
                       (b"$N0=G91\n", OK),
                       (b"$RST=#\n", b"[MSG:Restoring defaults]\r\nok\r\n" + BANNER + b">G91:ok\r\n")])
    emu.receive(b"$#\n")
    assert emu.transmit().startswith(b"[G54:0.000,0.000,0.000]\r\n")       # offsets gone
    run_exchange(emu, [(b"$RST=$\n", b"[MSG:Restoring defaults]\r\nok\r\n" + BANNER + b">G91:ok\r\n")])
    assert emu.settings[100] == pytest.approx(44.4444)                    # the build's steps again
    run_exchange(emu, [(b"$RST=*\n", b"[MSG:Restoring defaults]\r\nok\r\n" + BANNER),
                       (b"$N\n", b"$N0=\r\n$N1=\r\nok\r\n"),
                       (b"$RST=x\n", b"error:3\r\n")])
    assert world.ring_deg == on_step(5.0)                     # a reset moves nothing


def test_error_codes_of_odd_words():
    emu, world = emulator()
    run_exchange(emu, [(b"M999\n", b"error:23\r\n"), (b"G1 X1.2.3\n", b"error:1\r\n"),
                       (b"G10 L2.5 P1 X1\n", OK),           # L is read as GRBL's uint8: L2
                       (b"G28.2\n", b"error:20\r\n"), (b"G38.2 X1 F10\n", b"error:20\r\n")])


def test_positions_are_whole_steps_as_the_firmware_counts_them():
    """GRBL plans lround(target * $100) steps: G0 X5 at 44.4444 steps/deg is 222 steps, 4.995 deg,
    and the world turns 4.995 deg too; the parser keeps the exact 5 (G10 L20 uses it)."""
    emu, world = emulator()
    run_exchange(emu, [(b"G0 X5 Y3.33\nG4 P0\n", OK + OK),
                       (b"?", b"<Idle|MPos:4.995,3.325,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n"),
                       (b"G10 L20 P1 X0\n", OK),
                       (b"$10=0\n", OK),
                       (b"?", b"<Idle|WPos:-0.005,3.325,0.000|FS:0,0|WCO:5.000,0.000,0.000>\r\n")])
    assert (world.ring_deg, world.head_mm) == (222 / 44.4444, 266 / 80.0)
    emu, world = emulator("grblhal-ring")
    run_exchange(emu, [(b"$X\n", b"[MSG:Caution: Unlocked]\r\nok\r\n"), (b"G0 A0.01\nG4 P0\n", OK + OK)])
    assert world.ring_deg == 1 / 88.8889                   # the nearest step of 0.889


def test_whole_steps_can_be_turned_off_for_comparisons():
    emu, world = build_emulator("grbl-ring")
    emu.whole_steps = False
    emu.transmit()
    run_exchange(emu, [(b"G0 X5\nG4 P0\n", OK + OK)])
    assert world.ring_deg == 5.0
