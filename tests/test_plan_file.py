import json

import numpy as np
import pytest

from stringbot.errors import BadInput
from stringbot.planner import Plan, read_plan, write_plan


def small_plan(**kw):
    pins = kw.pop("pins", 8)
    a = np.arange(pins) * 2 * np.pi / pins
    xy = np.stack([0.5 + 0.5 * np.sin(a), 0.5 - 0.5 * np.cos(a)], axis=1)
    args = dict(pins=pins, frame="circle", pin_xy=xy, crop={"cx": 50, "cy": 50, "r": 50},
                sequence=[0, 4, 1, 5, 2], method="hand", parameters={}, stats={"lines": 4},
                source={"path": "x.png", "sha256": "0" * 64, "width": 100, "height": 100})
    args.update(kw)
    return Plan(**args)


def test_round_trip(tmp_path):
    path = tmp_path / "p.json"
    write_plan(small_plan(), path)
    back = read_plan(path)
    assert back.sequence == [0, 4, 1, 5, 2]
    assert back.pins == 8 and back.connected
    assert np.allclose(back.pin_xy[0], [0.5, 0.0])
    assert back.chord_list() == [(0, 4), (4, 1), (1, 5), (5, 2)]
    assert back.sha256() == small_plan().sha256()


def test_unknown_fields_are_kept_not_fatal(tmp_path):
    path = tmp_path / "p.json"
    doc = json.loads(small_plan().to_json())
    doc["future_field"] = {"x": 1}
    path.write_text(json.dumps(doc))
    extra = read_plan(path).extra
    assert extra["future_field"] == {"x": 1}
    assert set(extra) <= {"future_field", "diameter_mm", "thread_mm"}  # the thread fields are read and kept


@pytest.mark.parametrize("change, words", [
    (lambda d: d.pop("sequence"), "missing field 'sequence'"),
    (lambda d: d.update(format="other"), "'format'"),
    (lambda d: d.update(version=2), "version 2"),
    (lambda d: d.update(pins=2), "'pins'"),
    (lambda d: d.update(frame="hexagon"), "'frame'"),
    (lambda d: d.update(sequence=[0, 9, 1]), "sequence[1]"),
    (lambda d: d.update(sequence=[0, 3, 3]), "repeats pin 3"),
    (lambda d: d.update(pin_xy=[[0, 0]]), "'pin_xy'"),
    (lambda d: d["crop"].pop("r"), "crop.r"),
    (lambda d: d.update(connected=False), "missing field 'chords'"),
])
def test_contract_violations_name_the_field(tmp_path, change, words):
    doc = json.loads(small_plan().to_json())
    change(doc)
    path = tmp_path / "p.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(BadInput, match=None) as info:
        read_plan(path)
    assert words in str(info.value)


def test_not_json_and_not_a_file(tmp_path):
    (tmp_path / "bad.json").write_text("{nope")
    with pytest.raises(BadInput, match=r"is not JSON \(Expecting property name enclosed in double quotes: line 1 "
                                       r"column 2\)"):
        read_plan(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"a": 1}')
    with pytest.raises(BadInput, match="missing field 'format'; expected 'stringbot-plan'"):
        read_plan(tmp_path / "other.json")
    (tmp_path / "pic.json").write_bytes(b"\x89PNG\r\n\x1a\n")
    with pytest.raises(BadInput, match=r"is not a text file \(a picture\?\); expected a plan file"):
        read_plan(tmp_path / "pic.json")
    with pytest.raises(BadInput, match="is a folder"):
        read_plan(tmp_path)
    with pytest.raises(BadInput, match="does not exist"):
        read_plan(tmp_path / "missing.json")


def test_write_into_missing_folder_refused_and_old_file_kept(tmp_path):
    with pytest.raises(BadInput, match="does not exist"):
        write_plan(small_plan(), tmp_path / "nope" / "p.json")
    path = tmp_path / "p.json"
    path.write_text("old")
    with pytest.raises(BadInput, match="is a folder"):
        write_plan(small_plan(), tmp_path)
    assert path.read_text() == "old"


def test_written_files_get_the_usual_mode_not_a_private_temp_mode(tmp_path):
    import os
    path = tmp_path / "p.json"
    old = os.umask(0o022)
    try:
        write_plan(small_plan(), path)
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o644
    path.chmod(0o600)
    write_plan(small_plan(), path)
    assert path.stat().st_mode & 0o777 == 0o600
