"""A journal record with a missing or wrong-typed field is refused with one line (exit 2), never
a traceback; a torn last line is still ignored."""

import json
import subprocess
import sys

import pytest

from stringbot.errors import BadInput
from stringbot.planner import write_plan
from stringbot.winding import Journal, read_journal

from test_wind_sim import small_plan

HEADER = {"kind": "start", "format": "stringbot-journal", "version": 1, "plan": "p.json",
          "plan_sha256": "ab" * 32, "machine": "grbl-ring", "steps": 5, "t": 1.0}


def write(path, *records, tail=b""):
    path.write_bytes(b"".join(json.dumps(r).encode() + b"\n" for r in (HEADER,) + records) + tail)
    return path


@pytest.mark.parametrize("record, words", [
    ({"kind": "done"}, "done record without step"),
    ({"kind": "done", "step": "x", "pin": 3}, "done record's step is 'x'"),
    ({"kind": "done", "step": 1}, "done record without pin"),
    ({"kind": "done", "step": 7, "pin": 3}, "done record's step is 7; expected a step index 0..4"),
    ({"kind": "done", "step": True, "pin": 3}, "step is True"),
    ({"kind": "move", "step": 1, "move": None}, "move record's move is None"),
    ({"kind": "resume", "from_step": None}, "resume record's from_step is None"),
    ({"kind": "resume", "from_step": 2, "from_move": "0"}, "from_move is '0'"),
    ({"kind": "stop", "at": {"step_index": "a", "move": 0}}, "stop record's at is"),
    ({"kind": "stop", "position": ["x", 1]}, "stop record's position is"),
    ({"kind": "done", "step": 1, "pin": 3, "t": "noon"}, "t is 'noon'"),
    ({"kind": 5}, "kind is 5"),
    (HEADER, "a second header"),
])
def test_a_damaged_record_is_refused_naming_the_line(tmp_path, record, words):
    path = write(tmp_path / "j", {"kind": "done", "step": 0, "pin": 7, "t": 2.0}, record,
                 {"kind": "done", "step": 2, "pin": 9, "t": 3.0})
    with pytest.raises(BadInput) as info:
        read_journal(path)
    message = str(info.value)
    assert "line 3 is damaged" in message and words in message and "expected" in message


def test_a_header_with_a_bad_step_count_is_refused(tmp_path):
    (tmp_path / "j").write_text(json.dumps(dict(HEADER, steps="5")) + "\n")
    with pytest.raises(BadInput, match="line 1 is damaged: steps is '5'"):
        read_journal(tmp_path / "j")


def test_what_the_winder_writes_still_reads(tmp_path):
    j = Journal.create(tmp_path / "j", plan_path="p.json", plan_sha256="ab" * 32, machine="grbl-ring",
                       steps=5)
    j.done(0, 7)
    j.append({"kind": "move", "step": 1, "move": 1})
    j.append({"kind": "stop", "reason": "failed", "error": "x", "step": 2, "pin": 9, "next_step": 1,
              "at": {"step_index": 1, "move": 2}, "position_lost": False, "position": [1.2, 12.0, 0.0]})
    j.append({"kind": "stop", "reason": "interrupted", "error": "y", "step": None, "pin": None,
              "next_step": 5, "at": None, "position_lost": True, "position": None})
    j.append({"kind": "resume", "from_step": 1, "from_move": 2, "position_lost": False})
    j.append({"kind": "finished"})
    j.close()
    state = read_journal(tmp_path / "j")
    assert state.done == [0] and state.next_step == 1 and state.next_move == 2 and state.finished


def test_a_torn_last_line_is_still_ignored(tmp_path):
    path = write(tmp_path / "j", {"kind": "done", "step": 0, "pin": 7}, tail=b'{"kind":"done","st')
    state = read_journal(path)
    assert state.done == [0] and state.torn


def run(*args):
    return subprocess.run([sys.executable, "-m", "stringbot.cli", *args], capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("extra", [["--status"], ["--resume", "--port", "sim://?machine=grbl-ring"]])
def test_status_and_resume_refuse_a_damaged_journal_with_exit_2(tmp_path, extra):
    plan = tmp_path / "p.json"
    write_plan(small_plan(n=5), plan)
    journal = tmp_path / "p.json.journal"
    journal.write_text(json.dumps(dict(HEADER, plan=str(plan))) + "\n" + '{"kind":"done"}\n')
    proc = run("wind", str(plan), "--machine", "grbl-ring", "--yes", "--journal", str(journal), *extra)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [x for x in proc.stderr.splitlines() if x.startswith("stringbot:")]
    assert len(lines) == 1 and "line 2 is damaged" in lines[0] and "without step" in lines[0]
