"""`stringbot wind --status` reports the machine's winding, not a dry run's, unless told."""

import subprocess
import sys

from stringbot.planner import write_plan
from tests.test_wind_sim import small_plan


def run(*args):
    return subprocess.run([sys.executable, "-m", "stringbot.cli", *args], capture_output=True, text=True,
                          timeout=120)


def test_status_prefers_the_real_winding_over_a_dry_run(tmp_path):
    plan = tmp_path / "p.json"
    p = small_plan(n=6)
    write_plan(p, plan)
    dry = run("wind", str(plan), "--machine", "grbl-ring", "--yes")
    assert dry.returncode == 0, dry.stderr
    only_dry = run("wind", str(plan), "--machine", "grbl-ring", "--status")
    assert only_dry.returncode == 0, only_dry.stderr
    assert "p.json.dry-run.journal" in only_dry.stdout

    # a "real" winding: the machine reached through a port URL keeps the plan's own journal
    url = f"sim://?machine=grbl-ring&record={tmp_path / 'rec.json'}"
    real = run("wind", str(plan), "--machine", "grbl-ring", "--port", url, "--yes")
    assert real.returncode == 0, real.stderr
    status = run("wind", str(plan), "--machine", "grbl-ring", "--status")
    assert status.returncode == 0, status.stderr
    first = status.stdout.splitlines()[0]
    assert first.endswith("p.json.journal") and "dry-run" not in first
    assert f"finished: all {len(p.sequence)} steps done" in status.stdout

    chosen = run("wind", str(plan), "--machine", "grbl-ring", "--status",
                 "--journal", str(tmp_path / "p.json.dry-run.journal"))
    assert "dry-run" in chosen.stdout.splitlines()[0]


def test_status_of_a_plan_never_wound_says_so(tmp_path):
    plan = tmp_path / "p.json"
    write_plan(small_plan(n=6), plan)
    none = run("wind", str(plan), "--machine", "grbl-ring", "--status")
    assert none.returncode == 2
    lines = none.stderr.strip().splitlines()
    assert len(lines) == 1 and "no winding of this plan to report" in lines[0] and "resume" not in lines[0]
    assert sorted(f.name for f in tmp_path.iterdir()) == ["p.json"]   # a status query writes nothing


def test_a_missing_journal_named_by_hand_is_blamed_on_the_path(tmp_path):
    plan = tmp_path / "p.json"
    write_plan(small_plan(n=6), plan)
    missing = str(tmp_path / "elsewhere.journal")
    default = run("wind", str(plan), "--machine", "grbl-ring", "--status")
    given = run("wind", str(plan), "--machine", "grbl-ring", "--status", "--journal", missing)
    resumed = run("wind", str(plan), "--machine", "grbl-ring", "--port", "loop://", "--resume",
                  "--journal", missing)
    assert "give --journal" in default.stderr
    for r in (given, resumed):
        line = r.stderr.strip()
        assert r.returncode == 2 and len(line.splitlines()) == 1, r.stderr
        assert "elsewhere.journal" in line and "check the --journal path" in line
        assert "give --journal" not in line
    assert sorted(f.name for f in tmp_path.iterdir()) == ["p.json"]
