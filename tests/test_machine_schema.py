"""The bundled machines and the keys the motion layer added to the machine file."""

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from firmware_protocol.machine import (
    SCHEMA, MachineFileError, bundled_dir, bundled_machines, load_machine, machine_from_dict)
from test_machine_file import BASE

ROOT = Path(__file__).resolve().parents[1]


def test_bundled_machines_all_load_with_300_pins():
    names = bundled_machines()
    assert {"grbl-ring", "grblhal-ring", "marlin-ring", "dynamixel-ring"} <= set(names)
    for name in names:
        assert load_machine(name).pins == 300, name


@pytest.mark.parametrize("name, dialect, ring, head", [
    ("grbl-ring", "grbl", "X", "Y"), ("grblhal-ring", "grblhal", "A", "X"), ("marlin-ring", "marlin", "A", "Y"),
])
def test_gcode_machines_use_their_firmwares_axes(name, dialect, ring, head):
    m = load_machine(name)
    assert (m["controller.dialect"], m["controller.ring_axis"], m["controller.head_axis"]) == (dialect, ring, head)


def test_every_bundled_file_is_commented_and_sets_every_contract_key():
    for path in bundled_dir().glob("*.toml"):
        text = path.read_text()
        assert text.count("#") >= 10, f"{path.name}: comment it like a sample config"
        doc = tomllib.loads(text)
        for section in ("ring", "head", "controller", "thread"):
            assert section in doc, (path.name, section)


def test_winding_section_is_optional_with_defaults():
    m = machine_from_dict(tomllib.loads(BASE), source="base")
    assert m["winding.wrap_direction"] == "auto" and m["winding.dwell_s"] == 0.0
    assert m["winding.pause_every"] == 0


@pytest.mark.parametrize("extra, words", [
    ('[winding]\nwrap_direction = "sideways"', "winding.wrap_direction is 'sideways'; expected one of 'auto'"),
    ("[winding]\ndwell_s = -1", "winding.dwell_s is -1"),
    ("[winding]\npause_every = 2.5", "winding.pause_every is 2.5; expected an integer"),
    ("[winding]\nspeed = 3", "unknown key 'winding.speed'"),
    ("[windings]\ndwell_s = 1", "unknown section [windings]"),
    ("winding = 3", "[winding] is not a table"),
])
def test_bad_winding_keys(extra, words):
    text = (extra + "\n" + BASE) if extra.startswith("winding =") else BASE + extra
    with pytest.raises(MachineFileError) as info:
        machine_from_dict(tomllib.loads(text), source="m")
    assert words in str(info.value)


def test_ring_travel_and_steps_bounds():
    for text, words in [(BASE.replace("pins = 300", "pins = 300\ntravel_deg = 100.0"), "ring.travel_deg is 100.0"),
                        (BASE.replace("pins = 300", "pins = 300\nsteps_per_deg = 0"), "ring.steps_per_deg is 0"),
                        (BASE.replace("pins = 300", "pins = 300\nfeed_deg_per_min = -5"), "ring.feed_deg_per_min")]:
        with pytest.raises(MachineFileError, match=None) as info:
            machine_from_dict(tomllib.loads(text), source="m")
        assert words in str(info.value)


def test_head_home_switch_must_be_inside_the_pin_circle():
    text = BASE.replace('head_axis = "Y"', 'head_axis = "Y"\nhoming = true\nhome_head_mm = 7.0')
    with pytest.raises(MachineFileError, match=r"controller.home_head_mm is 7.0, outside the pin circle"):
        machine_from_dict(tomllib.loads(text), source="m")
    ok = machine_from_dict(tomllib.loads(text.replace("home_head_mm = 7.0", "home_head_mm = -3.0")), source="m")
    assert ok["controller.home_head_mm"] == -3.0


def test_dynamixel_travel_must_fit_the_servos_multi_turn_range():
    doc = tomllib.loads((bundled_dir() / "dynamixel-ring.toml").read_text())
    ratio = doc["controller"]["gear_ratio"]
    doc["ring"]["travel_deg"] = 256 * 360.0 / ratio           # exactly the servo's +-256 turns
    machine_from_dict(doc, source="d")
    doc["ring"]["travel_deg"] = 256 * 360.0 / ratio + 1.0
    with pytest.raises(MachineFileError, match=r"ring.travel_deg .* expected at most 256"):
        machine_from_dict(doc, source="d")


def test_to_toml_round_trips_every_bundled_machine():
    for name in bundled_machines():
        m = load_machine(name)
        assert machine_from_dict(tomllib.loads(m.to_toml()), source="again").values == m.values


def test_every_schema_key_is_documented_in_docs_machines_md():
    doc = (ROOT / "docs" / "machines.md").read_text()
    missing = [f"{s}.{k}" if s else k for s, keys in SCHEMA.items() for k in keys
               if f"`{k}`" not in doc]
    assert not missing, "document these keys in docs/machines.md: " + ", ".join(missing)


@pytest.mark.slow
def test_bundled_machines_found_after_a_plain_install(tmp_path):
    """``pip install .`` (not editable) ships machines/*.toml as firmware_protocol/machines."""
    import shutil
    src = tmp_path / "src"          # build from a copy: no build/ folder left in the tree
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    for name in ("stringbot", "firmware_protocol", "machines"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q",
                    "--target", str(target), str(src)], check=True, capture_output=True)
    code = ("import firmware_protocol.machine as m; print(m.bundled_dir()); print(','.join(m.bundled_machines()))")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env={"PYTHONPATH": str(target)},
                         check=True, capture_output=True, text=True).stdout.splitlines()
    assert out[0].startswith(str(target))
    assert {"grbl-ring", "grblhal-ring", "marlin-ring", "dynamixel-ring"} <= set(out[1].split(","))
    # every package of the tree is installed (a package missing from pyproject's list is missing here)
    packages = {str(d.relative_to(ROOT)) for top in ("stringbot", "firmware_protocol")
                for d in [ROOT / top, *(ROOT / top).rglob("*")] if (d / "__init__.py").is_file()}
    missing = sorted(p for p in packages if not (target / p / "__init__.py").is_file())
    assert not missing, f"not installed by a plain pip install (add to pyproject's packages): {missing}"
