"""FluidNC: the emulator speaks FluidNC's start message, $I and status forms; the host knows it."""

import json

import pytest
import serial

from firmware_protocol import urlhandler
from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.emulators.fluidnc import FluidNcEmulator
from firmware_protocol.emulators.testing import run_exchange
from firmware_protocol.machine import load_machine
from firmware_protocol.tcp import TcpBridge
from firmware_protocol.world import World
from stringbot.links.ports import sim_url
from stringbot.planner.plan_file import write_plan
from test_cli_plan import run
from test_gcode_replay import make_plan, random_sequence

OK = b"ok\r\n"
BOOT = (b"\r\n[MSG:INFO: FluidNC v3.7.8 https://github.com/bdring/FluidNC]\r\n[MSG:INFO: Machine fluidnc-ring]\r\n"
        b"\r\nGrbl 3.7 [FluidNC v3.7.8 (noradio) '$' for help]\r\n")


def test_fluidnc_exchange():
    m = load_machine("fluidnc-ring")
    emu, _ = build_emulator(m)
    assert isinstance(emu, FluidNcEmulator)
    run_exchange(emu, [
        (b"", BOOT),
        (b"$I\n", b"[VER:3.7 FluidNC v3.7.8:]\r\n[OPT:PHSEW]\r\n[MSG:Machine: stringbot simulator]\r\n" + OK),
        (b"G0 A6 X10\n", OK),
        (b"G4 P0\n", OK),
        # A 6 at 44.4444 steps/deg stands on step 267: FluidNC reports whole steps (6.008)
        (b"?", b"<Idle|MPos:10.000,0.000,0.000,6.008|FS:0,0|WCO:0.000,0.000,0.000,0.000>\r\n"),
        (b"?", b"<Idle|MPos:10.000,0.000,0.000,6.008|FS:0,0|Ov:100,100,100>\r\n"),
    ])


def test_a_soft_reset_prints_the_start_message_again():
    m = load_machine("fluidnc-ring")
    emu = FluidNcEmulator(m, world=World(m))
    run_exchange(emu, [(b"", BOOT), (b"\x18", BOOT)])


@pytest.fixture
def served(tmp_path):
    urlhandler.register()
    record = tmp_path / "rec.json"
    port = serial.serial_for_url(sim_url("fluidnc-ring", record=record), timeout=0)
    bridge = TcpBridge(port).start()
    yield bridge, record
    bridge.close()
    port.close()
    urlhandler.protocol_sim.forget()


def test_wind_a_fluidnc_ring_over_telnet(tmp_path, served):
    bridge, record = served
    seq = random_sequence(60, seed=2)
    plan = tmp_path / "p.json"
    write_plan(make_plan(seq), plan)
    code, out, err = run("wind", plan, "--machine", "fluidnc-ring", "--port", bridge.url, "--yes")
    assert code == 0, err
    assert "firmware FluidNC v3.7.8" in out
    rec = json.loads(record.read_text())
    assert [w["pin"] for w in rec["wraps"]] == seq and rec["collisions"] == []


def test_a_machine_file_for_grblhal_is_refused_on_fluidnc(tmp_path, served):
    bridge, _ = served
    text = (load_machine("fluidnc-ring").to_toml().replace('dialect = "fluidnc"', 'dialect = "grblhal"')
            .replace('name = "fluidnc-ring"', 'name = "mine"'))
    mine = tmp_path / "mine.toml"
    mine.write_text(text)
    plan = tmp_path / "p.json"
    write_plan(make_plan([0, 100, 200]), plan)
    code, _, err = run("wind", plan, "--machine", mine, "--port", bridge.url, "--yes")
    assert code == 1
    assert "the machine runs FluidNC v3.7.8, but the machine file says dialect 'grblhal'" in err


def test_a_fluidnc_machine_file_is_refused_on_grbl(tmp_path):
    text = load_machine("fluidnc-ring").to_toml().replace('name = "fluidnc-ring"', 'name = "mine"')
    mine = tmp_path / "mine.toml"
    mine.write_text(text)
    plan = tmp_path / "p.json"
    write_plan(make_plan([0, 100, 200]), plan)
    from test_wind_pty import Simulator
    sim = Simulator(tmp_path, "grblhal-ring")
    try:
        code, _, err = run("wind", plan, "--machine", mine, "--port", sim.pty, "--yes")
    finally:
        sim.stop()
    assert code == 1 and "the machine runs grblHAL" in err and "dialect 'fluidnc'" in err


def test_gcode_for_fluidnc_drives_the_a_axis(tmp_path):
    plan = tmp_path / "p.json"
    write_plan(make_plan([0, 100, 200]), plan)
    code, out, err = run("gcode", plan, "--machine", "fluidnc-ring", "-o", "-")
    assert code == 0, err
    moves = [ln for ln in out.splitlines() if ln.startswith("G1 ")]
    assert moves and all(" A" in ln or " X" in ln for ln in moves) and "G4 P0" in out
