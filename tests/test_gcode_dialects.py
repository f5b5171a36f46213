"""Dialect details: axis letters, homing, sync points, dwell units, number format, progress comments."""

import pytest

from firmware_protocol.machine import load_machine
from stringbot.errors import BadInput
from stringbot.motion import HookStep, Move, dialect_for
from stringbot.motion.gcode import fmt


def test_number_format():
    assert [fmt(x) for x in (0.0, -0.0, 1.2, 1.20000001, -0.00001, 12.0, 36000.123449, 1e-5)] == \
        ["0", "0", "1.2", "1.2", "0", "12", "36000.1234", "0"]


@pytest.mark.parametrize("name, sync, home, dwell, end", [
    ("grbl-ring", "G4 P0", [], "G4 P0.25", ["G4 P0", "M2"]),
    ("grblhal-ring", "G4 P0", ["$H", "G10 L20 P1 A0 X0"], "G4 P0.25", ["G4 P0", "M2"]),
    ("marlin-ring", "M400", ["G28 Y A", "G92 A0 Y20"], "G4 P250", ["M400", "M117 stringbot: done"]),
])
def test_dialects_differ_where_the_firmware_does(name, sync, home, dwell, end):
    d = dialect_for(load_machine(name))
    assert d.sync() == sync and d.home() == home and d.dwell(0.25) == dwell and d.end() == end
    assert d.preamble()[:2] == ["G21", "G90"]
    assert ("G94" in d.preamble()) == (name != "marlin-ring")


def test_step_lines_progress_comment_moves_and_dwell():
    m = load_machine("grblhal-ring")
    d = dialect_for(m)
    step = HookStep(index=4, pin=17, direction=1, total=2530, dwell_s=5.0,
                    moves=[Move(20.4, 0.0, 10800.0), Move(20.4, 10.0, 4000.0), Move(21.6, 10.0, None)])
    # each line names only the axis it moves: a ring move cannot move the head, nor the reverse
    assert d.step_lines(step) == ["; pin 17 (step 5/2530)", "G1 A20.4 X0 F10800", "G1 X10 F4000",
                                  "G1 A21.6", "G4 P5"]
    assert d.step_lines(step, prev=Move(19.2, 0.0))[1] == "G1 A20.4 F10800"


def test_dynamixel_machines_have_no_gcode_dialect():
    with pytest.raises(BadInput, match="controller.kind = 'dynamixel'"):
        dialect_for(load_machine("dynamixel-ring"))
