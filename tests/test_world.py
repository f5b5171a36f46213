"""The simulator's physical world by itself: wraps, collisions and the record."""

import json
import tomllib

import pytest

from firmware_protocol.machine import bundled_dir, load_machine, machine_from_dict
from firmware_protocol.world import World, Wrap


@pytest.fixture(scope="module")
def machine():
    return load_machine("grbl-ring")


def variant(**changes):
    """grbl-ring with ``section.key`` values replaced."""
    doc = tomllib.loads((bundled_dir() / "grbl-ring.toml").read_text())
    for dotted, value in changes.items():
        section, key = dotted.split(".")
        doc[section][key] = value
    return machine_from_dict(doc, source="variant")


def gap(m, g):
    """Ring degrees with the centre of the gap between pins g and g + 1 at the station."""
    return m.pin_angle(g) + m.pitch_deg / 2


def hook(w, m, pin, direction, *, turns=0):
    """Hook ``pin`` by the physical model: approach gap, OUT, one pitch, IN."""
    base = 360.0 * turns
    a = base + (gap(m, pin - 1) if direction > 0 else gap(m, pin))
    b = a + direction * m.pitch_deg
    w.move(a, m["head.in_mm"])
    w.move(a, m["head.out_mm"])
    w.move(b, m["head.out_mm"])
    return w.move(b, m["head.in_mm"])


def test_starts_at_zero_head_in(machine):
    w = World(machine)
    assert (w.ring_deg, w.head_mm) == (0.0, machine["head.in_mm"])
    assert not w.head_out and w.wraps == [] and w.collisions == []


@pytest.mark.parametrize("direction", [1, -1])
def test_hooking_one_pin_each_way(machine, direction):
    w = World(machine)
    new = hook(w, machine, 17, direction)
    assert new == [Wrap(17, direction)]
    assert w.wraps == [Wrap(17, direction)] and w.collisions == []
    assert not w.head_out


def test_head_out_flag_follows_the_circle(machine):
    w = World(machine)
    w.move(gap(machine, 3), machine["head.in_mm"])
    w.move(gap(machine, 3), machine.circle_mm)
    assert not w.head_out                     # ON the circle is not out
    w.move(gap(machine, 3), machine["head.out_mm"])
    assert w.head_out


def test_out_and_back_through_the_same_gap_wraps_nothing(machine):
    w = World(machine)
    a = gap(machine, 40)
    w.move(a, machine["head.in_mm"])
    w.move(a, machine["head.out_mm"])
    w.move(a + 5 * machine.pitch_deg, machine["head.out_mm"])   # wander while out
    w.move(a, machine["head.out_mm"])
    w.move(a, machine["head.in_mm"])
    assert w.wraps == [] and w.collisions == []


def test_several_pins_passed_while_out_are_wrapped_in_passing_order(machine):
    w = World(machine)
    a = gap(machine, 10)                       # between 10 and 11
    w.move(a, machine["head.in_mm"])
    w.move(a, machine["head.out_mm"])
    w.move(a + 3 * machine.pitch_deg, machine["head.out_mm"])
    w.move(a + 3 * machine.pitch_deg, machine["head.in_mm"])
    assert w.wraps == [Wrap(11, 1), Wrap(12, 1), Wrap(13, 1)]
    b = gap(machine, 20)
    w.move(b, machine["head.in_mm"])
    w.move(b, machine["head.out_mm"])
    w.move(b - 2 * machine.pitch_deg, machine["head.out_mm"])
    w.move(b - 2 * machine.pitch_deg, machine["head.in_mm"])
    assert w.wraps[3:] == [Wrap(20, -1), Wrap(19, -1)]
    assert w.collisions == []


def test_wrap_around_pin_zero_and_the_last_pin(machine):
    w = World(machine)
    n = machine.pins
    assert hook(w, machine, 0, -1) == [Wrap(0, -1)]           # from gap 0|1 down to gap -1|0
    assert hook(w, machine, n - 1, 1) == [Wrap(n - 1, 1)]
    # across the seam while out: gap n-2|n-1 up to gap 0|1 passes n-1 then 0
    a = gap(machine, n - 2)
    w.move(a, machine["head.in_mm"])
    w.move(a, machine["head.out_mm"])
    w.move(a + 2 * machine.pitch_deg, machine["head.out_mm"])
    w.move(a + 2 * machine.pitch_deg, machine["head.in_mm"])
    assert w.wraps[2:] == [Wrap(n - 1, 1), Wrap(0, 1)]
    assert w.collisions == []


@pytest.mark.parametrize("turns", [-7, 3, 95])
def test_multi_turn_angles_map_to_the_same_pins(machine, turns):
    w = World(machine)
    assert hook(w, machine, 123, 1, turns=turns) == [Wrap(123, 1)]
    assert hook(w, machine, 5, -1, turns=turns) == [Wrap(5, -1)]
    assert w.collisions == []


def test_a_full_turn_while_out_wraps_every_pin(machine):
    w = World(machine)
    a = gap(machine, 0)
    w.move(a, machine["head.in_mm"])
    w.move(a, machine["head.out_mm"])
    w.move(a + 360.0, machine["head.out_mm"])
    w.move(a + 360.0, machine["head.in_mm"])
    assert [x.pin for x in w.wraps] == list(range(1, machine.pins)) + [0]
    assert {x.direction for x in w.wraps} == {1}


@pytest.mark.parametrize("where", [0.0, 0.5, -0.1, 0.12])   # in pitches from a pin centre
def test_crossing_at_a_non_gap_is_a_collision(machine, where):
    w = World(machine)
    r = machine.pin_angle(30) + where * machine.pitch_deg
    w.move(r, machine["head.in_mm"])
    w.move(r, machine["head.out_mm"])
    if where == 0.5:
        assert w.collisions == []              # that is a gap centre
    else:
        assert len(w.collisions) == 1
        c = w.collisions[0]
        assert c["ring_deg"] == pytest.approx(r) and c["head_mm"] == machine.circle_mm
        assert "pin 30" in c["reason"]


def test_gap_tolerance_edges(machine):
    tol = machine.gap_tolerance_deg
    for off, collides in [(0.98 * tol, False), (-0.98 * tol, False), (1.02 * tol, True), (-1.02 * tol, True)]:
        w = World(machine)
        r = gap(machine, 50) + off
        w.move(r, machine["head.in_mm"])
        w.move(r, machine["head.out_mm"])
        assert bool(w.collisions) == collides, off


def test_diagonal_move_checks_the_ring_angle_where_it_crosses(machine):
    m = machine
    inn, out = m["head.in_mm"], m["head.out_mm"]
    # head IN -> OUT while the ring turns one pitch: crosses the circle halfway, at the ring
    # midpoint.  From pin 10 to pin 11 the midpoint is gap 10|11: fine.
    w = World(m)
    w.move(m.pin_angle(10), inn)
    w.move(m.pin_angle(11), out)
    assert w.collisions == []
    # from gap 9|10 to gap 10|11: the midpoint is pin 10 itself: a collision mid-segment
    w = World(m)
    w.move(gap(m, 9), inn)
    w.move(gap(m, 10), out)
    assert len(w.collisions) == 1
    assert w.collisions[0]["ring_deg"] == pytest.approx(m.pin_angle(10))
    # a diagonal out through gap 10|11 and straight in through gap 11|12 wraps pin 11
    w = World(m)
    w.move(m.pin_angle(10), inn)
    w.move(m.pin_angle(11), out)
    w.move(gap(m, 11), out)
    w.move(gap(m, 11), inn)
    assert w.wraps == [Wrap(11, 1)] and w.collisions == []


def test_head_stopping_exactly_on_the_circle(machine):
    m = machine
    c = m.circle_mm
    # to the circle at a gap, then on out, along, and back in: an ordinary hook
    w = World(m)
    w.move(gap(m, 60), m["head.in_mm"])
    w.move(gap(m, 60), c)
    assert w.collisions == [] and not w.head_out
    w.move(gap(m, 60), m["head.out_mm"])
    w.move(gap(m, 61), m["head.out_mm"])
    w.move(gap(m, 61), c)
    assert w.wraps == []                       # not back IN yet
    w.move(gap(m, 61), m["head.in_mm"])
    assert w.wraps == [Wrap(61, 1)] and w.collisions == []
    # touching the circle and going back to the same side is no crossing
    w = World(m)
    w.move(gap(m, 5), c)
    w.move(gap(m, 5), m["head.in_mm"])
    assert w.wraps == [] and w.collisions == []
    # arriving at the circle at a pin is a collision even without crossing it
    w = World(m)
    w.move(m.pin_angle(5), c)
    assert len(w.collisions) == 1


def test_sliding_along_the_circle(machine):
    m = machine
    c = m.circle_mm
    w = World(m)
    w.move(gap(m, 7), c)
    w.move(gap(m, 7) + 0.5 * m.gap_tolerance_deg, c)     # inside the gap window: fine
    assert w.collisions == []
    w.move(gap(m, 8), c)                                  # drags the eyelet through pin 8
    assert len(w.collisions) == 1 and "past a pin" in w.collisions[0]["reason"]


def test_out_side_below_in_side():
    m = variant(**{"head.in_mm": 10.0, "head.out_mm": -5.0})
    w = World(m)
    assert w.head_mm == 10.0 and not w.head_out
    assert hook(w, m, 100, -1) == [Wrap(100, -1)]
    assert w.collisions == []
    w.move(m.pin_angle(3), m["head.in_mm"])
    w.move(m.pin_angle(3), m["head.out_mm"])              # straight out at a pin
    assert len(w.collisions) == 1


def test_pin0_offset_is_respected():
    m = variant(**{"ring.pin0_angle_deg": 0.6})           # half a pitch: pin 0 where gap 0|1 was
    w = World(m)
    assert hook(w, m, 4, 1) == [Wrap(4, 1)] and w.collisions == []
    w = World(m)
    w.move(0.6, 0.0)
    w.move(0.6, 12.0)                                     # pin 0 faces the station now
    assert len(w.collisions) == 1


def test_record_is_written_atomically_after_each_wrap(machine, tmp_path):
    path = tmp_path / "rec.json"
    w = World(machine, record_path=path)
    assert json.loads(path.read_text())["wraps"] == []
    hook(w, machine, 17, 1)
    rec = json.loads(path.read_text())
    assert rec["wraps"] == [{"pin": 17, "direction": 1}]
    assert rec["moves"] == 4 and rec["collisions"] == []
    w.move(machine.pin_angle(2), machine["head.in_mm"])
    w.move(machine.pin_angle(2), machine["head.out_mm"])
    rec = json.loads(path.read_text())
    assert len(rec["collisions"]) == 1 and rec["collisions"][0]["reason"]
    assert rec == w.record()
    assert [p.name for p in tmp_path.iterdir()] == ["rec.json"]   # no temp files left


def test_rejects_non_finite_positions(machine):
    with pytest.raises(ValueError):
        World(machine).move(float("nan"), 0.0)


def test_touching_the_circle_from_outside_keeps_the_hook_open(machine):
    m = machine
    w = World(m)
    w.move(gap(m, 20), m["head.in_mm"])
    w.move(gap(m, 20), m["head.out_mm"])
    w.move(gap(m, 21), m["head.out_mm"])
    w.move(gap(m, 21), m.circle_mm)                       # touch from outside ...
    w.move(gap(m, 21), m["head.out_mm"])                  # ... and back out: still hooking
    w.move(gap(m, 22), m["head.out_mm"])
    w.move(gap(m, 22), m["head.in_mm"])
    assert w.wraps == [Wrap(21, 1), Wrap(22, 1)] and w.collisions == []


def test_segments_split_anywhere_give_the_same_wraps(machine):
    """An emulator may cut a move into many segments (acceleration slices)."""
    m = machine
    path = [(gap(m, 99), m["head.in_mm"]), (gap(m, 99), m["head.out_mm"]),
            (gap(m, 101), m["head.out_mm"]), (gap(m, 101), m["head.in_mm"])]
    w = World(m)
    here = (w.ring_deg, w.head_mm)
    for target in path:
        for i in range(1, 8):
            f = i / 7
            w.move(here[0] + f * (target[0] - here[0]), here[1] + f * (target[1] - here[1]))
        here = target
    assert w.wraps == [Wrap(100, 1), Wrap(101, 1)] and w.collisions == []


def test_record_file_equals_the_record_after_many_wraps(tmp_path):
    import json

    from firmware_protocol.machine import load_machine
    from firmware_protocol.world import World

    path = tmp_path / "rec.json"
    w = World(load_machine("grbl-ring"), record_path=path)
    half = w.machine.pitch_deg / 2
    for k in (5, 9, 9, 299, 0, 150):
        a = w.machine.pin_angle(k)
        w.move(a - half, 0.0)
        w.move(a - half, 12.0)
        w.move(a + half, 12.0)
        w.move(a + half, 0.0)
    on_disk = json.loads(path.read_text())
    assert [x["pin"] for x in on_disk["wraps"]] == [5, 9, 9, 299, 0, 150]
    assert on_disk == json.loads(json.dumps(w.record()))
