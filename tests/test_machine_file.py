import pytest

from firmware_protocol.machine import MachineFileError, bundled_machines, load_machine

BASE = """
name = "t"
[ring]
pins = 300
diameter_mm = 500.0
pin_diameter_mm = 1.5
[head]
in_mm = 0.0
out_mm = 12.0
[controller]
kind = "gcode"
dialect = "grbl"
ring_axis = "X"
head_axis = "Y"
[thread]
diameter_mm = 0.25
"""


def write(tmp_path, text):
    path = tmp_path / "m.toml"
    path.write_text(text)
    return path


def test_bundled_grbl_ring_loads_with_derived_geometry():
    assert "grbl-ring" in bundled_machines()
    m = load_machine("grbl-ring")
    assert m.pins == 300
    assert m.pitch_deg == pytest.approx(1.2)
    assert m.free_gap_mm == pytest.approx(3.14159 * 500 / 300 - 1.75, abs=1e-3)
    assert 0 < m.gap_tolerance_deg < m.pitch_deg / 2


@pytest.mark.parametrize("old, new, words", [
    ("pins = 300", "pins = 300\npin_count = 3", "unknown key 'ring.pin_count'"),
    ("pins = 300", 'pins = "300"', "ring.pins is '300'; expected an integer"),
    ("out_mm = 12.0", "out_mm = 0.0", "head.in_mm equals head.out_mm"),
    ("pin_diameter_mm = 1.5", "pin_diameter_mm = -1.5", "ring.pin_diameter_mm"),
    ("pins = 300", "pins = 3000", "the pins do not fit"),
    ('ring_axis = "X"', 'ring_axis = "A"', "controller.ring_axis is 'A'"),
    ('head_axis = "Y"', 'head_axis = "X"', "both 'X'"),
    ("[thread]\ndiameter_mm = 0.25", "", "missing section [thread]"),
])
def test_bad_machine_files_name_the_key(tmp_path, old, new, words):
    text = BASE.replace(old, new)
    assert text != BASE
    with pytest.raises(MachineFileError) as info:
        load_machine(write(tmp_path, text))
    assert words in str(info.value)


def test_unknown_machine_lists_the_bundled_ones():
    with pytest.raises(MachineFileError, match="grbl-ring"):
        load_machine("no-such-machine")
