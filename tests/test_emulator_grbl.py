"""The simulated GRBL 1.1h / grblHAL, byte for byte: exchange tables against the emulator."""

import math

import pytest

from firmware_protocol import grbl as codec
from firmware_protocol.emulators.grbl import GrblEmulator, GrblHalEmulator, GrblState
from firmware_protocol.emulators.testing import ExchangeMismatch, run_exchange
from firmware_protocol.machine import load_machine, machine_from_dict
from firmware_protocol.world import World

pytestmark = pytest.mark.timeout(30)

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
OK = b"ok\r\n"


def machine(name="grbl-ring", **controller):
    m = load_machine(name)
    if not controller:
        return m
    import tomllib
    from pathlib import Path
    doc = tomllib.loads(Path(m.path).read_text())
    doc["controller"].update(controller)
    return machine_from_dict(doc, source=m.path)


def emulator(**kw):
    m = machine(**kw)
    emu = GrblEmulator(m, world=World(m))
    run_exchange(emu, [(b"", BANNER)])
    return emu


def test_banner_after_power_up_and_nothing_else():
    m = machine()
    emu = GrblEmulator(m, world=World(m))
    run_exchange(emu, [(b"", BANNER), (b"", b"")])


def test_exchange_table_must_be_used_up_exactly():
    emu = emulator()
    with pytest.raises(ExchangeMismatch, match="step 0"):
        run_exchange(emu, [(b"G0 X1\nG0 X2\n", OK)])    # one ok too many


def test_ok_and_grbls_error_codes():
    run_exchange(emulator(), [
        (b"G0 X10\n", OK),
        (b"G1 Y5\n", b"error:22\r\n"),            # feed rate never set
        (b"G1 Y5 F600\n", OK),
        (b"G99\n", b"error:20\r\n"),              # unsupported command
        (b"G0 X1.2.3\n", b"error:1\r\n"),         # read_float stops at the 2nd '.', not a letter
        (b"G0 X.\n", b"error:2\r\n"),            # bad number format: no digits
        (b"X\n", b"error:2\r\n"),
        (b"10\n", b"error:1\r\n"),                # expected command letter
        (b"G0 X1 X2\n", b"error:25\r\n"),         # repeated word
        (b"G0 G1 X1\n", b"error:21\r\n"),         # modal group violation
        (b"G4\n", b"error:28\r\n"),               # G4 needs P
        (b"G0 A5\n", b"error:20\r\n"),            # stock GRBL has no A axis
        (b"G0 X1 P3\n", b"error:36\r\n"),         # unused value word
        (b"G92\n", b"error:26\r\n"),              # no axis words
        (b"G59.1\n", b"error:23\r\n"),            # GRBL's code: G59 with a mantissa (its docs say 29)
        (b"M999\n", b"error:23\r\n"),             # uint8 int_value 231, mantissa 11264: "not integer"
        (b"M5.5\n", b"error:23\r\n"),
        (b"M100\n", b"error:20\r\n"),
        (b"G1.5 X1\n", b"error:23\r\n"),
        (b"G43 Z1\n", b"error:20\r\n"),            # only G43.1
        (b"G90.1\n", b"error:20\r\n"),
        (b"G91.1\n", OK),                           # GRBL's only arc distance mode: accepted
        (b"G300\n", b"error:20\r\n"),
        (b"T300\n", b"error:38\r\n"),
        (b"G1 X5 F-3\n", b"error:4\r\n"),
        (b"N99999999 G0 X1\n", b"error:27\r\n"),
        (b"G4 P0\n", OK),                          # settings only when idle: wait for motion
        (b"$Q\n", b"error:2\r\n"),
        (b"$999=1\n", b"error:3\r\n"),
        (b"$0=2\n", b"error:6\r\n"),
        (b"$H\n", b"error:5\r\n"),                # homing disabled ($22=0)
        (b"g0 x0 (comment) ; tail\n", OK),        # lower case, comments, spaces
        (b"\n", OK),                              # an empty line is ok too
        (b"G0 X1\r\n", OK + OK),                  # CR and LF are two line ends to GRBL
        (b"G0 X" + b"1" * 90 + b"\n", b"error:11\r\n"),  # longer than the 80-byte line buffer
    ])


def test_error_codes_table_is_grbls():
    assert codec.describe_error(20).startswith("Unsupported command")
    assert codec.ALARM_CODES[3].startswith("Reset while in motion")
    assert codec.parse_error("error:9") == 9 and codec.parse_alarm("ALARM:3") == 3
    assert codec.parse_error("ok") is None


def test_status_reports_follow_grbls_default_mask_and_refresh_counters():
    emu = emulator()
    run_exchange(emu, [
        (b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n"),
        (b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|Ov:100,100,100>\r\n"),
        (b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0>\r\n"),
        (b"$10=3\n", OK),
        (b"?", b"<Idle|MPos:0.000,0.000,0.000|Bf:15,128|FS:0,0>\r\n"),
        (b"$10=0\n", OK),
        (b"G10 L2 P1 X5\n", OK),                   # a WCO change: the next report says so
        (b"?", b"<Idle|WPos:-5.000,0.000,0.000|FS:0,0|WCO:5.000,0.000,0.000>\r\n"),
        (b"?", b"<Idle|WPos:-5.000,0.000,0.000|FS:0,0>\r\n"),
        (b"G10 L2 P2 X7\n", OK),                   # G55 is not in use: no WCO change
        (b"?", b"<Idle|WPos:-5.000,0.000,0.000|FS:0,0>\r\n"),
        (b"G55\n", OK),
        (b"?", b"<Idle|WPos:-7.000,0.000,0.000|FS:0,0|WCO:7.000,0.000,0.000>\r\n"),
    ])
    st = codec.parse_status("<Idle|MPos:1.000,2.000,0.000|Bf:15,128|FS:0,0|WCO:1.000,0.000,0.000>")
    assert st.state == "Idle" and st.mpos == (1.0, 2.0, 0.0) and st.wpos == (0.0, 2.0, 0.0)
    assert (st.planner_free, st.rx_free) == (15, 128)


def test_settings_build_info_parser_state_help():
    emu = emulator()
    emu.receive(b"$$\n")
    out = emu.transmit().decode()
    lines = out.split("\r\n")
    assert lines[0] == "$0=10" and "$10=1" in lines and "$22=0" in lines
    assert "$110=7200.000" in lines and "$120=360.000" in lines and "$100=44.444" in lines
    assert out.endswith("ok\r\n")
    run_exchange(emu, [
        (b"$I\n", b"[VER:1.1h.20190830:]\r\n[OPT:V,15,128]\r\nok\r\n"),
        (b"$G\n", b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\nok\r\n"),
        (b"G91 G1 F250\n", OK),
        (b"$G\n", b"[GC:G1 G54 G17 G21 G91 G94 M5 M9 T0 F250 S0]\r\nok\r\n"),
        (b"$\n", b"[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]\r\nok\r\n"),
        (b"$N\n", b"$N0=\r\n$N1=\r\nok\r\n"),
    ])


#: grbl-ring's X (ring) steps per degree and Y (head) steps per mm: positions are whole steps
RING_SPU, HEAD_SPU = 44.4444, 80.0
HALF_RING_STEP, HALF_HEAD_STEP = 0.5 / RING_SPU, 0.5 / HEAD_SPU


def on_step(x, spu=RING_SPU):
    """``x`` on the nearest whole step, as GRBL plans it (``lround(x * steps_per_mm)``)."""
    return round(x * spu) / spu


def test_g4_p0_is_answered_only_when_motion_has_finished():
    emu = emulator()
    emu.receive(b"G0 X90\nG4 P0\n")
    assert emu.transmit() == OK                    # the move is queued, the dwell waits
    assert emu.state is GrblState.RUN
    run_exchange(emu, [(b"", OK)])                 # the clock runs until the dwell answers
    # 90 deg at 7200 deg/min (120 deg/s) and 360 deg/s^2: two ramps of 1/3 s and 20 deg, 50 deg cruise
    assert emu.now == pytest.approx(2 / 3 + 50 / 120)
    assert (emu.world.ring_deg, emu.world.head_mm) == (on_step(90.0), 0.0)     # 4000 steps
    run_exchange(emu, [(b"?", b"<Idle|MPos:90.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n")])


def test_planner_holds_15_blocks_and_withholds_ok_when_full():
    emu = emulator()
    run_exchange(emu, [(b"$10=3\n", OK)])
    lines = b"".join(b"G1 X%d F6000\n" % (10 * (i + 1)) for i in range(16))
    emu.receive(lines)
    assert emu.transmit() == OK * 15               # the 16th waits for room in the planner
    run_exchange(emu, [
        (b"?", b"<Run|MPos:0.000,0.000,0.000|Bf:0,128|FS:0,0|WCO:0.000,0.000,0.000>\r\n"),
        (b"", OK),                                  # the first block ends, the 16th is queued
    ])
    assert emu.motion.free == 0 and emu.world.ring_deg == on_step(10.0)


def test_receive_buffer_overflow_when_the_host_oversends():
    emu = emulator()
    fill = b"".join(b"G1 X%d F6000\n" % (10 * (i + 1)) for i in range(16))
    emu.receive(fill)
    assert emu.transmit() == OK * 15               # blocked on the 16th line
    # 11 lines of 12 bytes = 132 bytes: 128 fit, the rest is dropped on the floor
    burst = b"".join(b"G1 Y%d F1000\n" % (i % 10) for i in range(11))
    assert len(burst) == 132
    emu.receive(burst)
    assert emu.dropped_bytes == 4
    emu.settings[10] = 3                # buffer state on: nothing free in the planner or the RX buffer
    assert "|Bf:0,0|" in emu.status_report()
    run_exchange(emu, [(b"", OK)])      # a block ends: the 16th line is queued, the next one blocks
    # "G1 Y0 F1" of the 11th line arrived, its tail "000\n" did not: the next line merges with it
    run_exchange(emu, [(b"$G\n", OK * 10 + b"error:1\r\n")])


def test_feed_hold_resume_and_soft_reset_while_moving():
    emu = emulator()
    run_exchange(emu, [(b"G0 X360\n", OK)])
    emu.advance(0.5)
    run_exchange(emu, [(b"!", b""), (b"?", b"<Hold:1|MPos:" + b"%.3f" % on_step(emu.motion.position[0])
                                      + b",0.000,0.000|FS:7200,0|WCO:0.000,0.000,0.000>\r\n")])
    emu.advance(None)                              # decelerates to rest
    held = emu.world.ring_deg
    assert 0 < held < 360
    run_exchange(emu, [(b"?", b"<Hold:0|MPos:%.3f,0.000,0.000|FS:0,0|Ov:100,100,100>\r\n" % held)])
    emu.advance(5.0)
    assert emu.world.ring_deg == held              # held: nothing moves
    run_exchange(emu, [(b"~", b"")])
    assert emu.state is GrblState.RUN
    emu.advance(0.2)
    pos = on_step(emu.motion.position[0])
    run_exchange(emu, [(b"\x18", b"ALARM:3\r\n" + BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n")])
    assert emu.world.ring_deg == pytest.approx(pos)  # stopped where it was, on a step
    run_exchange(emu, [
        (b"G0 X0\n", b"error:9\r\n"),              # G-code locked out in alarm
        (b"?", b"<Alarm|MPos:%.3f,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n" % pos),
        (b"$X\n", b"[MSG:Caution: Unlocked]\r\nok\r\n"),
        (b"G0 X0\n", OK),
    ])


def test_soft_reset_when_idle_keeps_position_and_gives_no_alarm():
    emu = emulator()
    run_exchange(emu, [(b"G0 X5\nG4 P0\n", OK + OK), (b"G92 X0\n", OK), (b"\x18", BANNER)])
    # 5 deg is 222.222 steps: GRBL goes to 222 and reports 4.995
    run_exchange(emu, [(b"?", b"<Idle|MPos:4.995,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n")])


def test_homing_machine_starts_in_alarm_and_homes_to_the_switches():
    m = machine(homing=True)
    world = World(m)
    world.move(1.2 * 0.5, 0.0)       # someone turned the ring by hand, within the gap
    emu = GrblEmulator(m, world=world)
    run_exchange(emu, [
        (b"", BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n"),
        (b"G0 X1\n", b"error:9\r\n"),
        (b"$H\n", OK),
        (b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n"),
    ])
    assert world.ring_deg == pytest.approx(0.0, abs=HALF_RING_STEP) and world.collisions == []


def test_jog_and_jog_cancel():
    emu = emulator()
    run_exchange(emu, [(b"$J=G91 X100 F6000\n", OK)])
    assert emu.state is GrblState.JOG
    run_exchange(emu, [(b"G0 X1\n", b"error:9\r\n"), (b"$J=X1\n", b"error:22\r\n")])
    emu.advance(0.3)
    emu.receive(b"\x85")
    emu.advance(None)
    assert emu.state is GrblState.IDLE and 0 < emu.world.ring_deg < 100
    run_exchange(emu, [(b"$J=G91 G1 X1 F100\n", b"error:16\r\n")])


def test_check_mode_parses_without_moving():
    emu = emulator()
    run_exchange(emu, [
        (b"$C\n", b"[MSG:Enabled]\r\nok\r\n"),
        (b"G0 X50\n", OK),
        (b"G5\n", b"error:20\r\n"),
        (b"$C\n", b"[MSG:Disabled]\r\nok\r\n" + BANNER),
    ])
    assert emu.world.ring_deg == 0.0


def test_motion_reaches_the_world_partway_when_time_is_cut():
    emu = emulator()
    run_exchange(emu, [(b"G0 X360\n", OK)])
    emu.advance(0.25)                                # still accelerating: s = a t^2 / 2
    assert emu.world.ring_deg == pytest.approx(0.5 * 360 * 0.25 ** 2, abs=HALF_RING_STEP)
    assert emu.busy


def test_grblhal_banner_buffer_and_a_axis():
    m = load_machine("grblhal-ring")
    emu = GrblHalEmulator(m, world=World(m))
    hal_banner = b"\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n"
    run_exchange(emu, [(b"", hal_banner + b"[MSG:'$H'|'$X' to unlock]\r\n")])
    emu.receive(b"$I\n")
    lines = emu.transmit().decode().split("\r\n")
    assert lines[0].startswith("[VER:1.1f.")
    assert lines[1] == "[OPT:VNMSL,100,1024,4,0]" and "[AXS:4:XYZA]" in lines
    assert "[FIRMWARE:grblHAL]" in lines and lines[-2] == "ok"
    run_exchange(emu, [
        (b"$X\n", b"[MSG:Caution: Unlocked]\r\nok\r\n"),
        (b"G0 A3.6\n", OK),
        (b"G4 P0\n", OK),
        (b"?", b"<Idle|MPos:0.000,0.000,0.000,3.600|Bf:100,1024|FS:0,0|WCO:0.000,0.000,0.000,0.000>\r\n"),
    ])
    assert emu.world.ring_deg == pytest.approx(3.6)


def test_brownout_and_trapezoid_timing_helpers_are_consistent():
    from firmware_protocol.emulators.motion import Profile
    p = Profile.move(0.0, 10.0, 5.0, 2.0)           # ramps 2.5 s / 6.25 mm each: a triangle
    assert p.duration == pytest.approx(2 * math.sqrt(10.0 / 2.0))
    assert p.at(p.duration)[0] == pytest.approx(10.0)


def test_arcs_are_cut_into_segments_on_the_circle():
    emu = emulator()
    run_exchange(emu, [
        (b"G2 X10 Y0 F600\n", b"error:35\r\n"),          # no I or J
        (b"G2 I5 F600\n", b"error:32\r\n"),              # no in-plane axis word
        (b"G2 X10 Y0 I3 F600\n", b"error:33\r\n"),       # the end is not on the circle
        (b"G2 X10 Y0 R2 F600\n", b"error:33\r\n"),       # radius too small for the chord
        (b"G17 G2 X10 Y0 I5 J0 F600\n", OK),             # half circle through Y=+5 (clockwise)
        (b"G4 P0\n", OK),
    ])
    assert emu.world.ring_deg == on_step(10.0) and emu.world.head_mm == 0.0
    assert emu.world.moves > 20                           # cut within the 0.002 mm tolerance
    run_exchange(emu, [(b"G3 X0 Y0 R5\n", OK), (b"G4 P0\n", OK)])
    assert emu.world.ring_deg == 0.0
