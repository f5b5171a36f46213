"""End to end through the real SDK on the emulator's pty: the world's wraps equal the plan.

Hooking steps from the motion layer -> DynamixelLink -> dynamixel_sdk -> pty ->
DynamixelEmulator -> World.  No mocks: every byte crosses a real pseudo-terminal.
How a winding stops and fails (Ctrl-C, a pulled cable, the simulator killed) is here;
resuming after a stop is in test_dynamixel_resume.py.
"""

import pytest

from bundled import SERVO_REALTIME
from dynamixel_helpers import PLANS, machine, patient_servo_link  # noqa: F401  (fixtures)
from dynamixel_helpers import _simulate, _stop, _stringbot
from stringbot.links.dynamixel import DynamixelLink
from stringbot.motion import hook_steps
from test_dynamixel_sdk import serve
from test_gcode_replay import make_plan

pytestmark = [SERVO_REALTIME, pytest.mark.usefixtures("patient_servo_link")]   # the SDK's answers through a pty


@pytest.mark.parametrize("plan_name", sorted(PLANS))
def test_wound_through_the_sdk_the_world_wraps_the_plan(machine, plan_name):
    plan = make_plan(PLANS[plan_name])
    server, emu, world = serve(machine)
    link = DynamixelLink(machine, server.path)
    moved = []
    link.on_move = lambda step, k: moved.append((step.index, k))
    try:
        link.connect()
        start_ring, _ = link.prepare()
        steps = hook_steps(plan, machine, start_ring_deg=start_ring)
        for step in steps:
            link.run_step(step)
    finally:
        link.close()
        server.close()
    assert moved == [(s.index, k) for s in steps for k in range(len(s.moves))]
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    assert [w.direction for w in world.wraps] == [s.direction for s in steps]
    assert not world.head_out


def test_wound_over_sim_url_with_the_worlds_record(machine, tmp_path):
    import json

    from firmware_protocol.urlhandler.protocol_sim import forget
    from stringbot.links import open_link

    plan = make_plan(PLANS["seam"])
    record = tmp_path / "world.json"
    url = f"sim://?machine=dynamixel-ring&record={record}"
    link = open_link(url, machine)
    try:
        assert link.identify().name == "Dynamixel XM430-W350"
        steps = hook_steps(plan, machine, start_ring_deg=link.prepare(home=False)[0])
        link.execute(steps)
        link.finish()
    finally:
        link.close()
        forget(url)
    doc = json.loads(record.read_text())
    assert [w["pin"] for w in doc["wraps"]] == plan.sequence and doc["collisions"] == []


def test_bad_fault_in_a_sim_url_is_bad_input(machine):
    from stringbot.errors import BadInput
    from stringbot.links import open_link

    with pytest.raises(BadInput, match="expected power_loss@move=N"):
        open_link("sim://?machine=dynamixel-ring&faults=explode@3", machine)


def test_the_ring_stays_within_the_travel_bound_inside_the_extended_range(machine):
    """A plan that keeps going one way round: the motion layer's bound holds on the servo."""
    values = dict(machine.values)
    values["ring.travel_deg"] = 720.0
    tight = type(machine)(machine.name, machine.path, values)
    plan = make_plan([0, 100, 200] * 12 + [0])
    server, emu, world = serve(tight)
    seen = []
    move = world.move
    world.move = lambda r, h: (seen.append(emu.ring.present), move(r, h))
    link = DynamixelLink(tight, server.path)
    try:
        link.identify()
        steps = hook_steps(plan, tight, start_ring_deg=link.prepare()[0])
        link.execute(steps)
    finally:
        link.close()
        server.close()
    assert [w.pin for w in world.wraps] == plan.sequence and world.collisions == []
    bound = link.ring_ticks(720.0)
    assert max(seen) - min(seen) > link.ring_ticks(360.0)          # it did turn a lot ...
    assert -bound <= min(seen) and max(seen) <= bound              # ... but never past the bound


def test_the_wind_loop_drives_the_servos_through_the_pty(machine, tmp_path):
    """stringbot.winding's session and Winder, the link it opens for kind = dynamixel, the SDK on a pty."""
    from stringbot.planner import write_plan
    from stringbot.winding import load_job, read_journal, wind_plan

    plan = make_plan(PLANS["random"])
    path = tmp_path / "plan.json"
    write_plan(plan, path)
    server, emu, world = serve(machine)
    seen = []
    try:
        result = wind_plan(load_job(path, "dynamixel-ring", port=server.path), progress=seen.append)
    finally:
        server.close()
    assert result.steps_done == len(plan.sequence) and result.firmware.startswith("Dynamixel XM430-W350")
    assert [p.done for p in seen] == list(range(1, len(plan.sequence) + 1))
    assert read_journal(result.journal).finished
    assert [w.pin for w in world.wraps] == plan.sequence and world.collisions == []


def test_stringbot_simulate_serves_the_sdk_through_port_path(machine, tmp_path):
    """`stringbot simulate --machine dynamixel-ring --pty PATH` in its own process; the SDK opens PATH."""
    import json

    from stringbot.planner import write_plan
    from stringbot.winding import load_job, wind_plan

    plan = make_plan(PLANS["long jumps"])
    write_plan(plan, tmp_path / "plan.json")
    record = tmp_path / "world.json"
    sim, pty = _simulate(tmp_path, "--record", str(record))
    try:
        result = wind_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=pty))
    finally:
        out, err = _stop(sim)
    assert result.steps_done == len(plan.sequence), err
    doc = json.loads(record.read_text())
    assert [w["pin"] for w in doc["wraps"]] == plan.sequence and doc["collisions"] == []


def test_ctrl_c_through_the_wind_loop_holds_and_journals_the_position(machine, tmp_path):
    from stringbot.errors import Interrupted
    from stringbot.planner import write_plan
    from stringbot.winding import load_job, read_journal, wind_plan

    plan = make_plan(PLANS["random"])
    write_plan(plan, tmp_path / "plan.json")
    server, emu, world = serve(machine)

    def progress(p):
        if p.done == 5:
            raise KeyboardInterrupt

    try:
        with pytest.raises(Interrupted, match="5 of 40 steps done"):
            wind_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path), progress=progress)
    finally:
        server.close()
    state = read_journal(tmp_path / "plan.json.journal")
    stop = state.last_stop
    assert state.next_step == 5 and stop["reason"] == "interrupted"
    assert stop["position"] == [pytest.approx(world.ring_deg, abs=0.03), pytest.approx(world.head_mm, abs=0.03)]
    assert [w.pin for w in world.wraps] == plan.sequence[:5] and not world.head_out
    assert emu.ring.motion is None and emu.ring.get("Torque Enable") == 1    # held, thread tensioned


def _wait_for_the_port(pty, timeout=20.0):
    import os
    import time
    deadline = time.monotonic() + timeout
    while not os.path.exists(pty) and time.monotonic() < deadline:
        time.sleep(0.05)


def _error_lines(stderr):
    return [line for line in stderr.splitlines() if line.startswith("stringbot: error:")]


def test_a_pulled_cable_is_one_line_and_a_stop_record_then_resume_finishes(machine, tmp_path):
    """``unplug@30``: the simulator closes its pty halfway through the 30th servo move (the servos,
    still powered, finish it), then opens it again: ``wind`` exits 1 with one line and the resume
    hint, the journal holds the stop; ``--resume`` winds the rest exactly."""
    import json

    from stringbot.planner import write_plan
    from stringbot.winding import read_journal

    plan = make_plan(PLANS["random"])
    write_plan(plan, tmp_path / "plan.json")
    record = tmp_path / "world.json"
    sim, pty = _simulate(tmp_path, "--record", str(record), "--faults", "unplug@30")
    try:
        first = _stringbot("wind", str(tmp_path / "plan.json"), "--machine", "dynamixel-ring", "--port", pty,
                           "--yes")
        stop = read_journal(tmp_path / "plan.json.journal").last_stop
        _wait_for_the_port(pty)            # as a user would: the cable plugged back in, its device there
        again = _stringbot("wind", str(tmp_path / "plan.json"), "--machine", "dynamixel-ring", "--port", pty,
                           "--yes", "--resume")
    finally:
        _stop(sim)
    assert first.returncode == 1 and "Traceback" not in first.stderr, first.stderr
    [line] = _error_lines(first.stderr)
    assert f"lost the port {pty}" in line and "--resume" in line
    assert stop["reason"] == "failed" and "lost the port" in stop["error"]
    assert again.returncode == 0, again.stderr
    doc = json.loads(record.read_text())
    assert [w["pin"] for w in doc["wraps"]] == plan.sequence and doc["collisions"] == []


def test_the_simulator_killed_mid_winding_is_one_line_and_a_stop_record(machine, tmp_path):
    """The bus dies for good (the simulator's process is killed, its pty with it) while winding."""
    import subprocess
    import sys
    import time

    from stringbot.planner import write_plan
    from stringbot.winding import read_journal

    plan = make_plan(PLANS["random"] * 3)
    write_plan(plan, tmp_path / "plan.json")
    journal = tmp_path / "plan.json.journal"
    sim, pty = _simulate(tmp_path)
    wind = subprocess.Popen([sys.executable, "-c", "from stringbot.cli import main; main()", "wind",
                             str(tmp_path / "plan.json"), "--machine", "dynamixel-ring", "--port", pty, "--yes"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for _ in range(1200):                    # until a few steps are wound
            if journal.exists() and journal.read_text().count('"kind":"done"') >= 5 or wind.poll() is not None:
                break
            time.sleep(0.05)
        sim.kill()
        sim.communicate(timeout=10)
        _, err = wind.communicate(timeout=120)
    finally:
        for proc in (sim, wind):
            if proc.poll() is None:
                proc.kill()
    assert wind.returncode == 1 and "Traceback" not in err, err
    [line] = _error_lines(err)
    assert f"lost the port {pty}" in line and "--resume" in line
    state = read_journal(journal)
    assert state.last_stop["reason"] == "failed" and "lost the port" in state.last_stop["error"]
    assert 5 <= len(state.done) < len(plan.sequence)

