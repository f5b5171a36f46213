"""The emitted G-code, replayed against the physical world: exact wraps, zero collisions."""

import random
import tomllib

import numpy as np
import pytest

from bundled import GCODE_MACHINES
from firmware_protocol.machine import bundled_dir, load_machine, machine_from_dict
from firmware_protocol.world import World
from gcode_replay import replay
from stringbot.motion import gcode_job, hook_steps
from stringbot.planner import Plan


def make_plan(sequence, pins=300):
    a = np.arange(pins) * 2 * np.pi / pins
    xy = np.stack([0.5 + 0.5 * np.sin(a), 0.5 - 0.5 * np.cos(a)], axis=1)
    return Plan(pins=pins, frame="circle", pin_xy=xy, crop={"cx": 50, "cy": 50, "r": 50},
                sequence=list(sequence), method="hand", parameters={}, stats={},
                source={"path": "hand.png", "sha256": "0" * 64, "width": 100, "height": 100})


def random_sequence(n, pins=300, seed=1):
    rng = random.Random(seed)
    seq = [rng.randrange(pins)]
    while len(seq) < n:
        p = rng.randrange(pins)
        if p != seq[-1]:
            seq.append(p)
    return seq


PLANS = {
    "long jumps": [0, 150, 1, 151, 2, 152, 299, 149, 75, 225],
    "neighbours": [10, 11, 12, 13, 12, 11, 10, 9],
    "seam": [0, 299, 1, 298, 0, 299, 0, 1, 299],
    "revisits": [5, 100, 5, 100, 5, 6, 5],
    "one way round": [0, 100, 200] * 12 + [0],          # drifts the ring turn after turn
    "random": random_sequence(300),
}


def test_there_are_three_gcode_machines():
    assert {"grbl-ring", "grblhal-ring", "marlin-ring"} <= set(GCODE_MACHINES)


@pytest.mark.parametrize("name", GCODE_MACHINES)
@pytest.mark.parametrize("plan_name", sorted(PLANS))
def test_replayed_gcode_wraps_exactly_the_plan(name, plan_name):
    machine = load_machine(name)
    plan = make_plan(PLANS[plan_name])
    world, (lo, hi) = replay(gcode_job(plan, machine), machine)
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    steps = hook_steps(plan, machine)
    assert [w.direction for w in world.wraps] == [s.direction for s in steps]
    assert not world.head_out
    bound = machine["ring.travel_deg"]
    pin0 = machine["ring.pin0_angle_deg"]
    assert pin0 - bound - 1e-6 <= lo and hi <= pin0 + bound + 1e-6


def tight(name, travel):
    doc = tomllib.loads((bundled_dir() / f"{name}.toml").read_text())
    doc["ring"]["travel_deg"] = travel
    return machine_from_dict(doc, source="tight")


@pytest.mark.parametrize("name", GCODE_MACHINES)
def test_ring_stays_within_a_tight_travel_bound(name):
    machine = tight(name, 360.0)
    plan = make_plan(PLANS["one way round"] + random_sequence(200, seed=7))
    world, (lo, hi) = replay(gcode_job(plan, machine), machine)
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    pin0 = machine["ring.pin0_angle_deg"]
    assert pin0 - 360.0 - 1e-6 <= lo and hi <= pin0 + 360.0 + 1e-6
    # the unconstrained machine would have drifted past that bound on the same plan
    _, (lo2, hi2) = replay(gcode_job(plan, load_machine(name)), load_machine(name))
    assert hi2 - pin0 > 360.0 or pin0 - lo2 > 360.0


@pytest.mark.parametrize("fixed, direction", [("cw", 1), ("ccw", -1)])
def test_fixed_wrap_direction_is_obeyed(fixed, direction):
    doc = tomllib.loads((bundled_dir() / "grbl-ring.toml").read_text())
    doc["winding"]["wrap_direction"] = fixed
    machine = machine_from_dict(doc, source="fixed")
    plan = make_plan(PLANS["long jumps"])
    world, _ = replay(gcode_job(plan, machine), machine)
    assert world.collisions == []
    assert [(w.pin, w.direction) for w in world.wraps] == [(p, direction) for p in plan.sequence]


def test_hook_steps_replayed_directly_on_the_world():
    """The moves themselves (as the Dynamixel link would send them), without G-code rounding."""
    machine = load_machine("grbl-ring")
    plan = make_plan(random_sequence(500, seed=3))
    world = World(machine)
    for step in hook_steps(plan, machine):
        before = len(world.wraps)
        for mv in step.moves:
            world.move(mv.ring_deg, mv.head_mm)
        assert [(w.pin, w.direction) for w in world.wraps[before:]] == [(step.pin, step.direction)]
        assert not world.head_out
    assert world.collisions == []


def test_resuming_from_a_later_ring_position():
    """hook_steps(start_ring_deg=...) plans from where the ring is, e.g. several turns away."""
    machine = load_machine("grbl-ring")
    plan = make_plan([40, 200, 7])
    world = World(machine)
    world.move(725.0, machine["head.in_mm"])      # two turns and a bit, head IN
    for step in hook_steps(plan, machine, start_ring_deg=725.0):
        for mv in step.moves:
            world.move(mv.ring_deg, mv.head_mm)
    assert [w.pin for w in world.wraps] == [40, 200, 7] and world.collisions == []
    assert abs(world.ring_deg - 725.0) < 360.0     # it did not unwind back to zero


@pytest.mark.parametrize("start", [1, 137, 299])
def test_resuming_mid_plan_keeps_the_plans_wrap_directions(start):
    machine = load_machine("grblhal-ring")
    plan = make_plan(random_sequence(300, seed=11))
    full = hook_steps(plan, machine)
    world = World(machine)
    ring_at = 3 * 360.0 + 0.6                         # wherever the ring was left, head IN
    world.move(ring_at, machine["head.in_mm"])
    rest = hook_steps(plan, machine, start_ring_deg=ring_at, start_index=start)
    assert [s.index for s in rest] == list(range(start, 300))
    assert [s.direction for s in rest] == [s.direction for s in full[start:]]
    for step in rest:
        for mv in step.moves:
            world.move(mv.ring_deg, mv.head_mm)
    assert [w.pin for w in world.wraps] == plan.sequence[start:] and world.collisions == []
    assert hook_steps(plan, machine, start_index=300) == []


@pytest.mark.parametrize("seed", range(12))
def test_random_machines_and_plans_replay_exactly(seed):
    """Other pin counts, pin 0 offsets, head orientations, dialects and travel bounds."""
    rng = random.Random(seed)
    pins = rng.choice([3, 4, 5, 7, 64, 180, 301, 600])
    dialect, ring_axis, head_axis = rng.choice([("grbl", "Z", "X"), ("grblhal", "B", "Y"), ("marlin", "C", "Z")])
    inn = rng.uniform(-50, 50)
    doc = {
        "name": f"random-{seed}",
        "ring": {"pins": pins, "diameter_mm": 600.0, "pin_diameter_mm": 1.0,
                 "pin0_angle_deg": rng.uniform(-400, 400), "travel_deg": rng.choice([360.0, 500.0, 36000.0])},
        "head": {"in_mm": inn, "out_mm": inn + rng.choice([-1, 1]) * rng.uniform(3, 20)},
        "controller": {"kind": "gcode", "dialect": dialect, "ring_axis": ring_axis, "head_axis": head_axis,
                       "homing": rng.random() < 0.5, "home_ring_deg": rng.uniform(-10, 10)},
        "thread": {"diameter_mm": 0.3},
        "winding": {"wrap_direction": rng.choice(["auto", "auto", "cw", "ccw"])},
    }
    machine = machine_from_dict(doc, source="random")
    plan = make_plan(random_sequence(150, pins=pins, seed=seed), pins=pins)
    world, (lo, hi) = replay(gcode_job(plan, machine), machine)
    assert world.collisions == []
    assert [w.pin for w in world.wraps] == plan.sequence
    travel, pin0 = machine["ring.travel_deg"], machine["ring.pin0_angle_deg"]
    # within the bound, apart from where the job starts (the world's 0, or the home switch)
    start = machine["controller.home_ring_deg"] if machine["controller.homing"] else 0.0
    assert min(pin0 - travel, start, 0.0) - 1e-6 <= lo and hi <= max(pin0 + travel, start, 0.0) + 1e-6
    steps = hook_steps(plan, machine, start_ring_deg=start)
    inside = [mv.ring_deg for s in steps for mv in s.moves][1:]
    assert pin0 - travel - 1e-6 <= min(inside) and max(inside) <= pin0 + travel + 1e-6
