"""The typed contracts where the layers meet: mypy finds no error in them (pyproject.toml's
[tool.mypy] lists the modules), and the links the wind loop drives have every member of the
step-level link protocol (stringbot/links/contract.py)."""

import subprocess
import sys
from pathlib import Path

import pytest

from firmware_protocol.machine import load_machine
from stringbot.links import open_link, sim_url
from stringbot.links.contract import StepLink

from bundled import MACHINES

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.timeout(300)
def test_mypy_finds_no_error_in_the_contracts():
    p = subprocess.run([sys.executable, "-m", "mypy", "--cache-dir", str(ROOT / ".mypy_cache")], cwd=ROOT,
                       capture_output=True, text=True, timeout=280)
    assert p.returncode == 0, p.stdout + p.stderr
    assert p.stdout.startswith("Success: no issues found"), p.stdout


@pytest.mark.parametrize("machine", MACHINES)
def test_every_machines_link_is_a_step_link(machine):
    """What open_link gives for every bundled machine has every member the wind loop uses."""
    members = [n for n in vars(StepLink) if not n.startswith("_")] + list(StepLink.__annotations__)
    link = open_link(sim_url(machine), load_machine(machine))
    try:
        assert [n for n in members if not hasattr(link, n)] == []
        assert isinstance(link, StepLink)
    finally:
        link.close()
