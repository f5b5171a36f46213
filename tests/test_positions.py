"""Position tolerances come from the machine: one step of each axis plus print and float32 rounding."""

import pytest

from firmware_protocol.machine import load_machine
from stringbot.links import open_link, sim_url
from stringbot.motion import hook_steps
from stringbot.motion.positions import UNKNOWN_STEP, position_tolerance
from stringbot.winding.resume import locate, tolerance

from test_wind_sim import small_plan


def test_one_step_of_the_ring_plus_rounding_on_grbl_ring(tmp_path):
    m = load_machine("grbl-ring")                      # 44.4444 steps per degree: 0.0225 deg a step
    ring, head = position_tolerance(m)
    assert 1 / 44.4444 < ring < 1 / 44.4444 + 0.01
    # the head's steps from the file (80 per mm: 0.0125 mm a step)
    assert 1 / 80 < head < 1 / 80 + 0.01
    # a file without them: a coarse step is assumed
    text = "".join(line for line in open(m.path).readlines() if not line.startswith("steps_per_mm"))
    (tmp_path / "bare.toml").write_text(text)
    assert UNKNOWN_STEP < position_tolerance(load_machine(str(tmp_path / "bare.toml")))[1] < UNKNOWN_STEP + 0.01
    # the firmware's own $100/$101 when read; Marlin prints two decimals
    ring2, head2 = position_tolerance(m, ring_steps=100.0, head_steps=80.0, decimals=2)
    assert ring2 == pytest.approx(0.01 + 0.005 + 2 * 2 ** -23 * 36000)
    assert head2 == pytest.approx(0.0125 + 0.005 + 2 * 2 ** -23 * 12)


def test_a_whole_step_off_the_path_is_still_on_it():
    """Issue 15: MPos -2322.610 for a planned -2322.6 (GRBL reports whole steps) was refused
    with a fixed 0.01 tolerance; one step of the axis accepts it, a pitch is still refused."""
    m = load_machine("grbl-ring")
    steps = hook_steps(small_plan(n=6, seed=21), m)
    s = 3
    a, b, c, d = [(mv.ring_deg, mv.head_mm) for mv in steps[s].moves]
    tol = position_tolerance(m)
    turn = 1.0 if c[0] > b[0] else -1.0
    off = (b[0] - turn * 0.0105, b[1])                 # just short of the approach gap, head out
    assert locate(off, steps, s, 1, m) is None         # the old fixed 0.01
    assert locate(off, steps, s, 1, m, tol) == (s, 2)
    assert locate((b[0] + m.pitch_deg / 2, a[1]), steps, s, 1, m, tol) is None


def test_a_gcode_link_takes_the_step_from_the_firmwares_settings(tmp_path):
    m = load_machine("grbl-ring")
    url = sim_url("grbl-ring", record=tmp_path / "r.json")
    link = open_link(url, m)
    try:
        link.identify()
        assert link.proto.settings[100] == pytest.approx(44.444, abs=1e-3)
        ring, head = link.position_tolerance
        assert ring == pytest.approx(1 / link.proto.settings[100] + 0.0005 + 2 * 2 ** -23 * 36000)
        assert head == pytest.approx(1 / link.proto.settings[101] + 0.0005 + 2 * 2 ** -23 * 12)
        assert tolerance(link) == (ring, head)
    finally:
        link.close()
