"""A mis-set machine, per dialect, end to end: ``stringbot simulate --set`` in its own process on a
pty; ``machines check`` names the setting, ``wind`` refuses it before anything moves, and after
``machines check --apply`` it winds the plan exactly (the simulator's record)."""

import pytest

from stringbot.planner import write_plan
from stringbot.winding import read_journal

from planner_helpers import for_machine
from test_wind_cli import error_lines, run
from test_wind_pty import HOMES, Simulator
from test_wind_sim import small_plan

pytestmark = pytest.mark.timeout(120)


def MisSetSimulator(tmp_path, machine, *settings):
    """``stringbot simulate --machine M --pty P --record R --set S...`` in a subprocess."""
    return Simulator(tmp_path, machine, settings=settings)


@pytest.fixture
def simulator(tmp_path):
    sims = []

    def make(machine, *settings):
        sims.append(MisSetSimulator(tmp_path, machine, *settings))
        return sims[-1]
    yield make
    for sim in sims:
        sim.stop()


CASES = [
    ("grbl-ring", "$100=40", "$100 X steps/unit (ring) is 40", "$100=44.4444"),
    ("grblhal-ring", "$22=0", "$22 homing cycle is 0", "$22=1"),
    ("marlin-ring", "M92 A40", "M92 A (ring steps/deg) is 40", "M92 A44.4444"),
    ("dynamixel-ring", "ring:Drive Mode=1", "ring (id 1) Drive Mode (10) is 1 (Reverse Mode)", "1:Drive Mode=0"),
]


@pytest.mark.parametrize("machine, setting, named, fix", CASES, ids=[c[0] for c in CASES])
def test_mis_set_machine_is_named_refused_then_fixed_and_winds_exactly(tmp_path, capsys, simulator,
                                                                       machine, setting, named, fix):
    plan = for_machine(small_plan(n=8, seed=5), machine)
    write_plan(plan, tmp_path / "plan.json")
    journal = tmp_path / "plan.journal"
    sim = simulator(machine, setting)
    port = str(sim.pty)

    code, out, err = run(["machines", "check", machine, "--port", port], capsys)
    assert code == 1 and f"  {fix}" in out.splitlines()

    wind = ["wind", str(tmp_path / "plan.json"), "--machine", machine, "--port", port, "--yes",
            "--journal", str(journal)] + (["--head-side", "in"] if machine in HOMES else [])
    code, out, err = run(wind, capsys)
    assert code == 1, err
    lines = error_lines(err)
    assert len(lines) == 2 and "Traceback" not in err
    assert named in lines[0] and f"send {fix}" in lines[0]
    assert "nothing was moved or wound" in lines[1] and "--no-check" in lines[1] and "--apply" in lines[1]
    assert "resume" not in err
    assert read_journal(journal).done == []
    assert sim.wraps() == ([], [])

    code, out, err = run(["machines", "check", machine, "--port", port, "--apply", "--yes"], capsys)
    assert code == 0, err
    code, out, err = run(wind, capsys)
    assert code == 0, err
    sim.stop()
    assert sim.wraps() == (plan.sequence, [])


def test_wind_refuses_a_mis_set_machine_before_anything_moves(tmp_path, capsys, simulator):
    write_plan(small_plan(n=8, seed=5), tmp_path / "plan.json")
    journal = tmp_path / "plan.journal"
    sim = simulator("grbl-ring", "$100=40", "$110=5000")
    code, out, err = run(["wind", str(tmp_path / "plan.json"), "--machine", "grbl-ring", "--port", str(sim.pty),
                          "--yes", "--journal", str(journal)], capsys)
    assert code == 1, err
    lines = error_lines(err)
    assert len(lines) == 3 and "Traceback" not in err and "resume" not in err
    assert "$100 X steps/unit (ring) is 40" in lines[0] and "send $100=44.4444" in lines[0]
    assert "$110 X max rate (ring) is 5000" in lines[1] and "send $110=7200" in lines[1]
    assert "nothing was moved or wound" in lines[2] and "--no-check" in lines[2]
    assert read_journal(journal).done == []
    assert sim.wraps() == ([], [])


def test_without_the_check_the_mis_set_machine_winds_wrong(tmp_path, capsys, simulator):
    plan = small_plan(n=8, seed=5)
    write_plan(plan, tmp_path / "plan.json")
    sim = simulator("grbl-ring", "$100=40")
    code, out, err = run(["wind", str(tmp_path / "plan.json"), "--machine", "grbl-ring", "--port", str(sim.pty),
                          "--yes", "--no-check", "--journal", str(tmp_path / "j")], capsys)
    assert code == 0, err                       # the firmware does what it is told...
    sim.stop()
    pins, collisions = sim.wraps()
    assert pins != plan.sequence and collisions  # ...and the ring turns 0.9 degree for each one asked


def test_a_dry_run_checks_too_and_agrees(tmp_path, capsys, caplog):
    import logging
    for machine, rows in (("grbl-ring", 9), ("marlin-ring", 8)):
        write_plan(for_machine(small_plan(n=6, seed=5), machine), tmp_path / "plan.json")
        caplog.clear()
        with caplog.at_level(logging.INFO, logger="stringbot.links.settings_check"):
            code, out, err = run(["wind", str(tmp_path / "plan.json"), "--machine", machine, "--yes"], capsys)
        assert code == 0, err
        assert f"firmware settings: {rows} compared with the machine file, 0 disagree" in caplog.text


def test_status_after_a_refusal_names_when_it_was_refused(tmp_path, capsys):
    write_plan(small_plan(n=8, seed=5), tmp_path / "plan.json")
    journal = tmp_path / "plan.journal"
    code, _, err = run(["wind", str(tmp_path / "plan.json"), "--machine", "grbl-ring", "--port",
                        "sim://?machine=grbl-ring&set=%24100%3D40", "--yes", "--journal", str(journal)], capsys)
    assert code == 1 and "nothing was moved or wound" in err
    code, out, err = run(["wind", str(tmp_path / "plan.json"), "--machine", "grbl-ring", "--journal", str(journal),
                          "--status"], capsys)
    assert code == 0, err
    started = next(x for x in out.splitlines() if x.startswith("started: "))
    first, last = started[len("started: "):].split("; last record: ")
    assert last == first                     # the start record is the last one (was "?")
