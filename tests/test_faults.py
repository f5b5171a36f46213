"""Fault injection: kind@N on the N-th line the firmware receives (GRBL, grblHAL, Marlin)."""

import pytest

from firmware_protocol import marlin as mc
from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.emulators.grbl import GrblState
from firmware_protocol.emulators.testing import run_exchange
from firmware_protocol.faults import (BOOT_SECONDS, DISCONNECT_SECONDS, POWER_OFF_SECONDS, Fault, FaultPlan,
                                      parse_faults)

pytestmark = pytest.mark.timeout(30)

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
OK = b"ok\r\n"


def on_step(x, spu=44.4444):
    """``x`` on the nearest whole step of grbl-ring's ring axis (the firmware counts steps)."""
    return round(x * spu) / spu


HALF_STEP = 0.5 / 44.4444


def grbl(faults, machine="grbl-ring"):
    emu, world = build_emulator(machine, faults=faults)
    emu.transmit()
    return emu, world


def test_parse_faults_and_the_plan_counts_lines():
    assert parse_faults("reset@3, garble@7") == [Fault("reset", 3), Fault("garble", 7)]
    assert parse_faults("") == []
    for bad in ("reset", "reset@0", "reset@-1", "boom@2", "reset@2;garble@3"):
        with pytest.raises(ValueError, match="expected a comma list of kind@N"):
            parse_faults(bad)
    plan = FaultPlan("drop-ok@2,garble@2,reset@4")
    assert [plan.next_line() for _ in range(5)] == [set(), {"drop-ok", "garble"}, set(), {"reset"}, set()]
    assert str(plan) == "" and len(plan.fired) == 3


def test_grbl_reset_while_moving_alarms_pauses_and_keeps_the_position():
    emu, world = grbl("reset@3")
    run_exchange(emu, [(b"G0 X90\n", OK), (b"\n", OK)])        # empty lines count too
    emu.advance(0.5)
    moved = world.ring_deg
    assert 0 < moved < 90
    emu.receive(b"G0 Y5\n")
    assert emu.transmit() == b"ALARM:3\r\n"
    emu.receive(b"?$X\n")                                     # lost in GRBL's 0.5 s pause
    assert emu.next_event_in() == pytest.approx(0.5)
    run_exchange(emu, [(b"", BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n")])
    assert emu.state is GrblState.ALARM and emu.now == pytest.approx(1.0)
    emu.advance(10.0)
    assert world.ring_deg == moved                            # stopped where it was; Y5 never ran
    run_exchange(emu, [
        (b"?", f"<Alarm|MPos:{moved:.3f},0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n".encode()),
        (b"$X\n", b"[MSG:Caution: Unlocked]\r\nok\r\n"),
        (b"G0 X1\nG4 P0\n", OK + OK),
    ])
    assert world.ring_deg == on_step(1.0)                     # the belief is still the world


def test_grbl_reset_when_idle_has_no_alarm():
    emu, world = grbl("reset@3")
    run_exchange(emu, [(b"G0 X5\nG4 P0\n", OK + OK), (b"G0 X0\n", BANNER),
                       (b"?", b"<Idle|MPos:4.995,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n")])
    assert world.ring_deg == on_step(5.0)


def test_grbl_power_loss_drops_the_port_and_restarts_later():
    emu, world = grbl("power@2")
    run_exchange(emu, [(b"G0 X180\n", OK)])
    emu.advance(0.4)
    emu.receive(b"G0 X0\n")
    assert not emu.port_up and emu.transmit() == b""
    stopped = world.ring_deg
    emu.receive(b"?")                                         # nobody is listening
    assert emu.transmit() == b""
    assert emu.next_event_in() == pytest.approx(POWER_OFF_SECONDS)
    emu.advance(None)
    assert emu.port_up and world.ring_deg == stopped
    run_exchange(emu, [(b"", BANNER),
                       (b"?", b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n")])


def test_grbl_disconnect_loses_the_line_but_the_firmware_runs_on():
    emu, world = grbl("disconnect@2")
    run_exchange(emu, [(b"G0 X30\n", OK)])
    emu.receive(b"G0 X60\n")
    assert not emu.port_up
    emu.advance(0.3)                                           # motion goes on while unplugged
    assert 0 < world.ring_deg < 30.0 and not emu.port_up
    emu.reconnect()
    assert emu.port_up and emu.now == pytest.approx(DISCONNECT_SECONDS)
    run_exchange(emu, [(b"G4 P0\n", OK)])
    assert world.ring_deg == on_step(30.0)


def test_grbl_garble_error_and_drop_ok():
    emu, world = grbl("garble@1,error@2,drop-ok@3")
    run_exchange(emu, [
        (b"G0 X10\n", b"error:1\r\n"),          # "G0 \x7f10": a DEL where the letter should be
        (b"G0 X20\n", b"error:20\r\n"),
        (b"G0 X30\n", b""),                     # executed, ok lost
        (b"G4 P0\n", OK),
    ])
    assert world.ring_deg == on_step(30.0)


def test_grblhal_power_fault_through_the_factory():
    emu, world = build_emulator("grblhal-ring", faults="power@1")
    emu.transmit()
    emu.receive(b"$X\n")
    assert not emu.port_up
    emu.reconnect()
    assert emu.transmit().startswith(b"\r\nGrblHAL 1.1f")


def test_marlin_faults():
    # software endstops off: the move below goes under the believed 0 that power-up gives
    emu, world = build_emulator("marlin-ring", faults="garble@2,drop-ok@3,reset@5", settings=["M211 S0"])
    emu.transmit()
    n = lambda i, c: mc.numbered(i, c).encode() + b"\n"  # noqa: E731
    run_exchange(emu, [
        (n(0, "M110 N0"), b"ok\n"),
        (n(1, "G0 Y-9"), b"Error:checksum mismatch, Last Line: 0\nResend: 1\nok\n"),
        (n(1, "G0 Y-9"), b""),                  # executed; its ok is lost
        (n(2, "M400"), b"ok\n"),
    ])
    assert world.head_mm == 11.0               # belief -9 + the head's power-up position 20
    emu.receive(n(3, "G0 Y18"))
    assert emu.transmit() == b""                 # Marlin's reset is a restart: a moment of silence
    assert emu.next_event_in() == pytest.approx(BOOT_SECONDS)
    emu.advance(None)
    assert emu.transmit().startswith(b"start\n")  # the firmware restarted: line numbers start again
    run_exchange(emu, [(n(1, "M114"), b"X:0.00 Y:0.00 Z:0.00 A:0.00 Count X:0 Y:0 Z:0 A:0\nok\n")])
    assert world.head_mm == 11.0               # the thread and the axes stay put


def test_power_fault_on_a_pty_drops_the_port_and_the_firmware_restarts(tmp_path):
    import threading
    import time

    import serial

    from firmware_protocol.pty import PtyServer
    emu, world = build_emulator("grbl-ring", faults="power@2")
    path = tmp_path / "tty"
    server = PtyServer(emu, path, reopen_delay=0.1).start()
    stop = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stop,), kwargs={"poll": 0.005}, daemon=True)
    thread.start()
    try:
        port = serial.Serial(str(path), timeout=1)
        assert port.read(len(BANNER)) == BANNER
        port.write(b"G0 X5\n")
        assert port.readline() == OK
        port.write(b"G0 X9\n")
        with pytest.raises(serial.SerialException):
            for _ in range(200):
                port.read(1)
                port.write(b"?")
        port.close()
        deadline = time.monotonic() + 5
        while server.generation < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        port = serial.Serial(str(path), timeout=2)
        assert port.read(len(BANNER)) == BANNER          # the restarted firmware's banner waited
        port.write(b"?")
        assert port.readline() == b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n"
        port.close()
    finally:
        stop.set()
        thread.join(5)
        server.close()


def test_marlin_freeze_is_deaf_and_mute_until_a_reboot():
    emu, world = build_emulator("marlin-ring", faults="freeze@2,reboot@t=100")
    emu.transmit()
    emu.receive(b"G0 A90 F7200\n")
    assert emu.transmit() == b"ok\n"
    emu.receive(b"M400\n")                      # line 2: the main loop hangs as it arrives
    emu.advance(30.0)
    assert emu.transmit() == b""                # no ok, no busy: keepalive
    assert world.ring_deg == pytest.approx(90.0, abs=0.05)    # the steppers ran out their move
    emu.receive(b"M114\n")
    emu.advance(30.0)
    assert emu.transmit() == b""                # deaf
    emu.advance(100.0)                          # the reboot at t=100 ends it
    assert emu.transmit().startswith(b"start\n")
