"""The motion layer: wrap directions by geometry, the hooking moves, bad plans, the estimate."""

import itertools
import math
import random
import tomllib

import numpy as np
import pytest

from firmware_protocol.machine import bundled_dir, load_machine, machine_from_dict
from stringbot.errors import BadInput
from stringbot.motion import estimate, hook_steps, move_seconds, wrap_direction
from stringbot.planner import Plan
from bundled import MACHINES
from test_gcode_replay import make_plan, random_sequence


def pin_xy(pins):
    """As the plan file draws them: pin 0 at the top, clockwise, y down."""
    a = np.arange(pins) * 2 * np.pi / pins
    return np.stack([0.5 + 0.5 * np.sin(a), 0.5 - 0.5 * np.cos(a)], axis=1)


def turn_sense(xy, a, j, b):
    """+1 when the thread a -> j -> b turns clockwise as drawn (y down), -1 anticlockwise, 0 straight."""
    u, v = xy[j] - xy[a], xy[b] - xy[j]
    cross = u[0] * v[1] - u[1] * v[0]
    return 0 if abs(cross) < 1e-12 else (1 if cross > 0 else -1)


@pytest.mark.parametrize("pins", [5, 12, 300])
def test_auto_wrap_direction_is_the_short_turn_round_the_pin(pins):
    """Checked against plane geometry: the thread turns less than half a turn (does not cross itself).

    Direction +1 hooks from the gap on the lower-number side to the higher one,
    round the outside: clockwise as drawn.  So it must be the sense in which
    the incoming chord turns into the outgoing chord by less than 180 degrees.
    """
    xy = pin_xy(pins)
    rng = random.Random(pins)
    triples = (itertools.permutations(range(pins), 3) if pins < 20 else
               ((rng.randrange(pins), rng.randrange(pins), rng.randrange(pins)) for _ in range(3000)))
    checked = 0
    for a, j, b in triples:
        if a == j or b == j or a == b:
            continue
        assert wrap_direction(a, j, b, pins) == turn_sense(xy, a, j, b), (a, j, b)
        checked += 1
    assert checked > 50


def test_wrap_direction_at_the_ends_and_for_a_return_trip():
    assert wrap_direction(None, 0, 10, 300) == 1        # leave towards the higher side
    assert wrap_direction(None, 0, 290, 300) == -1
    assert wrap_direction(10, 0, None, 300) == -1       # arrive from the higher side: enter there
    assert wrap_direction(290, 0, None, 300) == 1
    assert wrap_direction(40, 0, 40, 300) is None        # either: the caller picks the nearer gap


def steps_for(seq, machine=None):
    machine = machine or load_machine("grbl-ring")
    return machine, hook_steps(make_plan(seq), machine)


def test_each_step_hooks_by_the_physical_model():
    m, steps = steps_for([3, 160, 40, 41, 299, 0])
    inn, out = m["head.in_mm"], m["head.out_mm"]
    assert [s.pin for s in steps] == [3, 160, 40, 41, 299, 0]
    assert [s.index for s in steps] == list(range(6)) and {s.total for s in steps} == {6}
    for s in steps:
        approach, go_out, across, go_in = s.moves[-4:]
        gap = (approach.ring_deg - m["ring.pin0_angle_deg"]) / m.pitch_deg
        assert approach.head_mm == inn and go_out.head_mm == out and go_in.head_mm == inn
        assert go_out.ring_deg == approach.ring_deg and go_in.ring_deg == across.ring_deg
        assert across.ring_deg - go_out.ring_deg == pytest.approx(s.direction * m.pitch_deg)
        # the approach gap is on the approach side of the pin (mod a turn)
        assert (gap - (s.pin - s.direction / 2)) % m.pins == pytest.approx(0, abs=1e-9)
        assert approach.feed == m["ring.feed_deg_per_min"] and go_out.feed == m["head.feed_mm_per_min"]
    assert steps[0].moves[0].ring_deg == 0.0 and steps[0].moves[0].head_mm == inn   # head IN first


def test_ring_turns_the_shorter_way_between_pins():
    m, steps = steps_for([0, 290, 10, 150])
    end = steps[0].moves[-1].ring_deg
    assert steps[1].moves[0].ring_deg < end            # 0 -> 290: back over the seam, not 290 pins on
    assert abs(steps[1].moves[0].ring_deg - end) < 12 * m.pitch_deg
    for a, b in zip(steps[:-1], steps[1:]):
        d = abs(b.moves[0].ring_deg - a.moves[-1].ring_deg) / m.pitch_deg
        assert d <= m.pins / 2 + 1


def test_bad_plans_are_refused_with_one_clear_line():
    m = load_machine("grbl-ring")
    with pytest.raises(BadInput, match="has 8 pins but machine 'grbl-ring' has ring.pins = 300"):
        hook_steps(make_plan([0, 4, 1], pins=8), m)
    plan = make_plan([0, 4, 1])
    plan.connected, plan.sequence, plan.chords = False, [], [(0, 4), (1, 5)]
    with pytest.raises(BadInput, match="disconnected") as info:
        hook_steps(plan, m)
    assert "\n" not in str(info.value)
    with pytest.raises(BadInput, match="start ring position"):
        hook_steps(make_plan([0, 4]), m, start_ring_deg=float("inf"))
    with pytest.raises(BadInput, match="start step is 3; expected a step index 0..2"):
        hook_steps(make_plan([0, 4]), m, start_index=3)


def test_dwell_and_tension_pauses():
    doc = tomllib.loads((bundled_dir() / "grbl-ring.toml").read_text())
    doc["winding"].update(dwell_s=0.5, pause_every=3, pause_s=10.0)
    m = machine_from_dict(doc, source="pauses")
    _, steps = steps_for([1, 50, 2, 60, 3, 70, 4], m)
    assert [s.dwell_s for s in steps] == [0.5, 0.5, 10.5, 0.5, 0.5, 10.5, 0.5]
    plain = estimate(make_plan([1, 50, 2, 60, 3, 70, 4]), load_machine("grbl-ring"))
    assert estimate(make_plan([1, 50, 2, 60, 3, 70, 4]), m).seconds == pytest.approx(
        plain.seconds + 7 * 0.5 + 20.0)


def test_move_seconds_trapezoid_and_triangle():
    # 600 units/min = 10 units/s, accel 10 units/s^2: cruise reached after 5 units (1 s ramp each way)
    assert move_seconds(100, 600, 10) == pytest.approx(100 / 10 + 10 / 10)
    assert move_seconds(10, 600, 10) == pytest.approx(2.0)       # exactly a triangle
    assert move_seconds(2.5, 600, 10) == pytest.approx(2 * math.sqrt(0.25))
    assert move_seconds(0, 600, 10) == 0.0


def test_estimate_figures_follow_from_the_moves():
    m = load_machine("grbl-ring")
    seq = random_sequence(200, seed=5)
    plan = make_plan(seq)
    steps = hook_steps(plan, m)
    est = estimate(plan, m)
    travel = 0.0
    ring = steps[0].moves[0].ring_deg
    for s in steps:
        for mv in s.moves:
            travel += abs(mv.ring_deg - ring)
            ring = mv.ring_deg
    assert est.ring_travel_deg == pytest.approx(travel)
    bound = sum(min((b - a) % 300, (a - b) % 300) for a, b in zip(seq, seq[1:])) * m.pitch_deg
    assert est.lower_bound_deg == pytest.approx(bound)
    assert 1.0 <= est.travel_ratio < 1.05
    chords_m = sum(np.hypot(*(plan.pin_xy[a] - plan.pin_xy[b])) for a, b in zip(seq, seq[1:])) * 0.5
    assert est.thread_m - est.wrap_m == pytest.approx(chords_m, rel=1e-6)
    r = (1.5 + 0.25) / 2 / 1000
    assert 0 < est.wrap_m < len(seq) * math.pi * r                 # each wrap less than half a turn
    assert est.steps == 200 and est.moves == sum(len(s.moves) for s in steps)
    # time: at least the ring travel at full speed plus the head strokes, at most a generous multiple
    floor = travel / (m["ring.feed_deg_per_min"] / 60) + 400 * 12 / (m["head.feed_mm_per_min"] / 60)
    assert floor < est.seconds < 3 * floor


def test_plan_type_is_the_planner_one():
    assert isinstance(make_plan([0, 1]), Plan)


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("direction", ["auto", "cw", "ccw"])
def test_hooking_moves_are_safe_by_construction(name, direction):
    """From the job's start (ring 0, head IN) every move is one axis only, the ring turns only
    with the head fully IN or OUT, and the head crosses the pin circle only at a gap."""
    from stringbot.motion.safety import check_moves
    doc = tomllib.loads((bundled_dir() / f"{name}.toml").read_text())
    doc.setdefault("winding", {})["wrap_direction"] = direction
    machine = machine_from_dict(doc)
    seq = random_sequence(400, machine.pins, seed=7)
    steps = hook_steps(make_plan(seq, machine.pins), machine)
    check_moves(machine, (0.0, machine["head.in_mm"]), [mv for s in steps for mv in s.moves])


def test_unsafe_moves_are_named():
    from stringbot.motion import Move
    from stringbot.motion.safety import UnsafeMove, check_moves
    m = load_machine("grbl-ring")                       # pitch 1.2 deg, gap centres at 0.6 + k * 1.2
    with pytest.raises(UnsafeMove, match="together"):
        check_moves(m, (0.0, 0.0), [Move(0.6, 12.0)])
    with pytest.raises(UnsafeMove, match="neither IN"):
        check_moves(m, (0.6, 6.0), [Move(1.8, 6.0)])
    with pytest.raises(UnsafeMove, match="across the pin circle at ring 0"):
        check_moves(m, (0.0, 0.0), [Move(0.0, 12.0)])
    check_moves(m, (0.0, 0.0), [Move(0.6, 0.0), Move(0.6, 12.0), Move(1.8, 12.0), Move(1.8, 0.0)])
