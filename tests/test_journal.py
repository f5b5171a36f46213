"""The journal: append-only JSON lines, a torn last record tolerated, a damaged one refused."""

import pytest

from stringbot.errors import BadInput
from stringbot.winding import Journal, journal_path_for, read_journal


def make(tmp_path, durable=True):
    j = Journal.create(tmp_path / "j", plan_path="p.json", plan_sha256="ab" * 32, machine="grbl-ring",
                       steps=5, durable=durable)
    return j


def test_records_read_back(tmp_path):
    j = make(tmp_path)
    j.done(0, 7)
    j.append({"kind": "move", "step": 1, "move": 1})
    j.close()
    state = read_journal(tmp_path / "j")
    assert state.done == [0] and state.next_step == 1 and state.next_move == 2
    assert state.header["machine"] == "grbl-ring" and state.steps_total == 5
    assert not state.finished and not state.torn


def test_a_torn_last_record_is_ignored_and_closed_on_reopen(tmp_path):
    j = make(tmp_path)
    j.done(0, 7)
    j.close()
    with open(tmp_path / "j", "ab") as f:
        f.write(b'{"kind":"done","st')                # the computer died mid-write
    state = read_journal(tmp_path / "j")
    assert state.done == [0] and state.torn
    j = Journal.reopen(tmp_path / "j")
    j.done(1, 3)
    j.close()
    state = read_journal(tmp_path / "j")
    assert state.done == [0, 1]


def test_a_damaged_record_in_the_middle_is_refused(tmp_path):
    j = make(tmp_path)
    j.done(0, 7)
    j.close()
    text = (tmp_path / "j").read_text().splitlines()
    text.insert(1, "garbage")
    (tmp_path / "j").write_text("\n".join(text) + "\n")
    with pytest.raises(BadInput, match="line 2 is damaged"):
        read_journal(tmp_path / "j")


@pytest.mark.parametrize("content, words", [
    (b"", "header"),
    (b'{"kind":"start","format":"other"}\n', "header"),
    (b'{"kind":"start","format":"stringbot-journal","version":9}\n', "version 9"),
])
def test_not_a_journal(tmp_path, content, words):
    (tmp_path / "j").write_bytes(content)
    with pytest.raises(BadInput, match=words):
        read_journal(tmp_path / "j")


def test_missing_journal_and_folder(tmp_path):
    with pytest.raises(BadInput, match="does not exist"):
        read_journal(tmp_path / "nope")
    with pytest.raises(BadInput, match="folder"):
        read_journal(tmp_path)
    with pytest.raises(BadInput, match="does not exist"):
        Journal.create(tmp_path / "no" / "j", plan_path="p", plan_sha256="x", machine="m", steps=1)


def test_from_step_moves_the_next_step(tmp_path):
    j = make(tmp_path)
    for i in range(4):
        j.done(i, i)
    j.append({"kind": "resume", "from_step": 2, "from_move": 0})
    j.close()
    state = read_journal(tmp_path / "j")
    assert state.next_step == 2 and state.done == [0, 1]


def test_default_path_is_beside_the_plan(tmp_path):
    assert journal_path_for(tmp_path / "cam.json") == tmp_path / "cam.json.journal"
    assert journal_path_for(tmp_path / "cam.json", dry_run=True) == tmp_path / "cam.json.dry-run.journal"
