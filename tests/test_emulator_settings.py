"""The simulated firmwares hold their settings: reported as the firmware does, kept across resets
and power cycles, and used by the motion, so a mis-set machine really winds wrong in the world."""

import pytest

from firmware_protocol import settings as fs
from firmware_protocol.emulators.factory import SimulatorError, build_emulator
from firmware_protocol.emulators.testing import run_exchange
from firmware_protocol.machine import load_machine

from test_dynamixel_emulator import read, settle, write

pytestmark = pytest.mark.timeout(30)

OK = b"ok\r\n"


def grbl(name="grbl-ring", *settings, faults=None):
    emu, world = build_emulator(load_machine(name), settings=settings, faults=faults)
    emu.transmit()
    return emu, world


def lines(emu, text):
    """What the firmware answers ``text``, once nothing more is pending, as lines."""
    emu.receive(text)
    out = emu.transmit()
    while emu.next_event_in() is not None:
        emu.advance(None)
        out += emu.transmit()
    got = out.decode("latin-1").replace("\r\n", "\n").splitlines()
    return [x for x in got if x != "echo:busy: processing"]     # Marlin's keepalive while moving


# ---- GRBL / grblHAL ----------------------------------------------------------------------------

def test_grbl_reports_the_machine_files_settings_as_grbl_prints_them():
    emu, _ = grbl()
    got = lines(emu, b"$$\n")
    assert got[-1] == "ok"
    assert {"$100=44.444", "$101=80.000", "$110=7200.000", "$111=3000.000", "$120=360.000",
            "$121=500.000", "$22=0", "$20=0", "$13=0"} <= set(got)
    assert fs.parse_settings(got)[100] == 44.444


def test_grblhal_reports_its_rotary_axis_and_takes_settings_past_255():
    emu, _ = grbl("grblhal-ring")
    got = fs.parse_settings(lines(emu, b"$$\n"))
    assert (got[103], got[100], got[22], got[376], got[538]) == (88.889, 80.0, 1, 1, 0)
    run_exchange(emu, [(b"$376=0\n", OK), (b"$999=1\n", b"error:3\r\n")])
    assert fs.parse_settings(lines(emu, b"$$\n"))[376] == 0


def test_a_steps_setting_moves_the_reported_position_not_the_motors_and_scales_motion():
    emu, world = grbl()
    run_exchange(emu, [(b"G0 X90\nG4 P0\n", OK + OK)])
    assert world.ring_deg == pytest.approx(90.0, abs=0.5 / 44.4444)   # whole steps
    run_exchange(emu, [(b"$100=40\n", OK)])
    assert world.ring_deg == pytest.approx(90.0, abs=0.5 / 44.4444)   # GRBL counts steps: they stay
    st = lines(emu, b"?")[0]
    assert st.startswith("<Idle|MPos:100.000,0.000,0.000")         # 90 * 44.4444 / 40
    run_exchange(emu, [(b"G0 X110\nG4 P0\n", OK + OK)])
    assert world.ring_deg == pytest.approx(90.0 + 10 * 40 / 44.4444)   # 10 units are 9 degrees now


def test_settings_survive_a_soft_reset_and_a_power_cycle():
    emu, _ = grbl("grbl-ring", faults="power@3")
    run_exchange(emu, [(b"$100=40\n", OK), (b"\x18", b"\r\nGrbl 1.1h ['$' for help]\r\n")])
    assert fs.parse_settings(lines(emu, b"$$\n"))[100] == 40.0     # line 2
    emu.receive(b"G0 X1\n")                                         # line 3: the power goes
    assert not emu.port_up
    emu.reconnect()
    assert emu.transmit() == b"\r\nGrbl 1.1h ['$' for help]\r\n"
    assert fs.parse_settings(lines(emu, b"$$\n"))[100] == 40.0


def test_max_rate_limits_the_ring_speed():
    times = []
    for rate in (7200, 3600):
        emu, world = grbl("grbl-ring", f"$110={rate}")
        run_exchange(emu, [(b"G0 X360\nG4 P0\n", OK + OK)])
        times.append(emu.now)
    # 360 deg at 120 deg/s, 360 deg/s^2: 1/3 s ramps + 320 deg cruise; at 60 deg/s: 1/6 s ramps + 350 deg
    assert times == [pytest.approx(2 / 3 + 320 / 120), pytest.approx(1 / 3 + 350 / 60)]


def test_homing_disabled_refuses_h_with_error_5_and_enabled_starts_locked():
    emu, _ = grbl("grblhal-ring", "$22=0")
    run_exchange(emu, [(b"$H\n", b"error:5\r\n")])
    emu, _ = grbl("grbl-ring", "$22=1")
    assert lines(emu, b"?")[0].startswith("<Alarm")


def test_presets_are_checked_like_the_firmware_checks_them():
    with pytest.raises(SimulatorError, match=r"'\$20=1'.*error:10"):
        grbl("grbl-ring", "$20=1")                                  # soft limits need homing
    with pytest.raises(SimulatorError, match=r"expected '\$N=VALUE'"):
        grbl("grbl-ring", "M92 A40")
    with pytest.raises(SimulatorError, match="M92 takes X, Y, Z, A"):
        build_emulator(load_machine("marlin-ring"), settings=["M92 Q40"])
    with pytest.raises(SimulatorError, match="not a writable control-table item"):
        build_emulator(load_machine("dynamixel-ring"), settings=["ring:Drive Mod=1"])


# ---- Marlin -----------------------------------------------------------------------------------

def marlin(*settings, faults=None):
    emu, world = build_emulator(load_machine("marlin-ring"), settings=settings, faults=faults)
    boot = emu.transmit().decode().splitlines()
    return emu, world, boot


def test_marlin_m503_reports_the_machine_files_settings():
    emu, _, boot = marlin()
    assert "echo:Hardcoded Default Settings Loaded" in boot
    assert lines(emu, b"M503\n") == [
        "echo:; Steps per unit:", "echo:  M92 X80.00 Y80.00 Z400.00 A44.44",
        "echo:; Max feedrates (units/s):", "echo:  M203 X300.00 Y40.00 Z5.00 A120.00",
        "echo:; Max Acceleration (units/s2):", "echo:  M201 X3000.00 Y400.00 Z100.00 A300.00",
        "echo:; Acceleration (units/s2) (P<print-accel> R<retract-accel> T<travel-accel>):",
        "echo:  M204 P3000.00 R3000.00 T3000.00",
        "echo:; Soft Endstops:", "echo:  M211 S1 ; ON",
        "echo:  Min:  X0.00 Y0.00 Z0.00 A-7200.00   Max:  X200.00 Y200.00 Z200.00 A7200.00",
        "ok"]
    s = fs.parse_m503(lines(emu, b"M503\n"))
    assert (s.steps["A"], s.max_feed["Y"], s.accel["T"], s.soft_endstops, s.soft_min["A"]) == \
        (44.44, 40.0, 3000.0, True, -7200.0)


def test_marlin_m92_scales_motion_and_lasts_until_reset_unless_m500_stored_it():
    emu, world, _ = marlin(faults="reset@6")
    assert lines(emu, b"M92 A40\n") == ["ok"]                        # line 1
    assert lines(emu, b"G0 A10 F7200\nM400\n") == ["ok", "ok"]         # lines 2, 3
    assert world.ring_deg == pytest.approx(10 * 40 / 44.4444)
    assert lines(emu, b"M92\n") == ["echo:; Steps per unit:", "echo:  M92 X80.00 Y80.00 Z400.00 A40.00", "ok"]
    assert lines(emu, b"M500\n") == ["echo:Settings Stored (444 bytes; crc 23981)", "ok"]   # line 5
    boot = lines(emu, b"M92\n")                                         # line 6: the firmware resets
    assert "echo:V86 stored settings retrieved (444 bytes; crc 23981)" in boot
    assert fs.parse_m503(lines(emu, b"M503\n")).steps["A"] == 40.0


def test_marlin_unsaved_settings_are_lost_at_reset():
    emu, _, _ = marlin(faults="reset@2")
    assert lines(emu, b"M92 A40\n") == ["ok"]
    assert "echo:Hardcoded Default Settings Loaded" in lines(emu, b"M400\n")
    assert fs.parse_m503(lines(emu, b"M503\n")).steps["A"] == 44.44


def test_marlin_software_endstops_clamp_the_ring_until_turned_off():
    emu, world, _ = marlin("M201 A3000", "M203 A1000")
    assert lines(emu, b"G0 A8000 F60000\nM400\n") == ["ok", "ok"]
    assert world.ring_deg == pytest.approx(8000.0)          # not homed: Marlin has no limits to trust
    assert lines(emu, b"G28\nG0 A8000 F60000\nM400\n") == ["ok", "ok", "ok"]
    assert world.ring_deg == pytest.approx(7200.0, abs=0.5 / 44.4444)  # stopped at the endstop
    assert lines(emu, b"M211 S0\nG0 A8000\nM400\n") == ["ok", "ok", "ok"]
    assert world.ring_deg == pytest.approx(8000.0)


def test_marlin_preset_is_how_it_was_built():
    emu, _, boot = marlin("M92 A40", "M211 S0")
    assert "echo:Hardcoded Default Settings Loaded" in boot
    s = fs.parse_m503(lines(emu, b"M503\n"))
    assert (s.steps["A"], s.soft_endstops) == (40.0, False)


# ---- Dynamixel ----------------------------------------------------------------------------------

def dxl(*settings):
    emu, world = build_emulator(load_machine("dynamixel-ring"), settings=settings)
    for sid in (1, 2):
        assert write(emu, sid, "Operating Mode", 4 if sid == 1 else 3) == 0
    return emu, world


def test_dynamixel_reverse_mode_turns_the_ring_the_other_way():
    for drive, sign in ((0, 1), (1, -1)):
        emu, world = dxl(f"ring:Drive Mode={drive}")
        assert read(emu, 1, "Drive Mode") == drive
        start = read(emu, 1, "Present Position")
        assert write(emu, 1, "Torque Enable", 1) == 0
        assert write(emu, 1, "Goal Position", start + 4096) == 0        # one servo turn: 90 ring degrees
        assert settle(emu)
        assert read(emu, 1, "Present Position") == start + 4096
        assert world.ring_deg == pytest.approx(sign * 90.0)


def test_dynamixel_time_based_profile_takes_profile_velocity_milliseconds():
    emu, world = dxl("ring:Drive Mode=4")
    for name, value in (("Profile Velocity", 800), ("Profile Acceleration", 200), ("Torque Enable", 1)):
        assert write(emu, 1, name, value) == 0
    assert write(emu, 1, "Goal Position", read(emu, 1, "Present Position") + 1024) == 0
    assert emu.servos[1].motion.duration == pytest.approx(0.8)     # whatever the distance
    assert settle(emu)
    assert world.ring_deg == pytest.approx(22.5)


def test_dynamixel_eeprom_presets_survive_a_power_cycle():
    emu, _ = dxl("head:Velocity Limit=100")
    emu.servos[2].power_up(emu.now)
    assert read(emu, 2, "Velocity Limit") == 100


# ---- how a user mis-sets a simulated machine: sim://?set=... and simulate --set --------------------

def test_sim_url_takes_set_any_number_of_times(tmp_path):
    import serial

    from firmware_protocol import urlhandler
    from firmware_protocol.urlhandler import protocol_sim
    urlhandler.register()
    url = f"sim://?machine=marlin-ring&set=M92%20A40&set=M211%20S0&record={tmp_path / 'r.json'}"
    assert protocol_sim.parse_url(url)["set"] == ["M92 A40", "M211 S0"]
    try:
        port = serial.serial_for_url(url, timeout=0.05)
        port.write(b"M503\n")
        s = fs.parse_m503(port.read(4000).decode().splitlines())
        assert (s.steps["A"], s.soft_endstops) == (40.0, False)
        port.close()
    finally:
        protocol_sim.forget(url)
    with pytest.raises(serial.SerialException, match=r"set: '\$100=x': expected '\$N=VALUE'"):
        serial.serial_for_url(f"sim://?machine=grbl-ring&set=$100=x&record={tmp_path / 'q.json'}")


def test_simulate_with_a_bad_set_is_one_line_and_exit_2(tmp_path, capsys):
    from stringbot.cli import main
    with pytest.raises(SystemExit) as info:
        main(["simulate", "--machine", "grbl-ring", "--pty", str(tmp_path / "p"), "--set", "$20=1"])
    err = capsys.readouterr().err
    assert info.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "'$20=1'" in err and "error:10" in err and not (tmp_path / "p").exists()
