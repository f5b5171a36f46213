"""A colour plan wound through ``stringbot simulate`` on a pty: the simulator in its own process
is told each tie-on (its operator socket), so its record holds the colour of every wrap."""

import json
import subprocess

import pytest

from stringbot.planner.plan_file import write_plan
from test_colour_plan import colour_plan
from test_wind_pty import STRINGBOT, Simulator

pytestmark = pytest.mark.timeout(300)


@pytest.mark.parametrize("machine", ["grbl-ring", "dynamixel-ring"])
def test_the_pty_simulators_record_has_the_colour_of_every_wrap(tmp_path, machine):
    plan = colour_plan(pins=300, n=(12, 9, 7))
    path = tmp_path / "c.json"
    write_plan(plan, path)
    sim = Simulator(tmp_path, machine)
    try:
        assert (tmp_path / "pty.operator").is_socket()
        p = subprocess.run(STRINGBOT + ["wind", str(path), "--machine", machine, "--port", str(sim.pty),
                                        "--yes", "--journal", str(tmp_path / "j.journal")],
                           capture_output=True, text=True, timeout=240)
        assert p.returncode == 0, p.stderr
    finally:
        sim.stop()
    rec = json.loads(sim.record.read_text())
    assert [(w["pin"], w.get("color")) for w in rec["wraps"]] == [
        (pin, lay.color) for lay in plan.layers for pin in lay.sequence]
    assert [s["color"] for s in rec["spools"]] == plan.colors
    assert not (tmp_path / "pty.operator").exists()          # the simulator cleans up after itself
