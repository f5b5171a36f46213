"""End to end through a pseudo-terminal: ``stringbot simulate --pty`` in its own process,
``stringbot wind --port PATH`` talking to it with the real pyserial port code.

Also the host killed with SIGKILL mid-winding: ``--resume`` finishes the plan exactly.
"""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from stringbot.planner import write_plan

from bundled import MACHINES, on_a_pty  # (puts benchmarks/ on the path: matrix_user)
from matrix_user import homes
from planner_helpers import for_machine
from test_wind_sim import small_plan

STRINGBOT = [sys.executable, "-c", "import sys; from stringbot.cli import main; main(sys.argv[1:])"]


class Simulator:
    """``stringbot simulate`` in a subprocess, serving one machine on a pty."""

    def __init__(self, tmp_path, machine, faults=None, realtime=False, settings=()):
        self.pty = tmp_path / "pty"
        self.record = tmp_path / "rec.json"
        cmd = STRINGBOT + ["simulate", "--machine", machine, "--pty", str(self.pty),
                           "--record", str(self.record)]
        if faults:
            cmd += ["--faults", faults]
        if realtime:
            cmd += ["--realtime"]
        for setting in settings:  # a mis-set machine: `simulate --set NAME=VALUE`
            cmd += ["--set", setting]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 30
        while not self.pty.exists():
            if self.proc.poll() is not None:
                raise RuntimeError("simulator died: " + self.proc.stderr.read())
            if time.monotonic() > deadline:
                raise RuntimeError("simulator did not start")
            time.sleep(0.05)

    def wait_port(self, timeout=10):
        deadline = time.monotonic() + timeout
        while not os.path.exists(os.path.realpath(self.pty)) and time.monotonic() < deadline:
            time.sleep(0.05)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def wraps(self):
        rec = json.loads(self.record.read_text())
        return [w["pin"] for w in rec["wraps"]], rec["collisions"]


@pytest.fixture
def sim_factory(tmp_path):
    sims = []

    def make(machine, faults=None, realtime=False):
        sim = Simulator(tmp_path, machine, faults, realtime)
        sims.append(sim)
        return sim
    yield make
    for sim in sims:
        sim.stop()


def steps_done(journal, n, proc, timeout=120):
    """Wait until ``journal`` holds ``n`` executed steps (while ``proc`` runs)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if journal.exists() and journal.read_bytes().count(b'"kind":"done"') >= n:
            return
        time.sleep(0.01)
    raise AssertionError(f"{n} step(s) not journaled (exit {proc.poll()})")


def wind(plan_path, machine, port, journal, *extra, timeout=120):
    cmd = STRINGBOT + ["wind", str(plan_path), "--machine", machine, "--port", str(port), "--yes",
                       "--journal", str(journal)] + list(extra)
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


# a start homes: the firmware that just started cannot say where the head is, so the operator does
HOMES = tuple(m for m in MACHINES if homes(m))


def first_wind(plan_path, machine, port, journal, *extra):
    """A fresh ``wind --yes``; on a machine that homes, the operator's word that the head is IN."""
    return wind(plan_path, machine, port, journal, *(["--head-side", "in"] if machine in HOMES else []), *extra)


@pytest.mark.parametrize("machine", on_a_pty(MACHINES))
def test_wind_through_a_pty(tmp_path, sim_factory, machine):
    plan = for_machine(small_plan(n=14, seed=11), machine)
    write_plan(plan, tmp_path / "plan.json")
    sim = sim_factory(machine)
    if machine in HOMES:        # --yes alone does not say where the head is before homing
        refused = wind(tmp_path / "plan.json", machine, sim.pty, tmp_path / "j")
        assert refused.returncode == 2, refused.stderr
        lines = [x for x in refused.stderr.splitlines() if x.startswith("stringbot:")]
        assert len(lines) == 1 and "before homing" in lines[0] and "--head-side in" in lines[0]
        assert json.loads(sim.record.read_text())["moves"] == 0
    done = first_wind(tmp_path / "plan.json", machine, sim.pty, tmp_path / "j")
    assert done.returncode == 0, done.stderr
    sim.stop()
    pins, collisions = sim.wraps()
    assert pins == plan.sequence and collisions == []


@pytest.mark.parametrize("machine, faults", [("grbl-ring", "power@19"), ("marlin-ring", "disconnect@23"),
                                             ("grblhal-ring", "reset@26")])
def test_fault_through_a_pty_then_resume(tmp_path, sim_factory, machine, faults):
    """Three faults a --yes resume gets past (every machine through its pty, the guided way too:
    tests/test_fault_matrix.py)."""
    plan = for_machine(small_plan(n=10, seed=12), machine)
    write_plan(plan, tmp_path / "plan.json")
    sim = sim_factory(machine, faults)
    first = first_wind(tmp_path / "plan.json", machine, sim.pty, tmp_path / "j")
    assert first.returncode == 1, first.stderr
    assert "--resume" in first.stderr
    time.sleep(0.6)                              # the pty comes back after a pulled cable / power loss
    sim.wait_port()
    again = wind(tmp_path / "plan.json", machine, sim.pty, tmp_path / "j", "--resume")
    if again.returncode == 2 and "--head-side" in again.stderr:      # asked: look at the machine
        side = json.loads(sim.record.read_text())["head_side"]
        again = wind(tmp_path / "plan.json", machine, sim.pty, tmp_path / "j", "--resume", "--head-side", side)
    assert again.returncode == 0, again.stderr
    sim.stop()
    pins, collisions = sim.wraps()
    assert pins == plan.sequence and collisions == []


def test_host_killed_with_sigkill_then_resume(tmp_path, sim_factory):
    """SIGKILL a few times mid-winding (once 3, 12 and 25 steps are journaled, a moment later: a
    random fraction of a step); --resume each time until done."""
    import random

    from matrix_user import run_host
    plan = small_plan(n=40, seed=13)
    write_plan(plan, tmp_path / "plan.json")
    sim = sim_factory("grbl-ring")
    journal = tmp_path / "j"
    base = ["wind", str(tmp_path / "plan.json"), "--machine", "grbl-ring", "--port", str(sim.pty), "--yes",
            "--journal", str(journal)]
    kills, rng = 0, random.Random(13)
    for after in (3, 12, 25, None):
        rc, out, err, _ = run_host(base + (["--resume"] if journal.exists() else []), 120, after, journal, rng)
        if rc == "killed":
            kills += 1
            continue
        assert rc == 0 or "says the winding is finished" in err, err     # the last kill may come at its end
        break
    sim.stop()
    pins, collisions = sim.wraps()
    assert kills >= 1
    assert collisions == []
    assert pins == plan.sequence


@pytest.mark.realtime
@pytest.mark.parametrize("machine", ["grbl-ring", "marlin-ring"])
def test_ctrl_c_on_a_realtime_machine_then_resume(tmp_path, sim_factory, machine):
    """SIGINT mid-winding at real speed: exit 130 with the resume command; --resume finishes exactly."""
    plan = for_machine(small_plan(n=4, seed=14), machine)
    write_plan(plan, tmp_path / "plan.json")
    sim = sim_factory(machine, realtime=True)
    cmd = STRINGBOT + ["wind", str(tmp_path / "plan.json"), "--machine", machine, "--port", str(sim.pty),
                       "--yes", "--journal", str(tmp_path / "j")] + (["--head-side", "in"] if machine in HOMES else [])
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    steps_done(tmp_path / "j", 1, proc)          # Ctrl-C once a pin is wound, however loaded the computer
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted at pin" in err and "--resume" in err and "Traceback" not in err
    again = wind(tmp_path / "plan.json", machine, sim.pty, tmp_path / "j", "--resume")
    assert again.returncode == 0, again.stderr
    sim.stop()
    pins, collisions = sim.wraps()
    assert pins == plan.sequence and collisions == []
