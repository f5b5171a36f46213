"""The simulator's record after an interrupted write: Ctrl-C (or any exception) during the
record's fsync must not leave the file behind the world once the simulator closes."""

import json
import os

import pytest

from firmware_protocol.machine import load_machine
from firmware_protocol.world import World


def test_a_record_write_cut_short_is_redone_when_the_world_closes(tmp_path, monkeypatch):
    rec = tmp_path / "rec.json"
    world = World(load_machine("grbl-ring"), record_path=rec, save_interval=3600.0)
    world.move(0.0, 1.0)                       # motion alone, inside the circle: written later
    real_fsync = os.fsync

    def interrupted(fd):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        world.flush()                          # Ctrl-C lands during the write
    monkeypatch.setattr(os, "fsync", real_fsync)
    assert json.loads(rec.read_text())["head_mm"] != 1.0     # the file is behind the world
    world.close()
    assert json.loads(rec.read_text())["head_mm"] == 1.0


def test_a_record_write_cut_short_is_retried_by_the_next_flush(tmp_path, monkeypatch):
    rec = tmp_path / "rec.json"
    world = World(load_machine("grbl-ring"), record_path=rec, save_interval=3600.0)
    world.move(0.0, 1.0)
    monkeypatch.setattr(os, "fsync", lambda fd: (_ for _ in ()).throw(OSError(28, "No space left")))
    with pytest.raises(OSError):
        world.flush()
    monkeypatch.undo()
    world.flush()
    assert json.loads(rec.read_text())["head_mm"] == 1.0
