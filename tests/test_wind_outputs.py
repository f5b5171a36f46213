"""`wind --record` and `--journal` never overwrite the plan or a file that is not theirs (exit 2,
one line naming it, the file untouched)."""

import json

import pytest

from stringbot.planner import write_plan
from stringbot.winding import Journal

from test_wind_cli import run
from test_wind_sim import small_plan

PNG = b"\x89PNG\r\n\x1a\n" + bytes(range(256))


@pytest.fixture
def plan_path(tmp_path):
    path = tmp_path / "plan.json"
    write_plan(small_plan(n=8, seed=2), path)
    return path


def one_error(err):
    lines = [x for x in err.splitlines() if x.startswith("stringbot:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("option", ["--record", "--journal"])
def test_the_plan_is_not_an_output(tmp_path, plan_path, capsys, option, monkeypatch):
    before = plan_path.read_bytes()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sub").mkdir()
    # the same file by another spelling
    code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes",
                          option, "./sub/../plan.json"], capsys)
    assert code == 2
    line = one_error(err)
    assert "is the plan itself" in line and option in line
    assert plan_path.read_bytes() == before


@pytest.mark.parametrize("option, words", [
    ("--record", "not a simulated world's record"),
    ("--journal", "is not a stringbot journal"),
])
def test_a_foreign_file_is_not_overwritten(tmp_path, plan_path, capsys, option, words):
    picture = tmp_path / "photo.png"
    picture.write_bytes(PNG)
    code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes",
                          option, str(picture)], capsys)
    assert code == 2
    line = one_error(err)
    assert words in line and "photo.png" in line
    assert picture.read_bytes() == PNG


def test_an_old_record_and_an_old_journal_are_replaced(tmp_path, plan_path, capsys):
    record, journal = tmp_path / "rec.json", tmp_path / "j"
    args = ["wind", str(plan_path), "--machine", "grbl-ring", "--yes", "--record", str(record),
            "--journal", str(journal)]
    from firmware_protocol.urlhandler import protocol_sim
    assert run(args, capsys)[0] == 0
    protocol_sim.forget()                      # in one process a sim:// URL keeps its machine
    assert run(args, capsys)[0] == 0           # both are ours: a second dry run replaces them
    assert [w["pin"] for w in json.loads(record.read_text())["wraps"]] == small_plan(n=8, seed=2).sequence


def test_a_record_in_a_missing_folder_names_the_folder(tmp_path, plan_path, capsys):
    code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes",
                          "--record", str(tmp_path / "nope" / "rec.json")], capsys)
    assert code == 2
    line = one_error(err)
    assert "record folder" in line and "nope" in line and "port" not in line


def test_record_and_journal_in_one_file_is_refused(tmp_path, plan_path, capsys):
    both = tmp_path / "out.json"
    code, out, err = run(["wind", str(plan_path), "--machine", "grbl-ring", "--yes",
                          "--record", str(both), "--journal", str(both)], capsys)
    assert code == 2 and "journal's file too" in one_error(err)
    assert not both.exists()


def test_journal_create_refuses_a_file_that_is_not_a_journal(tmp_path):
    from stringbot.errors import BadInput
    other = tmp_path / "notes.txt"
    other.write_text("my notes\n")
    with pytest.raises(BadInput, match="not a stringbot journal"):
        Journal.create(other, plan_path="p.json", plan_sha256="x", machine="m", steps=1)
    assert other.read_text() == "my notes\n"
    j = Journal.create(tmp_path / "j", plan_path="p.json", plan_sha256="x", machine="m", steps=1)
    j.close()
    j = Journal.create(tmp_path / "j", plan_path="p.json", plan_sha256="x", machine="m", steps=1)
    j.close()                                   # an old journal is replaced
