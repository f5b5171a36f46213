"""Resuming a Dynamixel winding after a stop, through the real SDK on the emulator's pty: after a servo's
power loss at each kind of move, Ctrl-C, a power loss along a two-turn ring move, host and servos dying
together; by hand (a new link) and as the user does (`stringbot wind --resume`, resume_plan).  The
world's wraps equal the plan each time.
"""

import pytest

from bundled import SERVO_REALTIME
from dynamixel_helpers import PLANS, machine, patient_servo_link  # noqa: F401  (fixtures)
from dynamixel_helpers import _simulate, _stop, _stringbot, resume
from stringbot.errors import MachineFailure
from stringbot.links.dynamixel import DynamixelLink
from stringbot.motion import hook_steps
from test_dynamixel_sdk import serve
from test_gcode_replay import make_plan

pytestmark = [SERVO_REALTIME, pytest.mark.usefixtures("patient_servo_link")]   # the SDK's answers through a pty


@pytest.mark.parametrize("fault, declare", [("power@37", False), ("power@38", False), ("power@39", False),
                                            ("power@40", False), ("power@41", False), ("power@39", True)])
def test_resume_after_a_servo_power_loss_is_exact(machine, fault, declare):
    """Power cut halfway through each kind of move of a step (approach, out, pitch turn, in)."""
    plan = make_plan(PLANS["long jumps"] * 2)
    server, emu, world = serve(machine, faults=fault)
    try:
        link = DynamixelLink(machine, server.path)
        link.identify()
        steps = hook_steps(plan, machine, start_ring_deg=link.prepare()[0])
        executed = []
        with pytest.raises(MachineFailure, match="lost torque") as failure:
            link.execute(steps, executed.append)
        stop = link.stop_point()            # what the journal keeps
        assert link.position_lost
        link.close()
        assert stop["step_index"] == len(executed) and failure.value.step == len(executed) + 1
        assert stop["move"] is not None and 0 < len(executed) < len(steps) - 1
        assert emu.ring.get("Torque Enable") == 0 and emu.ring.present < 4096   # re-based to one turn
        resume(server, machine, steps, stop, declare)
    finally:
        server.close()
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    assert [w.direction for w in world.wraps] == [s.direction for s in steps]
    assert not world.head_out


def test_ctrl_c_holds_and_resume_is_exact(machine):
    """KeyboardInterrupt lands inside an SDK exchange; hold stops the servos; resume finishes."""
    import signal

    plan = make_plan(PLANS["random"])
    server, emu, world = serve(machine)

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGALRM, interrupt)
    try:
        link = DynamixelLink(machine, server.path)
        link.identify()
        steps = hook_steps(plan, machine, start_ring_deg=link.prepare()[0])
        done = []

        def executed(step):
            done.append(step)
            if len(done) == 3:                   # Ctrl-C lands a moment later, inside an exchange
                signal.setitimer(signal.ITIMER_REAL, 0.01)

        with pytest.raises(KeyboardInterrupt):
            link.execute(steps, executed)
        status = link.hold()
        assert status.state == "Hold" and emu.ring.motion is None and emu.head.motion is None
        stop = link.stop_point()
        done += link.take_executed()
        link.close()
        assert 0 < len(done) < len(steps) and stop["step_index"] in (len(done) - 1, len(done))
        assert status.mpos == (pytest.approx(world.ring_deg, abs=0.03), pytest.approx(world.head_mm, abs=0.03))
        resume(server, machine, steps, stop)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        server.close()
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    assert [w.direction for w in world.wraps] == [s.direction for s in steps]


def test_stringbot_wind_fails_on_a_power_loss_then_resumes_exactly(machine, tmp_path):
    """The user's path: simulate with a fault, `wind --port` exits 1, `wind --port --resume` finishes."""
    import json

    from stringbot.planner import write_plan

    plan = make_plan(PLANS["random"])
    write_plan(plan, tmp_path / "plan.json")
    record = tmp_path / "world.json"
    sim, pty = _simulate(tmp_path, "--record", str(record), "--faults", "power@61")
    try:
        first = _stringbot("wind", str(tmp_path / "plan.json"), "--machine", "dynamixel-ring", "--port", pty,
                           "--yes")
        again = _stringbot("wind", str(tmp_path / "plan.json"), "--machine", "dynamixel-ring", "--port", pty,
                           "--yes", "--resume")
    finally:
        _stop(sim)
    assert first.returncode == 1 and "lost torque (power loss or reboot?)" in first.stderr
    assert "--resume" in first.stderr and "Traceback" not in first.stderr
    assert again.returncode == 0, again.stderr
    doc = json.loads(record.read_text())
    assert [w["pin"] for w in doc["wraps"]] == plan.sequence and doc["collisions"] == []


@pytest.mark.parametrize("fault", ["power@37", "power@38", "power@39",
                                   "power@40", "power@41", "power@60", "power@62", "hardware@39"])
def test_stringbot_resume_after_a_servo_fault_is_exact(machine, tmp_path, fault):
    """The wind loop fails on a servo power loss (or hardware error) halfway through a move of a
    step; `--resume` (resume_plan) re-bases the ring and finishes the winding exactly.  power@37
    strikes one servo turn into a two-turn ring move: the plan's start of the move would be a
    whole turn off as a re-base hint; the journaled last reading is not."""
    from stringbot.planner import write_plan
    from stringbot.winding import load_job, read_journal, wind_plan
    from stringbot.winding.resume import resume_plan

    plan = make_plan(PLANS["long jumps"] * 2)
    write_plan(plan, tmp_path / "plan.json")
    server, emu, world = serve(machine, faults=fault)
    try:
        with pytest.raises(MachineFailure, match="lost torque|hardware error"):
            wind_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path))
        stopped = read_journal(tmp_path / "plan.json.journal").next_step
        result = resume_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path))
    finally:
        server.close()
    assert 0 < stopped < len(plan.sequence) and result.steps_done == len(plan.sequence)
    assert [w.pin for w in world.wraps] == plan.sequence and world.collisions == []
    steps = hook_steps(plan, machine)
    assert [w.direction for w in world.wraps] == [s.direction for s in steps]


def _lose_power_along_the_first_long_ring_move(emu, fraction, min_ticks):
    """Cut the servo power ``fraction`` of the way (by distance) along the first ring motion of at
    least ``min_ticks``; returns [(start, goal, ticks at the cut)] once it has been armed."""
    from firmware_protocol.emulators.dynamixel import Fault, FaultKind

    started, armed = emu._motion_started, []

    def hook(servo):
        started(servo)
        mo = servo.motion
        if armed or servo is not emu.ring or mo is None or abs(mo.goal - mo.start) < min_ticks:
            return
        target = fraction * abs(mo.goal - mo.start)
        lo, hi = mo.t0, mo.end                      # the profile's position is monotonic in time
        for _ in range(60):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if abs(mo.at(mid)[0] - mo.start) < target else (lo, mid)
        armed.append((mo.start, mo.goal, mo.at(hi)[0]))
        emu._events.append((hi, "power_off", Fault(FaultKind.POWER_LOSS, at=0)))

    emu._motion_started = hook
    return armed


@pytest.mark.parametrize("fraction", [0.1, 0.4, 0.6, 0.9])
def test_resume_after_a_power_loss_along_a_two_turn_ring_move(machine, tmp_path, fraction):
    """Power lost 10%, 40%, 60% and 90% of the way along a 180-degree ring jump (two servo turns
    with the 4:1 belt).  The stop record keeps the last reading with torque on, `--resume`
    re-bases from it (not from the move's start, a turn or two off past 25%) and the winding
    ends exactly as planned."""
    from stringbot.planner import write_plan
    from stringbot.winding import load_job, read_journal, wind_plan
    from stringbot.winding.resume import resume_plan

    plan = make_plan([0, 150, 1, 151, 2, 152, 3])
    write_plan(plan, tmp_path / "plan.json")
    server, emu, world = serve(machine)
    tpt = machine["controller.ticks_per_turn"]
    cut = _lose_power_along_the_first_long_ring_move(emu, fraction, 1.9 * tpt)
    try:
        with pytest.raises(MachineFailure, match="lost torque"):
            wind_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path))
        state = read_journal(tmp_path / "plan.json.journal")
        result = resume_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path))
    finally:
        server.close()
    assert len(cut) == 1
    start, goal, at_cut = cut[0]
    assert abs(at_cut - start) == pytest.approx(fraction * abs(goal - start), abs=2)
    stop = state.last_stop
    assert stop["reason"] == "failed" and stop["position_lost"] and 0 < state.next_step < len(plan.sequence)
    # the journaled reading is the last one before the cut: a fraction of a servo turn behind it
    gear = machine["controller.gear_ratio"]
    ring_at_cut = at_cut / tpt * 360.0 / gear
    assert stop["position"] is not None
    assert abs(stop["position"][0] - ring_at_cut) < 0.25 * 360.0 / gear
    assert result.steps_done == len(plan.sequence)
    assert [w.pin for w in world.wraps] == plan.sequence and world.collisions == []
    steps = hook_steps(plan, machine)
    assert [w.direction for w in world.wraps] == [s.direction for s in steps]
    assert not world.head_out


def test_ctrl_c_mid_move_then_stringbot_resume_is_exact(machine, tmp_path):
    import signal

    from stringbot.errors import Interrupted
    from stringbot.planner import write_plan
    from stringbot.winding import load_job, read_journal, wind_plan
    from stringbot.winding.resume import resume_plan

    plan = make_plan(PLANS["random"])
    write_plan(plan, tmp_path / "plan.json")
    server, emu, world = serve(machine)

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    def progress(p):
        if p.done == 3:                          # winding under way: Ctrl-C lands a moment later
            signal.setitimer(signal.ITIMER_REAL, 0.01)

    old = signal.signal(signal.SIGALRM, interrupt)
    try:
        with pytest.raises(Interrupted):
            wind_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path), progress=progress)
        signal.setitimer(signal.ITIMER_REAL, 0)
        stopped = read_journal(tmp_path / "plan.json.journal").next_step
        result = resume_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path))
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        server.close()
    assert 0 < stopped < len(plan.sequence) and result.steps_done == len(plan.sequence)
    assert [w.pin for w in world.wraps] == plan.sequence and world.collisions == []


@pytest.mark.parametrize("fraction", [0.3, 0.7])
def test_host_and_servo_power_lost_together_on_a_long_move_asks_which_pin(machine, tmp_path, fraction):
    """The host dies with the servos' power (no stop record): along a two-turn ring move the
    encoder cannot tell the turn.  Without an operator the resume stops and names the
    candidate pins; with one, the pin that really faces the head is chosen and the
    winding ends exactly as planned."""
    import json

    from stringbot.planner import write_plan
    from stringbot.winding import load_job, wind_plan
    from stringbot.winding.resume import resume_plan

    plan = make_plan([0, 150, 1, 151, 2, 152, 3])
    write_plan(plan, tmp_path / "plan.json")
    server, emu, world = serve(machine)
    tpt = machine["controller.ticks_per_turn"]
    cut = _lose_power_along_the_first_long_ring_move(emu, fraction, 1.9 * tpt)
    journal = tmp_path / "plan.json.journal"
    asked = []

    def facing_pin(question, choices):
        """The operator looks at the ring and names the listed pin nearest the head."""
        asked.append(choices)
        at = (world.ring_deg - machine["ring.pin0_angle_deg"]) / machine.pitch_deg % machine.pins
        P = machine.pins
        return min(choices, key=lambda c: min(abs(int(c) - at), P - abs(int(c) - at)))

    try:
        with pytest.raises(MachineFailure, match="lost torque"):
            wind_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path))
        lines = journal.read_text().splitlines()
        assert json.loads(lines[-1])["kind"] == "stop"
        journal.write_text("\n".join(lines[:-1]) + "\n")      # the host died: no stop record
        ring_before = world.ring_deg
        with pytest.raises(MachineFailure, match="which pin faces the head"):
            resume_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path))
        assert world.ring_deg == ring_before                 # refusing moved nothing
        wraps_before = list(world.wraps)
        result = resume_plan(load_job(tmp_path / "plan.json", "dynamixel-ring", port=server.path),
                             choose=facing_pin)
    finally:
        server.close()
    assert len(cut) == 1 and len(asked) == 1 and len(asked[0]) >= 2
    assert wraps_before == world.wraps[:len(wraps_before)]
    assert result.steps_done == len(plan.sequence)
    assert [w.pin for w in world.wraps] == plan.sequence and world.collisions == []

