"""``stringbot machines check``: the firmware's settings against the machine file, through the CLI
and the simulator's bytes; and the comparison rules, setting by setting."""

import pytest
from click.testing import CliRunner

from firmware_protocol import settings as fs
from firmware_protocol.machine import bundled_machines, load_machine
from firmware_protocol.urlhandler import protocol_sim
from bundled import on_a_pty
from stringbot.cli import cli, main
from stringbot.links.settings_rules import PERSISTENCE, Verdict, compare

pytestmark = pytest.mark.timeout(60)


def run(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    out, err = capsys.readouterr()
    return info.value.code, out, err


def url(tmp_path, machine, *settings):
    """A fresh simulated machine (its own record file), mis-set with ``settings``."""
    from urllib.parse import quote
    sets = "".join(f"&set={quote(s)}" for s in settings)
    return f"sim://?machine={machine}&record={tmp_path / 'rec.json'}{sets}"


@pytest.fixture(autouse=True)
def forget_simulators():
    yield
    protocol_sim.forget()


ROWS = {"grbl-ring": 9, "grblhal-ring": 11, "fluidnc-ring": 9, "marlin-ring": 8, "dynamixel-ring": 13}


@pytest.mark.parametrize("machine", bundled_machines())
def test_each_bundled_machine_agrees_with_its_simulator(capsys, machine):
    code, out, err = run(["machines", "check", machine], capsys)
    assert code == 0, err
    lines = out.splitlines()
    assert lines[1].split() == ["setting", "firmware", "machine", "file", "needs", "verdict"]
    rows = ROWS.get(machine) or len(lines) - 3          # a machine file added since: every row it shows
    table = lines[2:2 + rows]
    assert all(x.rstrip().endswith(("ok", "wind sets it")) for x in table), table
    assert lines[2 + rows] == f"all {rows} settings agree with the machine file"


def test_a_setting_the_machine_file_does_not_give_is_not_counted_as_agreeing(tmp_path, capsys):
    text = (load_machine("grbl-ring").path and open(load_machine("grbl-ring").path).read())
    mine = tmp_path / "mine.toml"
    mine.write_text("\n".join(x for x in text.splitlines() if not x.startswith("steps_per_mm")) + "\n")
    code, out, err = run(["machines", "check", str(mine)], capsys)
    assert code == 0, err
    assert out.splitlines()[-1] == ("8 of 9 settings agree with the machine file; not checked (the machine "
                                    "file does not say): $101 Y steps/unit (head)")


def test_a_mis_set_grbl_names_the_setting_and_the_line_that_fixes_it(tmp_path, capsys):
    port = url(tmp_path, "grbl-ring", "$100=40", "$110=5000")
    code, out, err = run(["machines", "check", "grbl-ring", "--port", port], capsys)
    assert code == 1
    assert "$100 X steps/unit (ring)    40 " in out and "DISAGREES" in out
    assert out.splitlines()[-2:] == ["  $100=44.4444", "  $110=7200"]
    assert err.splitlines() == ["stringbot: error: 2 setting(s) of the firmware disagree with machine file "
                                "grbl-ring"]
    code, out, _ = run(["machines", "check", "grbl-ring", "--port", port], capsys)
    assert code == 1 and "  $100=44.4444" in out                       # nothing was sent unasked


def test_apply_sends_the_fixes_and_says_that_grbl_keeps_them(tmp_path, capsys):
    port = url(tmp_path, "grblhal-ring", "$22=0", "$376=0")
    code, out, err = run(["machines", "check", "grblhal-ring", "--port", port, "--apply", "--yes"], capsys)
    assert code == 0, err
    assert "stays after a reset or a power cycle" in out
    assert "$22 homing cycle: homing ($H) is refused with error:5 while it is off" in out
    assert out.rstrip().endswith("all 11 settings agree with the machine file")
    code, out, err = run(["machines", "check", "grblhal-ring", "--port", port], capsys)
    assert code == 0, err


def test_apply_asks_first_and_a_no_sends_nothing(tmp_path):
    port = url(tmp_path, "marlin-ring", "M92 A40")
    runner = CliRunner()
    got = runner.invoke(cli, ["machines", "check", "marlin-ring", "--port", port, "--apply"], input="n\n")
    assert got.exit_code == 1
    assert "M500 (sent last) stores them in EEPROM" in got.output
    assert "to fix, send these lines:\n  M92 A44.4444\n  M500\n" in got.output
    assert "Send these 2 line(s) to the machine? [y/N]: n" in got.output
    again = runner.invoke(cli, ["machines", "check", "marlin-ring", "--port", port])
    assert again.exit_code == 1 and "  M92 A44.4444" in again.output
    fixed = runner.invoke(cli, ["machines", "check", "marlin-ring", "--port", port, "--apply"], input="y\n")
    assert fixed.exit_code == 0, fixed.output


def test_dynamixel_fixes_are_control_table_writes(tmp_path, capsys):
    port = url(tmp_path, "dynamixel-ring", "ring:Drive Mode=1", "head:Velocity Limit=100")
    code, out, err = run(["machines", "check", "dynamixel-ring", "--port", port], capsys)
    assert code == 1
    assert out.splitlines()[-2:] == ["  1:Drive Mode=0", "  2:Velocity Limit=120"]
    assert "1 (Reverse Mode)" in out
    code, out, err = run(["machines", "check", "dynamixel-ring", "--port", port, "--apply", "--yes"], capsys)
    assert code == 0, err


@pytest.mark.parametrize("args, words", [
    (["machines", "check", "no-such-ring"], "unknown machine 'no-such-ring'"),
    (["machines", "check", "grbl-ring", "--port", "/dev/no-such-port"], "does not exist"),
    (["machines", "check", "grbl-ring", "--port", "sim://?machine=grbl-ring&set=$100"], "expected '$N=VALUE'"),
])
def test_bad_input_is_one_line_and_exit_2(capsys, args, words):
    code, out, err = run(args, capsys)
    assert code == 2 and words in err
    assert err.count("\n") == 1 and "Traceback" not in err


# ---- the rules --------------------------------------------------------------------------------

def grbl_settings(**changes):
    s = {100: 44.444, 101: 80.0, 110: 7200.0, 111: 3000.0, 120: 360.0, 121: 500.0, 130: 72000.0, 131: 24.0,
         22: 0, 20: 0, 13: 0}
    s.update({int(k[1:]): v for k, v in changes.items()})
    return s


def verdicts(report):
    return {row.setting.split()[0]: row.verdict for row in report.rows}


def test_values_agree_within_what_the_firmware_prints():
    m = load_machine("grbl-ring")
    assert compare(m, grbl_settings()).agrees                              # 44.444 printed for 44.4444
    report = compare(m, grbl_settings(s100=44.44, s111=3500.0, s121=499.0))
    assert [r.setting for r in report.disagreements] == ["$100 X steps/unit (ring)", "$121 Y acceleration (head)"]
    assert report.fixes == ["$100=44.4444", "$121=500"]


def test_homing_and_soft_limits_rules():
    m = load_machine("grbl-ring")
    report = compare(m, grbl_settings(s22=1))
    assert report.fixes == ["$22=0"] and "starts locked in alarm" in report.disagreements[0].hint
    assert compare(m, grbl_settings(s22=1, s20=1)).fixes == ["$22=0"]          # travel $130/$131 suffice
    short = compare(m, grbl_settings(s22=1, s20=1, s130=300.0))
    assert short.fixes == ["$22=0", "$20=0"]
    hal = load_machine("grblhal-ring")
    s = {103: 88.889, 100: 80.0, 113: 10800.0, 110: 4000.0, 123: 600.0, 120: 800.0, 22: 7, 20: 0, 13: 0}
    report = compare(hal, s)
    assert verdicts(report)["$376"] is Verdict.UNCHECKED and report.agrees   # an older grblHAL: no $376
    report = compare(hal, {**s, 22: 6, 376: 2, 538: 1})
    assert report.fixes == ["$22=7", "$376=3", "$538=0"]                       # other bits kept


def test_a_machine_file_without_steps_leaves_them_unchecked():
    import tomllib
    from pathlib import Path

    from firmware_protocol.machine import machine_from_dict
    doc = tomllib.loads(Path(load_machine("grbl-ring").path).read_text())
    del doc["ring"]["steps_per_deg"], doc["head"]["steps_per_mm"]
    report = compare(machine_from_dict(doc), grbl_settings(s100=40.0))
    assert verdicts(report)["$100"] is Verdict.UNCHECKED and report.agrees


def test_marlin_rules_and_the_endstops_note():
    m = load_machine("marlin-ring")
    s = fs.MarlinSettings(steps={"Y": 80.0, "A": 44.44}, max_feed={"Y": 40.0, "A": 120.0},
                          max_accel={"Y": 400.0, "A": 300.0}, accel={"P": 3000.0, "T": 300.0},
                          soft_endstops=True, soft_min={"Y": 0.0, "A": -360.0}, soft_max={"Y": 200.0, "A": 360.0})
    report = compare(m, s)
    assert report.fixes == ["M204 T400", "M211 S0", "M500"]
    assert "software endstops on again at every start" in report.notes[0]
    s.soft_endstops, s.accel["T"] = False, 400.0
    assert compare(m, s).agrees


def test_dynamixel_rules():
    m = load_machine("dynamixel-ring")
    servo = {"Operating Mode": 3, "Drive Mode": 0, "Velocity Limit": 128, "Min Position Limit": 0,
             "Max Position Limit": 4095, "model": 1020}
    firmware = {"ring": {**servo, "id": 1}, "head": {**servo, "id": 2}}
    report = compare(m, firmware)
    assert report.agrees
    assert [r.verdict for r in report.rows if "Operating Mode" in r.setting] == [Verdict.SET_AT_START, Verdict.OK]
    firmware["ring"]["Drive Mode"] = 5                                         # reverse + time-based
    firmware["head"]["Min Position Limit"] = 1900
    report = compare(m, firmware)
    assert report.fixes == ["1:Drive Mode=0", "2:Min Position Limit=1800"]
    import tomllib
    from pathlib import Path

    from firmware_protocol.machine import machine_from_dict
    doc = tomllib.loads(Path(m.path).read_text())
    doc["controller"]["ticks_per_turn"] = 1024
    doc["ring"]["feed_deg_per_min"] = 5000.0
    report = compare(machine_from_dict(doc), {"ring": {**servo, "id": 1}, "head": {**servo, "id": 2}})
    wrong = report.disagreements[0]
    assert "ticks per turn" in wrong.setting and wrong.fix == () and "ticks_per_turn = 4096" in wrong.hint
    notes = [r for r in report.rows if r.verdict is Verdict.NOTE]
    assert notes and "set ring.feed_deg_per_min" in notes[0].hint


def test_apply_without_a_terminal_is_one_line_and_sends_nothing(tmp_path):
    import subprocess
    import sys
    port = url(tmp_path, "grbl-ring", "$100=40")
    p = subprocess.run([sys.executable, "-m", "stringbot.cli", "machines", "check", "grbl-ring", "--port", port,
                        "--apply"], stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    assert p.stderr.splitlines()[-1] == (
        "stringbot: error: --apply asks before sending, but standard input ended (not a terminal); "
        "nothing was sent: run in a terminal, or add --yes")
    assert "Traceback" not in p.stderr


# ---- every bundled machine, mis-set as a user does it -------------------------------------------

def _kind(name):
    m = load_machine(name)
    return m["controller.dialect"] or m["controller.kind"]


@pytest.mark.parametrize("machine", bundled_machines())
def test_every_bundled_machine_mis_set_through_sim_url_names_the_disagreement(tmp_path, capsys, machine):
    """``sim://?machine=M&set=...`` takes its kind's ``--set`` form (fluidnc-ring ended in KeyError)."""
    setting = fs.PRESET_EXAMPLES[_kind(machine)]
    code, out, err = run(["machines", "check", machine, "--port", url(tmp_path, machine, setting)], capsys)
    assert code == 1, err
    assert "Traceback" not in err and err.count("\n") == 1
    assert "DISAGREES" in out and "to fix, send these lines" in out
    code, out, err = run(["machines", "check", machine, "--port", url(tmp_path, machine, setting), "--apply",
                          "--yes"], capsys)
    assert code == 0, err
    assert PERSISTENCE[_kind(machine)] in out


@pytest.mark.parametrize("machine", on_a_pty(bundled_machines()))
def test_every_bundled_machine_mis_set_with_simulate_set_is_found_over_its_pty(tmp_path, machine):
    """``stringbot simulate --machine M --set ...`` in one process, ``machines check M --port PTY``
    in another, as a user practises on a mis-set machine."""
    import signal
    import subprocess

    setting = fs.PRESET_EXAMPLES[_kind(machine)]
    pty = tmp_path / "tty"
    sim = subprocess.Popen(["stringbot", "simulate", "--machine", machine, "--pty", str(pty), "--set", setting],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = sim.stdout.readline()
        assert line.startswith(f"simulating {machine} on {pty}"), sim.stderr.read() if not line else line
        check = subprocess.run(["stringbot", "machines", "check", machine, "--port", str(pty)],
                               capture_output=True, text=True, timeout=50)
    finally:
        sim.send_signal(signal.SIGINT)
        _, err = sim.communicate(timeout=20)
    assert "Traceback" not in err
    assert check.returncode == 1, check.stderr
    assert "DISAGREES" in check.stdout
    assert check.stderr == (f"stringbot: error: 1 setting(s) of the firmware disagree with machine file "
                            f"{machine}\n")
