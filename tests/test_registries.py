"""Each kind of thing is named in one place, and the help, the docs and the runs follow it.

The planner's methods (``stringbot/planner/methods/__init__.py``) and the simulator's fault kinds
(``firmware_protocol/faults.py``; the Dynamixel bus's own in its emulator) are registries:
these tests fail when ``--help`` or a docs table leaves a kind out or names one that is not
there, and run every method through ``stringbot plan`` as a user does.
"""

import json
import os
import re
import subprocess
from pathlib import Path

import pytest

from firmware_protocol.emulators.dynamixel import FAULT_ALIASES
from firmware_protocol.emulators.dynamixel import FaultKind as DynamixelFault
from firmware_protocol.faults import FAULT_KINDS, parse_faults
from stringbot.planner.methods import DEFAULT_METHOD, METHODS

ROOT = Path(__file__).resolve().parents[1]


def help_text(*command):
    """``stringbot COMMAND --help`` as the user reads it, its wrapping undone."""
    out = subprocess.run(["stringbot", *command, "--help"], capture_output=True, text=True, check=True).stdout
    return " ".join(re.sub(r"(?<=\w)-\n\s*(?=\w)", "-", out).split())     # drop-ok wrapped as drop-/ok


def table_after(page, heading):
    """The first column of the first table after the line starting with ``heading``, backticks off."""
    text = (ROOT / "docs" / page).read_text()
    start = text.index(heading)
    rows = re.search(r"\n(\|.*\|\n)+", text[start:]).group(0).strip().splitlines()[2:]
    return [row.split("|")[1].strip() for row in rows]


def kind_cells(cells):
    return [re.match(r"`([\w-]+)", cell).group(1) for cell in cells]


# ---- fault kinds ----------------------------------------------------------------------------------

@pytest.mark.parametrize("command", [("simulate",), ("wind",)])
def test_every_fault_kind_is_in_the_help(command):
    text = help_text(*command)
    for kind in FAULT_KINDS:
        assert re.search(rf"(?<![\w-]){re.escape(kind)}(?![\w-])", text), f"stringbot {command[0]} --help: {kind}"


def test_the_simulator_docs_tables_are_the_fault_kinds_exactly():
    machine = kind_cells(table_after("simulator.md", "Faults that hit the machine"))
    line = kind_cells(table_after("simulator.md", "Faults that hit a line"))
    assert sorted(machine) == sorted(k.name for k in FAULT_KINDS.values() if k.hits == "machine")
    assert sorted(line) == sorted(k.name for k in FAULT_KINDS.values() if k.hits == "line")


def test_the_dynamixel_docs_table_is_its_fault_kinds_exactly():
    cells = table_after("dynamixel.md", "Faults (`--faults`")
    # each row: the short form, then (in brackets) the long one or another name for it
    named = {m for c in cells for m in re.findall(r"`(\w+)@", c)}
    assert {FAULT_ALIASES.get(n, n) for n in named} == {k.value for k in DynamixelFault}


@pytest.mark.parametrize("kind", list(FAULT_KINDS.values()), ids=list(FAULT_KINDS))
def test_every_fault_kind_parses_in_each_form_its_scope_takes(kind):
    assert [f.kind for f in parse_faults(f"{kind.name}@7")] == [kind.name]
    ranged, timed = f"{kind.name}@7..9", f"{kind.name}@t=2.5"
    if kind.hits == "line":
        assert parse_faults(ranged)[0].last == 9
        with pytest.raises(ValueError, match="hits a line as it arrives"):
            parse_faults(timed)
    else:
        assert parse_faults(timed)[0].time == 2.5
        with pytest.raises(ValueError, match="fires once"):
            parse_faults(ranged)


def test_a_fault_kind_that_is_not_there_is_refused_naming_every_kind():
    with pytest.raises(ValueError) as info:
        parse_faults("meltdown@3")
    assert all(k in str(info.value) for k in FAULT_KINDS)


# ---- planner methods -------------------------------------------------------------------------------

def test_every_method_is_a_choice_of_plan_with_its_summary_and_the_default():
    text = help_text("plan")
    assert f"--method [{'|'.join(METHODS)}]" in text
    for m in METHODS.values():
        assert f"{m.name}: {m.summary}" in text
    assert f"[default: {DEFAULT_METHOD}]" in text


def test_every_method_has_its_part_in_docs_planner():
    planner = (ROOT / "docs" / "planner.md").read_text()
    methods_part = planner[planner.index("## What the methods do"):planner.index("## Colour")]
    said = re.findall(r"^\*\*(\w+)\*\* \(", methods_part, re.M)
    assert said == list(METHODS)
    assert f"**{DEFAULT_METHOD}** (the default" in methods_part
    row = re.search(r"^\| `--method ([\w\\|]+)` \| (\w+) \|", planner, re.M)
    assert row.group(1).split("\\|") == list(METHODS) and row.group(2) == DEFAULT_METHOD


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_plans_a_small_picture_through_the_command_line(tmp_path, method):
    """A small plan (60 pins, 101 px, 40 lines): the plan file names the method, its sequence is
    one thread over the frame's pins, and ``score`` reads it."""
    out = tmp_path / "p.json"
    env_cache = {"STRINGBOT_CACHE": str(tmp_path / "cache")}
    p = subprocess.run(["stringbot", "plan", str(ROOT / "examples" / "camera.png"), "-o", str(out), "--method",
                        method, "--pins", "60", "--size", "101", "--lines", "40"], capture_output=True, text=True,
                       env={**os.environ, **env_cache}, timeout=120)
    assert p.returncode == 0, p.stderr
    plan = json.loads(out.read_text())
    seq = plan["sequence"]
    assert plan["method"] == method and plan["parameters"]["method"] == method
    assert 2 <= len(seq) <= 41 and all(0 <= x < 60 for x in seq) and all(a != b for a, b in zip(seq, seq[1:]))
    s = subprocess.run(["stringbot", "score", str(out), "--json"], capture_output=True, text=True, timeout=120,
                       env={**os.environ, **env_cache})
    assert s.returncode == 0, s.stderr
    assert 0 < json.loads(s.stdout)["ssim"] <= 1


def test_a_knob_of_one_method_given_to_another_names_the_methods_that_take_it(tmp_path):
    from stringbot.errors import BadInput
    from stringbot.planner.build import plan_picture
    from stringbot.planner.methods import methods_taking

    others = [m for m in METHODS if m not in methods_taking("style")]
    with pytest.raises(BadInput, match=f"knobs of --method {' or '.join(methods_taking('style'))};"):
        plan_picture(ROOT / "examples" / "camera.png", method=others[0], style="fill", pins=60, size=101)
