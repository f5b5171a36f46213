"""The docs a newcomer follows: every `sh` example runs as written, every option has help.

The examples run (``-m slow``) in a fresh copy of the repository's files (what
``git clone`` gives: README, docs, examples, machines), in order: README first,
then docs/ alphabetically, each block as a bash script.  A line ending in ``&``
starts something in the background; a line whose ``#`` comment says ``exit N`` must
exit N; every other line must exit 0.  The environment set-up of the quick
start (venv, pip) is already done by the test run itself and is left out.
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import click
import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
SETUP = re.compile(r"^(python3 -m venv \S+|\. \S+/bin/activate|pip install .*?)$")


def sh_blocks(path):
    """The ```sh blocks of a page, as lists of lines."""
    return [b.strip("\n").splitlines() for b in re.findall(r"```sh\n(.*?)```", path.read_text(), re.S)]


def runnable(line):
    """A line as it runs here: the quick start's set-up left out; None when nothing is left."""
    parts = [p.strip() for p in line.split("&&")]
    if any("pytest" in p for p in parts):
        return None                                # the test suite's own command
    parts = [p for p in parts if not SETUP.match(p)]
    return " && ".join(parts) if parts else None


def script(lines):
    # whatever an example left in the background is stopped as Ctrl-C would, then for good
    out = ["set -u", "cd \"$WORKDIR\"",
           "stop_all() { kill -INT $(jobs -p) 2>/dev/null; sleep 1; kill -KILL $(jobs -p) 2>/dev/null; wait 2>/dev/null; }"]
    for line in lines:
        line = line.rstrip()
        cmd = runnable(line)
        if cmd is None or cmd.startswith("#"):
            continue
        m = re.search(r"#.*\bexit (\d+)", cmd)
        want = int(m.group(1)) if m else 0
        if cmd.endswith("&"):
            out.append(cmd)
            continue
        quoted = cmd.replace("'", "'\"'\"'")
        out.append(f"{cmd}\nrc=$?; if [ $rc -ne {want} ]; then echo 'EXAMPLE FAILED (exit '$rc'): {quoted}' >&2; "
                   "stop_all; exit 1; fi")
    out.append("stop_all; exit 0")
    return "\n".join(out)


def test_every_example_names_files_that_ship():
    """Quick check (not slow): a file an sh example reads from examples/ or machines/ exists."""
    for page in PAGES:
        for block in sh_blocks(page):
            for line in block:
                for name in re.findall(r"(?:examples|machines)/[\w.\-]+", line):
                    assert (ROOT / name).exists(), f"{page.name}: {line} names {name}, which does not ship"


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_every_sh_example_runs_as_written(tmp_path):
    work = tmp_path / "clone"
    work.mkdir()
    for name in ("README.md", "docs", "examples", "machines", "benchmarks"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    env = dict(os.environ, WORKDIR=str(work), STRINGBOT_CACHE=str(tmp_path / "cache"),
               PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    failures = []
    for page in PAGES:
        for k, block in enumerate(sh_blocks(page)):
            p = subprocess.run(["bash", "-c", script(block)], env=env, capture_output=True, text=True,
                               timeout=1200)
            print(f"{page.name} block {k + 1}: exit {p.returncode}", flush=True)
            if p.returncode != 0:
                failures.append(f"{page.name} block {k + 1}: {p.stderr.strip().splitlines()[-3:]}")
    assert not failures, "\n".join(failures)


def walk(cmd, path=()):
    yield path, cmd
    if isinstance(cmd, click.Group):
        for name, sub in cmd.commands.items():
            yield from walk(sub, path + (name,))


def test_every_option_has_help_and_every_command_an_example():
    from stringbot.cli import cli
    for path, cmd in walk(cli):
        name = " ".join(("stringbot",) + path)
        for p in cmd.params:
            if isinstance(p, click.Option):
                assert p.help, f"{name} {p.opts[0]} has no help text"
        assert cmd.epilog and "Examples:" in cmd.epilog, f"{name} has no example"
    assert "docs/design.md" in cli.epilog


def test_machines_show_is_a_machine_file_that_loads_back(tmp_path):
    mine = tmp_path / "mine.toml"
    with open(mine, "w") as f:
        subprocess.run([sys.executable, "-m", "stringbot.cli", "machines", "show", "grblhal-ring"], stdout=f,
                       check=True)
    from firmware_protocol.machine import load_machine
    assert load_machine(str(mine)).values == load_machine("grblhal-ring").values


def test_ci_runs_the_readmes_test_command():
    """.ci/run runs the README's test command exactly (what a newcomer runs is what CI runs)."""
    [block] = [b for b in sh_blocks(ROOT / "README.md") if any("pytest" in line for line in b)]
    [line] = [x for x in block if "pytest" in x]
    command = line[line.index("python3 -m pytest"):]
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert command in ci, f".ci/run does not run the README's test command {command!r}"
    assert "-n auto" in command and "-m 'realtime and not slow'" in command
