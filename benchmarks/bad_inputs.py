"""Every bad input named by issues 11 (files, ports), 12 (colour) and 14 (settings check), run as a
user runs it (a new ``stringbot`` process in a scratch folder): its exit code and its one line.

Prints a Markdown table (command, exit, the line on standard error) and checks each case: exit 2
(``machines check`` on a mis-set machine: 1), one line, no traceback, nothing on disk changed.

    python benchmarks/bad_inputs.py
"""

import hashlib
import os
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STRINGBOT = [sys.executable, "-c", "import sys; from stringbot.cli import main; main(sys.argv[1:])"]


def setup(work):
    shutil.copy(ROOT / "examples" / "camera.png", work / "camera.png")
    subprocess.run(STRINGBOT + ["plan", "camera.png", "-o", "plan.json", "--pins", "60", "--lines", "80",
                                "--size", "101"], cwd=work, check=True, capture_output=True)
    subprocess.run(STRINGBOT + ["plan", "camera.png", "-o", "square.json", "--pins", "60", "--lines", "80",
                                "--size", "101", "--frame", "square"], cwd=work, check=True, capture_output=True)
    subprocess.run(STRINGBOT + ["plan", "camera.png", "-o", "ring.json", "--machine", "grbl-ring", "--lines",
                                "40", "--size", "301"], cwd=work, check=True, capture_output=True)
    subprocess.run(STRINGBOT + ["wind", "ring.json", "--machine", "grbl-ring", "--yes", "--journal",
                                "ring.json.journal"], cwd=work, check=True,
                   capture_output=True)                      # ring.json now has a journal with steps done
    os.mkfifo(work / "fifo.json")
    os.mkfifo(work / "fifo.txt")
    os.symlink("/dev/null", work / "dev.json")
    os.symlink("/dev/null", work / "dev.png")
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(work / "sock.journal"))
    (work / "notes.gcode").write_text("my own job\n")
    (work / "afile").write_text("x\n")
    text = (ROOT / "machines" / "grbl-ring.toml").read_text().replace("out_mm = 12.0", "out_mm = 0.5")
    (work / "short-stroke.toml").write_text(text)
    return s


CASES = [
    # issue 11: outputs
    "plan camera.png -o dev.json --pins 60 --lines 50 --size 101",
    "plan camera.png -o out.json --preview dev.png --pins 60 --lines 50 --size 101",
    "plan camera.png -o fifo.json --pins 60 --lines 50 --size 101",
    "plan camera.png -o afile/out.json --pins 60 --lines 50 --size 101",
    "plan camera.png -o ring.json --machine grbl-ring --lines 50 --size 301",
    "plan camera.png -o - --pins 60 --lines 50",
    "render plan.json -o -",
    "wind ring.json --machine grbl-ring --yes --record fifo.json",
    "wind ring.json --machine grbl-ring --yes --journal sock.journal",
    "gcode plan.json --machine grbl-ring -o notes.gcode",
    "gcode plan.json --machine grbl-ring -o dev.json",
    "pins plan.json -o fifo.json",
    "pins plan.json -o fifo.txt",
    "animate plan.json -o -",
    "plan camera.png -o sq.json --frame square --machine grbl-ring",
    "wind square.json --machine grbl-ring --yes",
    "machines show short-stroke.toml",
    # issue 11: ports
    "wind ring.json --machine grbl-ring --port rfc2217://127.0.0.1:1",
    "wind ring.json --machine grbl-ring --port socket://127.0.0.1:1",
    "wind ring.json --machine grbl-ring --port socket://no-such-host.invalid:23",
    "wind ring.json --machine grbl-ring --port /dev/ttyNOPE",
    # issue 12: colour
    "plan camera.png -o c.json --colors crimsonx",
    "plan camera.png -o c.json --colors #12345",
    "plan camera.png -o c.json --colors auto:0",
    "plan camera.png -o c.json --colors auto:99",
    "plan camera.png -o c.json --colors white",
    "plan camera.png -o c.json --colors black --background black",
    "plan camera.png -o c.json --colors black,red --background blak",
    # issue 14: settings check
    "machines check no-such-machine",
    "machines check grbl-ring --port /dev/ttyNOPE",
    "machines check grbl-ring --port sim://?machine=grbl-ring&set=$100=40",
]


def digest(work):
    out = {}
    for p in sorted(work.rglob("*")):
        if p.is_file() and not p.is_symlink() and p.suffix != ".journal":
            out[p.name] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def run(work, argv):
    return subprocess.run(STRINGBOT + argv, cwd=work, capture_output=True, text=True, timeout=120,
                          stdin=subprocess.DEVNULL)


def main():
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        keep = setup(work)
        print("| command | exit | what it says |")
        print("|---|---|---|")
        bad = 0
        for case in CASES:
            argv = case.split(" ")
            before = digest(work)
            p = run(work, argv)
            lines = [x for x in p.stderr.splitlines() if x.strip()]
            want = 1 if case.startswith("machines check grbl-ring --port sim://") else 2
            changed = [k for k, v in before.items() if digest(work).get(k) != v]
            ok = p.returncode == want and len(lines) == 1 and "Traceback" not in p.stderr and not changed
            bad += not ok
            line = lines[-1] if lines else "(nothing)"
            flag = "" if ok else " **(!)**"
            print(f"| `stringbot {case}` | {p.returncode}{flag} | {line.replace('|', '/')} |")
        keep.close()
        print(f"\n{len(CASES)} cases, {bad} not as expected (exit 2 -- 1 for a mis-set machine --, "
              "one line, no traceback, nothing on disk changed)")
        return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
