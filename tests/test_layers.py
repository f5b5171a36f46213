"""The dependency rules of docs/design.md, checked mechanically by import-linter."""

import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_hold():
    exe = shutil.which("lint-imports")
    assert exe, "import-linter is part of the test extra: pip install -e '.[test]'"
    result = subprocess.run([exe, "--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


def test_library_code_never_prints():
    offenders = []
    for path in (ROOT / "stringbot").rglob("*.py"):
        if path.relative_to(ROOT).parts[:2] == ("stringbot", "cli"):
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if line.lstrip().startswith("print("):
                offenders.append(f"{path.relative_to(ROOT)}:{n}")
    assert not offenders, "library code logs or returns; only the cli package prints: " + ", ".join(offenders)


def test_modules_stay_small():
    big = [f"{p.relative_to(ROOT)} ({n})" for folder in ("stringbot", "firmware_protocol", "tests", "benchmarks")
           for p in (ROOT / folder).rglob("*.py") if (n := len(p.read_text().splitlines())) >= 500]
    assert not big, "modules of 500 lines or more, split by what they do: " + ", ".join(big)
