"""A kind of firmware is one record (firmware_protocol/kinds.py): the host and the simulator read
the same one, so what the emulator of a kind prints is what the host recognises as that kind.

Every kind's emulator, as bytes: its start-up line is the kind's banner (the one detector resume's
recovery asks), its identification answer names the kind, its ``--set`` example is taken.  A kind
the records do not hold is refused in one place, by every way of making a link.  Every kind has a
bundled machine, so the registry-driven wind, resume and fault tests (tests/bundled.py) run it.
"""

import re
from pathlib import Path

import pytest

from firmware_protocol import grbl as grbl_codes
from firmware_protocol.emulators.factory import build_emulator
from firmware_protocol.kinds import KINDS, family, get_kind, gcode_kinds, kind_of
from firmware_protocol.machine import Machine, load_machine
from firmware_protocol.settings import parse_preset
from stringbot.errors import BadInput
from stringbot.links import gcode_link, gcode_machine_link, open_link
from stringbot.motion import dialect_for

from bundled import MACHINES

ROOT = Path(__file__).resolve().parents[1]
BY_KIND = {}
for _name in MACHINES:
    BY_KIND.setdefault(kind_of(load_machine(_name)).name, _name)
GCODE = [k for k in gcode_kinds()]


def test_every_kind_has_a_bundled_machine_that_the_tests_run():
    assert set(BY_KIND) == set(KINDS), f"kinds without a machine file in machines/: {set(KINDS) - set(BY_KIND)}"


def _start(emu, query):
    """What the emulator says on power-up and to its identification query, as lines."""
    out = emu.transmit()
    emu.receive(query)
    for _ in range(50):
        emu.advance(0.01)
        out += emu.transmit()
    return [x for x in out.decode("latin-1").replace("\r", "").split("\n") if x]


@pytest.mark.parametrize("kind", [k for k in GCODE if KINDS[k].family == "grbl"])
def test_a_grbl_family_emulator_prints_its_kinds_banner_and_is_identified_as_its_kind(kind):
    emu, _ = build_emulator(BY_KIND[kind])
    lines = _start(emu, b"$I\n")
    banners = [x for x in lines if grbl_codes.is_banner(x)]
    assert banners and all(KINDS[kind].is_banner(x) for x in banners), lines
    found = grbl_codes.identify(lines)
    assert found is not None and found.kind == kind, (lines, found)
    assert found.version, lines
    # and no other kind of the family takes its banner for its own, except the family's own kind
    others = [k for k in family("grbl") if k.name not in (kind, "grbl")]
    assert not any(k.is_banner(x) for k in others for x in banners)


def test_marlins_emulator_starts_with_its_kinds_banner_and_names_itself_to_m115():
    emu, _ = build_emulator(BY_KIND["marlin"])
    lines = _start(emu, b"M115\n")
    assert any(KINDS["marlin"].is_banner(x) for x in lines) and not any(grbl_codes.is_banner(x) for x in lines)
    assert KINDS["marlin"].found_in(lines) and grbl_codes.identify(lines) is None


@pytest.mark.parametrize("kind", list(KINDS))
def test_every_kinds_set_example_is_taken_by_its_emulator(kind):
    preset = parse_preset(kind, KINDS[kind].set_example)
    emu, _ = build_emulator(BY_KIND[kind], settings=[preset.text])
    assert emu is not None


@pytest.mark.parametrize("kind", GCODE)
def test_the_host_and_the_emulator_agree_on_the_sync_line_and_the_axes(kind):
    machine = load_machine(BY_KIND[kind])
    rec = KINDS[kind]
    assert dialect_for(machine).sync() == rec.sync_line
    ring, head = machine["controller.ring_axis"], machine["controller.head_axis"]
    emu, _ = build_emulator(machine)
    assert emu.axes == rec.status_axes(ring, head)


def _unknown(dialect="no-such-firmware"):
    """A machine whose controller.dialect no record holds (made past the machine file's check)."""
    base = load_machine("grbl-ring")
    return Machine(name="odd-ring", path=None, values=dict(base.values, **{"controller.dialect": dialect}))


def test_a_kind_the_records_do_not_hold_is_refused_the_same_way_by_every_way_to_a_link():
    from test_wind_sim import EmulatorPort

    port = EmulatorPort(build_emulator("grbl-ring")[0])
    said = []
    for make in (lambda: gcode_link(port, _unknown()), lambda: gcode_machine_link(port, _unknown()),
                 lambda: open_link("sim://?machine=grbl-ring", _unknown()), lambda: dialect_for(_unknown())):
        with pytest.raises(BadInput) as info:
            make()
        said.append(str(info.value))
    assert len(set(said)) == 1, said
    assert "unknown firmware 'no-such-firmware'" in said[0] and all(k in said[0] for k in GCODE)


def test_get_kind_names_every_kind():
    with pytest.raises(ValueError, match="expected one of " + ", ".join(GCODE) + " .*'dynamixel'"):
        get_kind("no-such-firmware")


def test_the_machine_file_docs_list_every_g_code_kind():
    row = next(x for x in (ROOT / "docs" / "machines.md").read_text().splitlines() if x.startswith("| `dialect` |"))
    assert re.findall(r'`"(\w+)"`', row) == GCODE, row
