"""What the wind, resume and fault tests take from the registries, so that a new machine file or
fault kind is run by them without editing them.

- :data:`MACHINES`: every bundled machine (``machines/*.toml``, what ``stringbot machines`` lists);
  :data:`GCODE_MACHINES` those that speak G-code.
- :data:`RESUMABLE`: the G-code fault kinds a resume alone gets past (``FaultKind.resumable``),
  :data:`MACHINE_KINDS` / :data:`LINE_KINDS` those of them that hit the machine / a line.
- :func:`fault_point`: the line number of a kind of move in a fault-free winding of a plan, as
  that machine's firmware counts lines (found by winding once in process, through ``sim://``;
  it only chooses where faults strike: the tests judge by the simulator's record).
"""

import random
import sys
import tempfile
from functools import lru_cache
from pathlib import Path

import pytest

from firmware_protocol.faults import FAULT_KINDS
from firmware_protocol.machine import bundled_machines, load_machine

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

__all__ = ["MACHINES", "GCODE_MACHINES", "RESUMABLE", "MACHINE_KINDS", "LINE_KINDS", "fault_point", "POINTS",
           "on_a_pty", "SERVO_REALTIME", "PATIENT_GRACE_MS"]

MACHINES = bundled_machines()
GCODE_MACHINES = [m for m in MACHINES if load_machine(m)["controller.kind"] == "gcode"]
RESUMABLE = [k.name for k in FAULT_KINDS.values() if k.resumable]
MACHINE_KINDS = [k for k in RESUMABLE if FAULT_KINDS[k].hits == "machine"]
LINE_KINDS = [k for k in RESUMABLE if FAULT_KINDS[k].hits == "line"]
#: A servo bus through a pty or a pipe is a realtime test: its link declares a servo silent when
#: no answer comes within 35 ms, then 65, 185 and 585 ms (0.75 s in all), and a loaded computer's
#: simulator thread or process misses that; G-code links wait seconds.
SERVO_REALTIME = pytest.mark.realtime


#: Retry graces (ms) for servo links made in a test's own process: the link's own (0, 50, 200, 500)
#: are what a user gets; these give a loaded computer's simulator thread seconds, not 0.75 s
#: (tests/test_dynamixel_late.py checks the link's own).
PATIENT_GRACE_MS = (0.0, 250.0, 1000.0, 2500.0)


def on_a_pty(machines):
    """``machines`` as parameters of a test that serves them on a pty or another process: a servo
    bus's marked realtime (run apart, one at a time)."""
    return [pytest.param(m, marks=SERVO_REALTIME) if load_machine(m)["controller.kind"] == "dynamixel" else m
            for m in machines]


#: The kinds of move a fault can strike (benchmarks/bench_fault_matrix.py): the ring turning to a
#: pin with the head IN, the head going OUT, the ring turning with the head OUT (mid-hook), the
#: sync line that arrives while that turn runs, the head coming back IN.
POINTS = ("ring", "out", "hook", "hook-sync", "in")



def fault_point(machine, plan, point, *, seed=1):
    """The line number, as ``machine``'s firmware counts them, of a ``point`` (one of
    :data:`POINTS`) in a fault-free winding of ``plan``: in the middle part of the job, the same
    for the same plan and seed."""
    return _points(machine, plan.sha256(), _plan_file(plan), seed)[point]


def _plan_file(plan):
    from stringbot.planner import write_plan

    path = _work() / f"{plan.sha256()[:16]}.json"
    if not path.exists():
        write_plan(plan, path)
    return str(path)


@lru_cache(maxsize=None)
def _work():
    return Path(tempfile.mkdtemp(prefix="stringbot-points-"))


@lru_cache(maxsize=None)
def _points(machine, _sha, plan_path, seed):
    import matrix_cases as mc

    table = mc.line_table(Path(plan_path), machine)
    found = mc.fault_points(table, machine, random.Random(seed), list(POINTS))
    missing = [p for p, n in found.items() if n is None]
    if missing:
        raise AssertionError(f"{machine}: the plan has no {', '.join(missing)} move to strike")
    return found
