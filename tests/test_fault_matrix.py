"""The cross-process fault matrix (benchmarks/bench_fault_matrix.py), case by case.

Each case is what a user does: ``stringbot simulate --faults ...`` in one process, ``stringbot
wind --port PTY --yes`` in another, then ``--resume`` after every stop, the operator's answers
(``--head-side``, or the guided way at a terminal) read from the simulator's record file only.
Judged by the world: its wraps equal the plan, no collision.

The fast cases cover the kinds tests/test_wind_pty.py does not (power, disconnect, reset at a
line and the host's SIGKILL are there): a garbled, an erroneous and a lost-``ok`` line, a reboot
at a line, mid-move reset / power / reboot (the guided way included), Ctrl-C on a board that
reboots when its port opens, and the simulator killed.  The slow test runs a reduced matrix.
"""

import sys
from pathlib import Path

import pytest

from bundled import GCODE_MACHINES, MACHINES, on_a_pty
from planner_helpers import plan_files
from test_wind_sim import small_plan

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_fault_matrix as fm  # noqa: E402
import matrix_cases as mc  # noqa: E402


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A 10-step plan (made for each machine's thread) and, per machine, its fault points from a
    fault-free probe."""
    work = tmp_path_factory.mktemp("matrix")
    plan = small_plan(n=10, seed=31)
    cache = {}
    plan_for = plan_files(work, plan)

    def points(machine, wanted):
        if machine not in cache:
            cache[machine] = mc.line_table(plan_for(machine), machine)
        import random
        return mc.fault_points(cache[machine], machine, random.Random(1), wanted)
    return work, plan, points, plan_for


def _run(tiny, case):
    work, plan, _, plan_for = tiny
    return fm.run_case(case, plan_for(case.machine), plan.sequence, work, timeout=60.0)


def _explain(r):
    return f"{r['outcome']}: {r['why']}\n" + "\n".join(r["log"])


@pytest.mark.parametrize("machine, kind, point", [
    ("grbl-ring", "garble", "hook"),            # error:N for a damaged line, the head OUT
    ("marlin-ring", "error", "in"),             # a rejected line: Marlin resends it, no stop
    ("grblhal-ring", "drop-ok", "hook-sync"),   # a lost ok while the ring turns behind a pin
    ("marlin-ring", "reboot", "out"),           # the board restarts: re-homed without crossing pins
])
def test_a_line_fault_then_resume_winds_the_plan_exactly(tiny, machine, kind, point):
    n = tiny[2](machine, [point])[point]
    r = _run(tiny, mc.Case(machine, machine, kind, f"{kind}@{n}", point))
    assert r["outcome"] == "exact", _explain(r)


@pytest.mark.parametrize("machine, kind, point", [
    ("grblhal-ring", "reset", "hook"),          # ALARM:3 with the ring turning, MPos kept
    ("grbl-ring", "reboot", "hook"),            # the position gone mid-hook, no switch: the guided way
])
def test_a_fault_in_the_middle_of_a_move_then_resume_winds_the_plan_exactly(tiny, machine, kind, point):
    n = tiny[2](machine, [point])[point]
    r = _run(tiny, mc.Case(machine, machine, f"{kind}+0.5", f"{kind}@{n}+0.5", point))
    assert r["outcome"] == "exact", _explain(r)
    if machine == "grbl-ring":
        assert any("--yes" not in entry.split("\n")[0] for entry in r["log"]), "the guided way was not taken"


@pytest.mark.parametrize("machine", on_a_pty(MACHINES))
def test_every_bundled_machine_loses_power_mid_hook_then_resumes_exactly(tiny, machine):
    """Every machine file of machines/ (the registry: a new one is run here unedited): power lost
    halfway through the ring's turn with the head OUT among the pins -- the firmware restarts with
    its position lost -- then resumes as its user would until the world is the plan."""
    if machine in GCODE_MACHINES:
        n = tiny[2](machine, ["hook"])["hook"]
        case = mc.Case(machine, machine, "power+0.5", f"power@{n}+0.5", "hook")
    else:                 # a servo bus counts moves (4 a step: approach, out, the pitch turn, in)
        case = mc.Case(machine, machine, "power", f"power@{4 * (len(tiny[1].sequence) // 2) + 3}", "hook")
    r = _run(tiny, case)
    assert r["outcome"] == "exact", _explain(r)
    assert r["stops"] >= 1, "the fault did not stop the winding"


def test_ctrl_c_then_a_board_that_reboots_when_its_port_opens_resumes_exactly(tiny):
    """Issue 15: Ctrl-C, then the resume's open reboots the board (an Uno).  On Marlin a G92 of the
    held position would shift its software endstops (the head could no longer go OUT): it re-homes."""
    import signal
    uno = mc.uno_machine(tiny[0], "marlin-ring")
    r = _run(tiny, mc.Case(uno, "marlin-ring", "uno-int", point="Ctrl-C", signal=signal.SIGINT, kills=[3]))
    assert r["outcome"] == "exact", _explain(r)
    assert r["stops"] == 1 and "-> 130" in r["log"][0]


def test_the_simulator_killed_stops_the_host_with_the_resume_and_no_pin_it_did_not_see(tiny):
    r = _run(tiny, mc.Case("grbl-ring", "grbl-ring", "sim-kill", point="1 kill", sim_kill=4))
    assert r["outcome"] == "refused", _explain(r)
    assert "--resume" in r["why"]


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_a_reduced_matrix_is_never_silently_wrong_and_never_hangs(tmp_path):
    """Every machine, every kind, two points each (one with the head OUT), a 20-line plan."""
    kinds = (mc.LINE_KINDS + [f"{k}+0.5" for k in mc.MID_KINDS] + [f"uno-{k}" for k in mc.UNO_KINDS]
             + ["dynamixel", "host-kill", "host-int", "sim-kill"])
    cases, plans = mc.build_cases(tmp_path, mc.GCODE + mc.SERVO, kinds, 2, 3, 11,
                                  lambda name: mc.make_plan(tmp_path, name, 20))
    results = fm.run_matrix(cases, plans, tmp_path, workers=2, timeout=120.0)
    table = "\n".join(fm.table_lines(results))
    bad = [f"{r['case']}: {r['outcome']}: {r['why']}" for r in results if r["outcome"] in ("silent", "hung")]
    assert not bad, table + "\n" + "\n".join(bad)
    assert sum(r["outcome"] == "exact" for r in results) > len(results) // 2, table
