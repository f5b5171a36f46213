"""End to end through the real SDK on the emulator's pty: the world's wraps equal the plan.

Hooking steps from the motion layer -> DynamixelLink -> dynamixel_sdk -> pty ->
DynamixelEmulator -> World.  No mocks: every byte crosses a real pseudo-terminal.
"""

import numpy as np
import pytest

from firmware_protocol.machine import load_machine
from stringbot.errors import MachineFailure
from stringbot.links.dynamixel import DynamixelLink
from stringbot.motion import hook_steps
from stringbot.planner import Plan
from test_dynamixel_sdk import serve


def make_plan(sequence, pins=300):
    a = np.arange(pins) * 2 * np.pi / pins
    xy = np.stack([0.5 + 0.5 * np.sin(a), 0.5 - 0.5 * np.cos(a)], axis=1)
    return Plan(pins=pins, frame="circle", pin_xy=xy, crop={"cx": 50, "cy": 50, "r": 50},
                sequence=list(sequence), method="hand", parameters={}, stats={},
                source={"path": "hand.png", "sha256": "0" * 64, "width": 100, "height": 100})


def random_sequence(n, pins=300, seed=3):
    rng = np.random.default_rng(seed)
    seq = [int(rng.integers(pins))]
    while len(seq) < n:
        p = int(rng.integers(pins))
        if p != seq[-1]:
            seq.append(p)
    return seq


PLANS = {
    "long jumps": [0, 150, 1, 151, 2, 152, 299, 149, 75, 225],
    "seam": [0, 299, 1, 298, 0, 299, 0, 1, 299],
    "one way round": [0, 100, 200] * 6 + [0],
    "random": random_sequence(40),
}


@pytest.fixture
def machine():
    return load_machine("dynamixel-ring")


@pytest.mark.parametrize("plan_name", sorted(PLANS))
def test_wound_through_the_sdk_the_world_wraps_the_plan(machine, plan_name):
    plan = make_plan(PLANS[plan_name])
    server, emu, world = serve(machine)
    link = DynamixelLink(machine, server.path)
    try:
        link.connect()
        start_ring, _ = link.prepare()
        steps = hook_steps(plan, machine, start_ring_deg=start_ring)
        for step in steps:
            link.run_step(step)
    finally:
        link.close()
        server.close()
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    assert [w.direction for w in world.wraps] == [s.direction for s in steps]
    assert not world.head_out


def test_resume_after_a_servo_power_loss_is_exact(machine):
    plan = make_plan(PLANS["long jumps"] * 2)
    server, emu, world = serve(machine, faults="power_loss@move=37")
    try:
        link = DynamixelLink(machine, server.path)
        link.connect()
        steps = hook_steps(plan, machine, start_ring_deg=link.prepare()[0])
        done = 0
        with pytest.raises(MachineFailure, match="lost torque") as failure:
            for step in steps:
                link.run_step(step)
                done += 1
        hint = link.position()          # what the journal keeps
        link.close()
        assert failure.value.step == done
        assert 0 < done < len(steps) - 1
        wrapped = len(world.wraps)
        # a new process: reconnect, re-base, re-plan from the last finished step, go on
        link = DynamixelLink(machine, server.path)
        link.connect()
        ring_deg, head_mm = link.prepare(resume_at=hint)
        assert (ring_deg, head_mm) == (pytest.approx(world.ring_deg, abs=0.03),
                                       pytest.approx(world.head_mm, abs=0.03))
        redo = steps[done]
        if world.head_out:
            # the failed step was cut while out: back the way it came, through the same gap
            back = [m for m in redo.moves if m.head_mm == machine["head.out_mm"]][0]
            link.move_to(back.ring_deg, back.head_mm)
            link.move_to(back.ring_deg, machine["head.in_mm"])
        rest = hook_steps(make_plan(plan.sequence[done:]), machine, start_ring_deg=link.position()[0])
        for step in rest:
            link.run_step(step)
        link.close()
    finally:
        server.close()
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    assert wrapped == done
