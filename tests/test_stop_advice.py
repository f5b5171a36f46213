"""Every stop's advice, followed to the letter, ends in an exact piece (issue 24, items 1-2).

Each test is what a user meets: ``stringbot simulate --pty`` in its own process (faults, or lines a
person typed into a terminal program before winding), ``stringbot wind --port PTY`` in another;
then exactly what the stop's message says to do -- the same command, ``--resume``, ``--head-side``,
a terminal (the guided way: the operator reads the simulator's record and types the guide's jog
commands), ``$X``, ``~``.  Judged by the simulator's record: the wraps are the plan's sequence, no
collision.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import serial

from planner_helpers import plan_files
from test_wind_sim import small_plan

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import matrix_cases as mc  # noqa: E402
from matrix_user import STRINGBOT, Simulator, displacement, run_guided, run_host, type_lines, wait_event  # noqa: E402

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """An 8-step plan (made for each machine's thread), and per machine the line numbers of its
    first moves (a fault-free probe)."""
    work = tmp_path_factory.mktemp("advice")
    plan = small_plan(n=8, seed=41)
    cache = {}
    plan_for = plan_files(work, plan)

    def first(machine):
        """{"home": line, "first": line, "ring": [lines of ring moves with the head IN]}"""
        if machine not in cache:
            table = mc.line_table(plan_for(machine), machine)
            cache[machine] = mc.first_points(table, machine)
            ring_ax = "X" if machine == "grbl-ring" else "A"
            cache[machine]["ring"] = [n for n, text, side in table if side == "in" and text.startswith("G1 ")
                                      and text.split()[1][0] == ring_ax]
        return cache[machine]
    return work, plan, first, plan_for


def last_error(err):
    """The last ``stringbot: error:`` line (after a question, it ends the question's line)."""
    found = re.findall(r"stringbot: error: .*", err)
    return found[-1] if found else ""


class Machine:
    """One simulated machine in its own process and the commands a user types at it."""

    def __init__(self, tmp_path, tiny, machine, faults=""):
        self.work, self.plan, _, plan_for = tiny
        self.plan_path = plan_for(machine)
        self.machine, self.tmp = machine, tmp_path
        self.pty, self.record, self.journal = tmp_path / "pty", tmp_path / "rec.json", tmp_path / "j.journal"
        self.sim = Simulator(machine, self.pty, self.record, faults)

    def args(self, *extra, yes=True):
        return (["wind", str(self.plan_path), "--machine", self.machine, "--port", str(self.pty),
                 "--journal", str(self.journal)] + (["--yes"] if yes else []) + list(extra))

    def wind(self, *extra):
        """``stringbot wind ... --yes``: (exit code, the last ``stringbot: error:`` line, stderr)."""
        self.sim.wait_port()
        rc, out, err, _ = run_host(self.args(*extra), 120)
        lines = [x for x in err.splitlines() if x.startswith("stringbot: error:")]
        assert "Traceback" not in err, err
        return rc, (lines[-1] if lines else ""), err

    def guided(self, *extra, answers=None):
        """The same command in a terminal (no ``--yes``), answered from the simulator's record."""
        self.sim.wait_port()
        if answers is not None:             # typed answers, as given
            proc = subprocess.run(STRINGBOT + self.args(*extra, yes=False), input=answers, text=True,
                                  capture_output=True, timeout=120)
            return proc.returncode, proc.stderr
        rc, out, err = run_guided(self.args(*extra, yes=False), self.machine, self.record, 120)
        return rc, err

    def world(self):
        return self.sim.look()

    def exact(self):
        rec = self.sim.stop()
        return [w["pin"] for w in rec["wraps"]] == list(self.plan.sequence) and not rec["collisions"] \
            and not rec.get("crashes")

    def close(self):
        self.sim.stop()


# ---- "nothing was wound yet: run the same command again" ----------------------------------------

def test_a_stop_before_anything_moved_says_run_it_again_and_that_is_exact(tiny, tmp_path):
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, "grbl-ring", "disconnect@1")     # the cable goes at the first line
    try:
        rc, line, _ = m.wind()
        assert rc == 1 and "nothing was wound yet (nothing moved)" in line and "the same command again" in line
        assert "--resume" not in line and m.world()["moves"] == 0
        rc, line, err = m.wind()
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


# ---- a stop after the machine moved: --resume, and a new start refused -----------------------

@pytest.mark.parametrize("machine_name, kind", [("grbl-ring", "power"), ("grbl-ring", "reboot"),
                                                ("fluidnc-ring", "power")])
def test_the_position_lost_in_the_first_ring_move_names_resume_and_refuses_a_new_start(
        tiny, tmp_path, machine_name, kind):
    """Issue 24, item 1: the power cut (or a reboot) half way through the first ring move.  Before,
    the stop said "run the same command again", which wound every pin wrong."""
    n = tiny[2](machine_name)["first"]
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, machine_name, f"{kind}@{n}+0.5")
    try:
        rc, line, _ = m.wind()
        assert rc == 1 and "resume with: stringbot wind" in line and line.endswith("--resume")
        assert "the same command again" not in line
        moved = m.world()
        assert abs(moved["ring_deg"]) > 0.1 and moved["wraps"] == []     # stopped with the ring off 0
        rc, line, err = m.wind()                                        # the same command: refused
        assert rc == 2 and len([x for x in err.splitlines() if x.startswith("stringbot:")]) == 1
        assert "unfinished winding" in line and line.endswith("--resume") and "--port" in line
        assert m.world()["moves"] == moved["moves"]                     # nothing moved
        rc, line, _ = m.wind("--resume")             # the ring may be anywhere on that turn: a person looks
        assert rc == 2 and "without --yes" in line
        rc, err = m.guided("--resume")
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


@pytest.mark.parametrize("machine_name, kind, point", [
    ("grblhal-ring", "power", "home"),           # the power goes as homing begins
    ("grblhal-ring", "reset", "home"),           # a reset half way through homing (ALARM:6)
    ("marlin-ring", "reboot", "home"),
    ("marlin-ring", "power", "first"),           # homed, then the power goes in the first ring move
])
def test_a_stop_while_homing_or_in_the_first_move_resumes_exactly(tiny, tmp_path, machine_name, kind, point):
    """The ring was left turned (the head IN) by a person, so homing moves it; the fault strikes half
    way through homing, or through the first ring move after it."""
    lines = displacement(machine_name, "ring")
    # the typed lines are counted too, and a GRBL that vouches for its position is asked for its
    # work offset ($#) before homing (the probe's fresh one could not vouch)
    n = tiny[2](machine_name)[point] + len(lines) + (machine_name != "marlin-ring")
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, machine_name, f"{kind}@{n}+0.5")
    try:
        type_lines(m.pty, lines)
        rc, line, _ = m.wind("--head-side", "in")
        assert rc == 1 and line.endswith("--resume"), line
        assert [e["event"] for e in m.world()["events"]][:1] in (["reset"], ["reboot"], ["power off"])
        rc, line, err = m.wind("--resume")            # the journal knows homing began from the head IN
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


# ---- before homing, and the first moves: from a position checked safe -----------------------

def test_homing_from_the_head_out_at_a_pin_is_refused_then_guided_in_exactly(tiny, tmp_path):
    """Issue 24, item 2: grblHAL moved so that the head stands OUT with a pin in front of it; before,
    ``wind --yes`` homed and dragged the head across the pin."""
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, "grblhal-ring")
    try:
        type_lines(m.pty, displacement("grblhal-ring", "out-pin"))
        before = m.world()
        assert before["head_side"] == "out"
        rc, line, _ = m.wind()
        assert rc == 1 and "before homing" in line and "a pin is in front of it" in line
        assert "without --yes" in line and "nothing was wound yet (nothing moved)" in line
        assert m.world()["moves"] == before["moves"] and m.world()["collisions"] == []
        rc, line, _ = m.wind("--head-side", "in")             # a wrong word is refused, not believed
        assert rc == 2 and "contradicts the machine's own report" in line
        rc, err = m.guided()                                  # the guide's jogs, read off the record
        assert rc == 0, err
        assert "Bring the head IN through a gap" in err
        assert m.exact()
    finally:
        m.close()


@pytest.mark.parametrize("machine_name, power", [("marlin-ring", False), ("grblhal-ring", True)])
def test_homing_where_the_firmware_cannot_say_asks_the_operator_never_yes(tiny, tmp_path, machine_name, power):
    """Marlin never knows its position before homing; a grblHAL whose power went after it was moved
    off its start does not either: --yes does not answer, the operator does (here: guided)."""
    lines = displacement(machine_name, "out-pin")
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, machine_name, f"power@{len(lines) + 1}" if power else "")
    try:
        type_lines(m.pty, lines, then="G4 P0" if power else None)
        if power:
            assert wait_event(m.record, "power on")          # the machine comes back
        rc, line, _ = m.wind()
        assert rc == 2 and "before homing, the firmware cannot say" in line and "--head-side in" in line
        assert m.world()["collisions"] == []
        rc, line, _ = m.wind("--head-side", "out")
        assert rc == 2 and "safe from OUT only where a gap faces it" in line
        rc, err = m.guided()
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


def test_a_start_with_the_head_out_at_a_pin_without_switches_is_guided_in_exactly(tiny, tmp_path):
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, "grbl-ring")
    try:
        type_lines(m.pty, displacement("grbl-ring", "out-pin"))
        rc, line, _ = m.wind()
        assert rc == 1 and "reports the head OUT" in line and "without --yes" in line
        assert "nothing was wound yet" in line
        rc, err = m.guided()
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


def test_quitting_the_guide_at_the_start_names_resume_which_guides_again(tiny, tmp_path):
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, "grbl-ring")
    try:
        type_lines(m.pty, displacement("grbl-ring", "out-pin"))
        rc, err = m.guided(answers="y\nring -0.2\nquit\n")    # tied on; one jog, then the operator stops
        line = last_error(err)
        assert rc == 130 and "while bringing the head IN" in line and line.endswith("--resume")
        rc, line, _ = m.wind("--resume")
        assert rc == 2 and "jogged" in line and "without --yes" in line
        rc, err = m.guided("--resume")
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


# ---- the operator's own answers ---------------------------------------------------------------

@pytest.mark.parametrize("machine_name, answers, advice", [
    ("grbl-ring", "n\n", "the same command again"),         # nothing moved yet
    ("grblhal-ring", "in\nn\n", "--resume"),                 # it homed (the head IN, said the operator)
])
def test_declining_the_tie_on_then_following_the_advice_is_exact(tiny, tmp_path, machine_name, answers, advice):
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, machine_name)
    try:
        rc, err = m.guided(answers=answers)
        line = last_error(err)
        assert rc == 130 and "stopped by the operator before winding" in line and advice in line
        rc, line, err = m.wind(*(["--resume"] if advice == "--resume" else []))
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


# ---- a machine someone else left behind ------------------------------------------------------

def _raw(pty, data, *, read=0.3):
    port = serial.Serial(str(pty), 115200, timeout=read)
    try:
        port.read(4096)
        port.write(data)
        return port.read(4096)
    finally:
        port.close()


def test_a_grbl_left_in_hold_is_let_go_then_the_same_command_is_exact(tiny, tmp_path):
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, "grbl-ring")
    try:
        _raw(m.pty, b"G1 X30 F600\n!")                      # another program's move, held
        rc, line, _ = m.wind()
        assert rc == 1 and "in Hold" in line and "send ~" in line and "nothing was wound yet" in line
        _raw(m.pty, b"~")                                    # the advice: let it go on
        type_lines(m.pty, ["G4 P0"])                         # (and wait for the move to end)
        rc, line, err = m.wind()
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


def test_a_grbl_in_alarm_is_unlocked_then_the_same_command_is_exact(tiny, tmp_path):
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, "grbl-ring", "reset@2+0.5")     # a reset half way through a jog
    try:
        type_lines(m.pty, ["G90", "G1 X30 F3000"])
        rc, line, _ = m.wind()
        assert rc == 1 and "in alarm" in line and "unlock it ($X" in line and "the same command again" in line
        type_lines(m.pty, ["$X"])
        rc, line, err = m.wind()
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


def test_a_machine_moved_between_a_stop_and_the_resume_is_guided_not_believed(tiny, tmp_path):
    """The firmware kept its position, but someone jogged the head after the stop: the journal and the
    firmware disagree (the head is off the path); --yes refuses, the guide brings it back."""
    n = tiny[2]("grbl-ring")["ring"][3]                     # a ring move with the head IN, mid-job
    (tmp_path / "m").mkdir()
    m = Machine(tmp_path / "m", tiny, "grbl-ring", f"disconnect@{n}")
    try:
        rc, line, _ = m.wind()
        assert rc == 1 and line.endswith("--resume")
        m.sim.wait_port()
        type_lines(m.pty, ["G4 P0"])
        assert m.world()["head_side"] == "in"
        type_lines(m.pty, ["G91", "G1 Y3 F3000", "G90", "G4 P0"])      # the head moved, still inside
        rc, line, _ = m.wind("--resume")
        assert rc == 1 and "not on the path the journal expects" in line and "without --yes" in line
        rc, err = m.guided("--resume")
        assert rc == 0, err
        assert m.exact()
    finally:
        m.close()


def test_journal_records_of_the_first_moves_are_checked(tmp_path):
    """The records a start writes before the first step (homing, approach) are part of the journal's
    format: a damaged one is refused with its line number."""
    from stringbot.errors import BadInput
    from stringbot.winding import read_journal
    path = tmp_path / "j.journal"
    head = {"kind": "start", "format": "stringbot-journal", "version": 1, "plan": "p", "plan_sha256": "x",
            "machine": "grbl-ring", "steps": 3}
    good = [head, {"kind": "homing", "from": None, "how": "the operator"},
            {"kind": "approach", "from": [1.0, 12.0], "to": [1.0, 0.0]}]
    path.write_text("".join(json.dumps(r) + "\n" for r in good))
    state = read_journal(path)
    assert state.moved and state.start_phase((0, 0)) == "approach" and state.homing["how"] == "the operator"
    path.write_text("".join(json.dumps(r) + "\n" for r in good[:2] + [{"kind": "approach", "from": "here"}]
                            + [{"kind": "done", "step": 0, "pin": 1}]))
    with pytest.raises(BadInput, match="line 3 is damaged: approach record's from"):
        read_journal(path)
