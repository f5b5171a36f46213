"""A spool change is a person's act: a colour plan on a port never goes through one unasked.

Through the command line, the simulator in its own process (``stringbot simulate --pty``), and
judged by what the simulator saw: each wrap's pin and the colour of the thread that went round it,
with the colour known only from the person's own act at the machine (``simulate --tie-on``), never
from the host.
"""

import json
import shlex
import subprocess

import pytest

from bundled import on_a_pty
from planner_helpers import for_machine
from stringbot.planner.plan_file import write_plan
from test_colour_plan import colour_plan
from test_wind_pty import HOMES, STRINGBOT, Simulator

pytestmark = pytest.mark.timeout(300)


def plan_for(tmp_path, machine, n=(6, 5, 4)):
    """A 3-colour plan for ``machine``'s ring and thread, written to ``tmp_path / c.json``."""
    plan = for_machine(colour_plan(n=n), machine)
    path = tmp_path / "c.json"
    write_plan(plan, path)
    return plan, path


def stringbot(args, **kw):
    return subprocess.run(STRINGBOT + [str(a) for a in args], capture_output=True, text=True, timeout=240, **kw)


def tie_on(sim, color, pin):
    """The person at the machine ties a thread on (the simulator's operator socket, through the CLI)."""
    p = stringbot(["simulate", "--pty", sim.pty, "--tie-on", color, "--pin", pin])
    assert p.returncode == 0, p.stderr
    assert color in p.stdout


def resume_command(stderr):
    """The resume command a stop prints, as arguments for this test's ``stringbot``."""
    line = stderr.strip().splitlines()[-1]
    assert "then resume with: " in line, stderr
    argv = shlex.split(line.split("then resume with: ", 1)[1])
    assert argv[0] == "stringbot"
    return argv[1:]


def seen(sim):
    """(pin, colour) of every wrap the simulated machine saw, and its record."""
    rec = json.loads(sim.record.read_text())
    return [(w["pin"], w.get("color")) for w in rec["wraps"]], rec


@pytest.mark.parametrize("machine", on_a_pty(["grbl-ring", "marlin-ring", "dynamixel-ring"]))
def test_yes_on_a_port_stops_at_each_spool_change_and_the_resume_goes_on_with_the_next_colour(tmp_path, machine):
    plan, path = plan_for(tmp_path, machine)
    journal = tmp_path / "c.journal"
    sim = Simulator(tmp_path, machine)
    try:
        assert (tmp_path / "pty.operator").is_socket()             # where the person's hands are heard
        tie_on(sim, plan.colors[0], plan.sequence[0])            # the first thread, before starting
        args = ["wind", path, "--machine", machine, "--port", sim.pty, "--yes", "--journal", journal]
        if machine in HOMES:        # it homes: the firmware that just started cannot say where the head is
            args += ["--head-side", "in"]
        want = [(pin, lay.color) for lay in plan.layers for pin in lay.sequence]
        for k in (1, 2):
            p = stringbot(args)
            assert p.returncode == 3, p.stderr
            start, pin = plan.layer_starts[k], plan.sequence[plan.layer_starts[k]]
            last = p.stderr.strip().splitlines()[-1]
            assert last.startswith(f"stringbot: spool change before step {start + 1} (layer {k + 1} of 3)")
            assert f"({plan.colors[k - 1]}) thread and tie it off at pin {plan.sequence[start - 1]}" in last
            assert f"({plan.colors[k]}) thread on at pin {pin}" in last
            got, rec = seen(sim)
            assert got == want[:start] and rec["collisions"] == []     # every layer before, nothing more
            assert rec["head_side"] == "in"
            stop = [json.loads(x) for x in journal.read_text().splitlines()][-1]
            assert (stop["kind"], stop["reason"], stop["layer"], stop["next_step"]) == \
                ("stop", "spool change", k, start)
            tie_on(sim, plan.colors[k], pin)                        # the person makes the change
            args = resume_command(p.stderr)
            assert "--resume" in args and "--yes" in args
        p = stringbot(args)
        assert p.returncode == 0, p.stderr
    finally:
        sim.stop()
    assert not (tmp_path / "pty.operator").exists()              # the simulator cleans up after itself
    got, rec = seen(sim)
    assert got == want and rec["collisions"] == []
    assert [s["color"] for s in rec["spools"]] == plan.colors        # the person's three, none from the host
    layers = [r for r in map(json.loads, journal.read_text().splitlines()) if r["kind"] == "layer"]
    assert [(r["layer"], r["step"]) for r in layers] == [(k, s) for k, s in enumerate(plan.layer_starts)]


def test_a_resume_run_without_the_change_made_winds_the_old_thread_as_the_machine_would(tmp_path):
    """The host never tells the machine a thread was changed: what the record shows is what was done."""
    plan, path = plan_for(tmp_path, "grbl-ring", n=(4, 3, 3))
    sim = Simulator(tmp_path, "grbl-ring")
    try:
        tie_on(sim, plan.colors[0], plan.sequence[0])
        args = ["wind", path, "--machine", "grbl-ring", "--port", sim.pty, "--yes", "--journal", tmp_path / "j"]
        p = stringbot(args)
        assert p.returncode == 3, p.stderr
        p = stringbot(resume_command(p.stderr))                    # nobody tied the next thread on
        assert p.returncode == 3, p.stderr
    finally:
        sim.stop()
    got, rec = seen(sim)
    b = plan.layer_starts[2]
    assert got == [(pin, plan.colors[0]) for pin in plan.sequence[:b]]
    assert len(rec["spools"]) == 1


def test_continue_on_a_port_goes_through_the_spool_changes_and_journals_each(tmp_path):
    plan, path = plan_for(tmp_path, "grbl-ring", n=(4, 3, 3))
    journal = tmp_path / "j"
    sim = Simulator(tmp_path, "grbl-ring")
    try:
        p = stringbot(["wind", path, "--machine", "grbl-ring", "--port", sim.pty, "--yes", "--journal", journal,
                       "--spool-change", "continue"])
        assert p.returncode == 0, p.stderr
        assert "--spool-change continue" in p.stderr                # said before starting
    finally:
        sim.stop()
    got, rec = seen(sim)
    assert [pin for pin, _ in got] == plan.sequence and rec["collisions"] == []
    layers = [r for r in map(json.loads, journal.read_text().splitlines()) if r["kind"] == "layer"]
    assert [r["step"] for r in layers] == plan.layer_starts


@pytest.mark.parametrize("extra, says", [
    (["--spool-change", "stop"], "a dry run's simulated machine ends with its command"),
    (["--spool-change", "ask", "--yes"], "--spool-change ask asks at a terminal and --yes asks nothing"),
])
def test_spool_change_options_that_cannot_work_are_refused(tmp_path, extra, says):
    _, path = plan_for(tmp_path, "grbl-ring")
    p = stringbot(["wind", path, "--machine", "grbl-ring", *extra])
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and says in p.stderr
    assert not (tmp_path / "c.json.dry-run.journal").exists()


def test_the_question_has_no_default_the_colour_is_typed(tmp_path):
    """A dry run at a terminal: an empty answer asks again, another colour is refused, the name, the
    hex or y confirm; the simulated operator ties on what was confirmed."""
    plan, path = plan_for(tmp_path, "grbl-ring", n=(4, 3, 3))
    record = tmp_path / "rec.json"
    answers = "\n\nblue\n" + "black\n#C8102E\n" + "y\n"
    p = stringbot(["wind", path, "--machine", "grbl-ring", "--record", record], input=answers)
    assert p.returncode == 0, p.stderr
    assert "[Y/n]" not in p.stderr
    assert p.stderr.count("Tie the blue (#1f5bb5) thread on at pin") == 3             # asked again twice
    assert "'black' is not the red (#c8102e) thread; type red (or y) once it is tied on" in p.stderr
    assert p.stderr.count("Spool change: cut the") == 3                              # 2 + 1
    rec = json.loads(record.read_text())
    assert [(w["pin"], w["color"]) for w in rec["wraps"]] == \
        [(pin, lay.color) for lay in plan.layers for pin in lay.sequence]


def test_n_at_a_spool_change_stops_and_an_ended_input_is_one_line(tmp_path):
    plan, path = plan_for(tmp_path, "grbl-ring", n=(4, 3, 3))
    p = stringbot(["wind", path, "--machine", "grbl-ring"], input="y\nn\n")
    assert p.returncode == 130 and "spool change before step 5 (layer 2)" in p.stderr
    p = stringbot(["wind", path, "--machine", "grbl-ring"], input="y\n")
    assert p.returncode == 2 and "standard input ended" in p.stderr.strip().splitlines()[-1]


def test_a_resume_at_a_terminal_after_the_stop_asks_for_the_thread(tmp_path):
    plan, path = plan_for(tmp_path, "grbl-ring", n=(4, 3, 3))
    journal = tmp_path / "j"
    sim = Simulator(tmp_path, "grbl-ring")
    try:
        p = stringbot(["wind", path, "--machine", "grbl-ring", "--port", sim.pty, "--yes", "--journal", journal])
        assert p.returncode == 3, p.stderr
        tie_on(sim, plan.colors[1], plan.sequence[plan.layer_starts[1]])
        again = [a for a in resume_command(p.stderr) if a != "--yes"]
        p = stringbot(again, input="y\n\nred\n" + "n\n")          # resume? the thread typed; at layer 3: not yet
        assert p.returncode == 130, p.stderr
        assert p.stderr.count("Spool change: cut the blue (#1f5bb5) thread") == 2      # Enter asked again
    finally:
        sim.stop()
    got, _ = seen(sim)
    b = plan.layer_starts[2]
    assert got[plan.layer_starts[1]:] == [(pin, plan.colors[1]) for pin in plan.sequence[plan.layer_starts[1]:b]]


def test_stop_at_a_terminal_stops_at_each_change_and_its_resume_goes_on_to_the_next(tmp_path):
    """``--spool-change stop`` without ``--yes``: the resume it prints (no ``--yes``) does not stop again at the
    change it was run for."""
    plan, path = plan_for(tmp_path, "grbl-ring", n=(4, 3, 3))
    sim = Simulator(tmp_path, "grbl-ring")
    try:
        tie_on(sim, plan.colors[0], plan.sequence[0])
        p = stringbot(["wind", path, "--machine", "grbl-ring", "--port", sim.pty, "--journal", tmp_path / "j",
                       "--spool-change", "stop"], input="")
        assert p.returncode == 3, p.stderr
        again = resume_command(p.stderr)
        assert "--yes" not in again and again[-2:] == ["--spool-change", "stop"]
        tie_on(sim, plan.colors[1], plan.sequence[plan.layer_starts[1]])
        p = stringbot(again, input="y\n")                   # "Resume at pin ...?"
        assert p.returncode == 3, p.stderr
        assert f"spool change before step {plan.layer_starts[2] + 1} (layer 3 of 3)" in p.stderr
    finally:
        sim.stop()
    got, _ = seen(sim)
    assert got == [(pin, lay.color) for lay in plan.layers[:2] for pin in lay.sequence]
