"""Every bad input named by issues 11 (files, ports), 12 (colour), 14 (settings check), 24 (files
stringbot did not write, pictures it cannot plan, ports that are not serial devices, a second
simulator) and 27 (winding by hand; the maker's outputs over a user's file; the workshop server), run as a user runs it (a new ``stringbot`` process in a scratch folder): its exit code
and its one line.

Prints a Markdown table (command, exit, the line on standard error) and checks each case: exit 2
(``machines check`` on a mis-set machine: 1; a warning: 0), one line, no traceback, nothing on disk
changed.

    python benchmarks/bad_inputs.py
"""

import hashlib
import os
import shutil
import signal
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
    subprocess.run(STRINGBOT + ["calibrate", "sheet", "--machine", "marlin-ring", "-o", "marlin-sheet.json"], cwd=work,
                   check=True, capture_output=True)
    text = (ROOT / "machines" / "grbl-ring.toml").read_text().replace("out_mm = 12.0", "out_mm = 0.5")
    (work / "short-stroke.toml").write_text(text)
    # issue 24: pictures of the user's own, G-code stringbot wrote, pictures it cannot plan well
    import numpy as np
    from PIL import Image
    rng = np.random.default_rng(24)
    Image.fromarray(rng.integers(0, 255, (300, 400, 3), dtype=np.uint8)).save(work / "rk.jpg")
    Image.fromarray(rng.integers(0, 255, (300, 400, 3), dtype=np.uint8)).save(work / "rk.png")   # unrelated
    Image.fromarray(rng.integers(0, 255, (300, 400, 3), dtype=np.uint8)).save(work / "photo.jpg")
    subprocess.run(STRINGBOT + ["gcode", "ring.json", "--machine", "grbl-ring", "-o", "keep.gcode"], cwd=work,
                   check=True, capture_output=True)
    Image.fromarray(np.zeros((300, 300), np.uint8)).save(work / "black.png")
    night = np.full((300, 300), 10, np.uint8)
    night[120:180, 120:180] = 120                       # a lit window in the night
    Image.fromarray(night).save(work / "night.png")
    Image.fromarray(rng.integers(0, 255, (20, 2000), dtype=np.uint8)).save(work / "strip.png")
    (work / "adir").mkdir()
    (work / "notes.txt").write_text("my notes\n")
    (work / "invoice.pdf").write_bytes(b"%PDF-1.4\n% my invoice\n")
    (work / "cat.gif").write_bytes(b"GIF89a my cat")
    other = work / "other.json"                 # a by-hand position for another plan under plan.json's name
    subprocess.run(STRINGBOT + ["plan", "camera.png", "-o", str(other), "--pins", "60", "--lines", "30", "--size", "101"],
                   cwd=work, check=True, capture_output=True)
    subprocess.run(STRINGBOT + ["by-hand", "other.json"], input=b"next\nquit\n", cwd=work, check=True,
                   capture_output=True)
    shutil.copy(work / "other.json.by-hand", work / "square.json.by-hand")
    sim = subprocess.Popen(STRINGBOT + ["simulate", "--pty", "live.pty"], cwd=work, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    sim.stdout.readline()                               # "simulating grbl-ring on live.pty ..."
    return s, sim


CASES = [
    # issue 11: outputs
    "plan camera.png -o dev.json --pins 60 --lines 50 --size 101",
    "plan camera.png -o out.json --preview dev.png --pins 60 --lines 50 --size 101",
    "plan camera.png -o fifo.json --pins 60 --lines 50 --size 101",
    "plan camera.png -o afile/out.json --pins 60 --lines 50 --size 101",
    "plan camera.png -o ring.json --machine grbl-ring --lines 50 --size 301",
    # before the port cases: a wind that cannot open its port has already begun a new journal for ring.json
    "calibrate sheet --machine grbl-ring -o ring.json",
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
    # issue 23: the insert/delete passes
    "plan camera.png -o pp.json --polish-passes 21",
    "plan camera.png -o pp.json --polish-passes 2 --lines 50",
    "plan camera.png -o pp.json --polish-passes 2 --colors auto:3",
    # issue 14: settings check
    "machines check no-such-machine",
    "machines check grbl-ring --port /dev/ttyNOPE",
    "machines check grbl-ring --port sim://?machine=grbl-ring&set=$100=40",
    # issue 24: files stringbot did not write
    "plan rk.jpg -o rk.json --pins 60 --lines 50 --size 101",
    "render plan.json -o camera.png",
    "render plan.json -o photo.jpg",
    "plan camera.png -o out.json --preview photo.jpg --pins 60 --lines 50 --size 101",
    "plan camera.png -o ring.json.journal --pins 60 --lines 50 --size 101",
    "plan camera.png -o keep.gcode --pins 60 --lines 50 --size 101",
    "plan camera.png -o photo.jpg --preview out.png --pins 60 --lines 50 --size 101",
    "wind ring.json --machine grbl-ring --yes --record rk.png",
    "simulate --pty new.pty --record photo.jpg",
    # issue 24: pictures the planner cannot paint in black on white
    "plan black.png -o b.json",
    "plan night.png -o n.json",
    "plan strip.png -o s.json --pins 60 --lines 50 --size 101",
    # issue 24: ports that are not serial devices, a path a simulator holds
    "wind ring.json --machine grbl-ring --yes --port afile",
    "wind ring.json --machine grbl-ring --yes --port adir",
    "wind ring.json --machine grbl-ring --yes --port /dev/null",
    "wind ring.json --machine grbl-ring --yes --port fifo.txt",
    "machines check grbl-ring --port afile",
    "simulate --pty live.pty",
    # issue 23: calibration
    "calibrate sheet --machine grbl-ring -o fifo.json",
    "calibrate fit camera.png --machine grbl-ring -o mine.toml",
    "calibrate fit afile --machine grbl-ring -o mine.toml",
    "calibrate fit camera.png --machine grbl-ring --sheet plan.json -o mine.toml",
    "calibrate fit camera.png --machine grbl-ring --sheet marlin-sheet.json -o mine.toml",
    "calibrate fit camera.png --machine grbl-ring -o mine.json",
    # issue 25: faces
    "plan camera.png -o f.json --face --pins 60 --lines 50 --size 101",
    "plan camera.png -o c.json --colors black,red --face",
    # issue 27: winding by hand; the maker's outputs over a user's file
    "by-hand square.json",
    "by-hand plan.json --from-step 0",
    "by-hand plan.json --from-step 999",
    "by-hand plan.json --voice en",
    "by-hand plan.json --position notes.txt",
    "by-hand plan.json --position plan.json",
    "pins plan.json -o notes.txt",
    "template --machine grbl-ring -o invoice.pdf",
    "animate plan.json -o cat.gif",
    "calibrate sheet --machine grbl-ring -o s2.json --template invoice.pdf",
    # issue 27: the workshop page's server
    "serve --host nosuch.invalid",
    "serve --plans afile",
    "serve --port 70000",
]
#: Cases that go on with a warning (exit 0, one ``stringbot: warning:`` line).
WARNINGS = ("plan strip.png",)


def digest(work, *, journals=True):
    """sha256 of every regular file (journals too unless ``journals`` is false: a refused wind notes it)."""
    out = {}
    for p in sorted(work.rglob("*")):
        if p.is_file() and not p.is_symlink() and (journals or p.suffix != ".journal"):
            out[p.name] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def run(work, argv):
    return subprocess.run(STRINGBOT + argv, cwd=work, capture_output=True, text=True, timeout=120,
                          stdin=subprocess.DEVNULL)


def main():
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        keep, sim = setup(work)
        print("| command | exit | what it says |")
        print("|---|---|---|")
        bad = 0
        try:
            for case in CASES:
                argv = case.split(" ")
                journals = argv[0] != "wind"
                before = digest(work, journals=journals)
                p = run(work, argv)
                lines = [x for x in p.stderr.splitlines() if x.strip()]
                warning = case.startswith(WARNINGS)
                want = 1 if case.startswith("machines check grbl-ring --port sim://") else 0 if warning else 2
                changed = [k for k, v in before.items() if digest(work, journals=journals).get(k) != v]
                ok = p.returncode == want and len(lines) == 1 and "Traceback" not in p.stderr and not changed \
                    and lines[0].startswith("stringbot: warning:" if warning else "stringbot: error:")
                bad += not ok
                line = lines[-1] if lines else "(nothing)"
                flag = "" if ok else " **(!)**"
                print(f"| `stringbot {case}` | {p.returncode}{flag} | {line.replace('|', '/')} |")
            alive = sim.poll() is None          # the simulator the last case tried to take over
            bad += not alive
            print(f"\n{len(CASES)} cases, {bad} not as expected (exit 2 -- 1 for a mis-set machine, 0 with "
                  "one warning line for a plan that goes on --, one line, no traceback, nothing on disk changed; "
                  f"the simulator on live.pty {'still serving' if alive else 'GONE'} at the end)")
        finally:
            keep.close()
            sim.send_signal(signal.SIGINT)
            sim.communicate(timeout=30)
        return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
