"""The user's side of the cross-process fault matrix (:mod:`bench_fault_matrix`): the
simulator and the host as processes of their own, and an operator who knows only what the
simulator's record file shows (where the eyelet is, which pin faces the head).
"""

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

STRINGBOT = [sys.executable, "-m", "stringbot.cli"]


def _sigint_default():
    """Children take Ctrl-C as a user's would, even when this script runs in the background
    (where a shell starts it with SIGINT ignored, and every child would inherit that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


# ---- the two processes ------------------------------------------------------------------------

class Simulator:
    def __init__(self, machine, pty, record, faults=""):
        self.pty, self.record = Path(pty), Path(record)
        cmd = STRINGBOT + ["simulate", "--machine", machine, "--pty", str(pty), "--record", str(record)]
        if faults:
            cmd += ["--faults", faults]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 preexec_fn=_sigint_default)
        deadline = time.monotonic() + 30
        while not self.pty.exists():
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("the simulator did not start: " + self.proc.stderr.read()[-300:])
            time.sleep(0.02)

    def wait_port(self, timeout=10.0):
        """As a user waits for the port to come back (after a pulled cable or a power cut)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and self.proc.poll() is None:
            if os.path.exists(os.path.realpath(self.pty)):
                return True
            time.sleep(0.05)
        return False

    def look(self):
        try:
            return json.loads(self.record.read_text())
        except (OSError, ValueError):
            return {}

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.look()


def _done(journal):
    try:
        return sum(1 for line in Path(journal).read_bytes().splitlines() if b'"kind":"done"' in line)
    except FileNotFoundError:
        return 0


def run_host(args, timeout, kill_after=None, journal=None, rng=None, sig=signal.SIGKILL):
    """One ``stringbot wind`` run; ``kill_after``: send it ``sig`` once the journal holds that many
    steps.  Returns (returncode or "hung" or "killed", stdout, stderr, whether the signal was sent)."""
    proc = subprocess.Popen(STRINGBOT + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, text=True, preexec_fn=_sigint_default)
    if kill_after is not None:
        deadline = time.monotonic() + timeout
        kill_after = max(kill_after, _done(journal) + 1)       # once this run has wound a step
        while proc.poll() is None and _done(journal) < kill_after and time.monotonic() < deadline:
            time.sleep(0.002)
        time.sleep(rng.uniform(0.0, 0.03))
        sent = proc.poll() is None
        if sent and sig == signal.SIGKILL:
            proc.send_signal(signal.SIGKILL)
            out, err = proc.communicate()
            return "killed", out, err, True
        if sent:
            proc.send_signal(sig)
    else:
        sent = False
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        return "hung", out, err, sent
    return proc.returncode, out, err, sent


CLEAR_MM = 1.0       # a head within 1 mm of its IN or OUT position is clearly there; else it is among the pins


def clear_side(rec, machine):
    """``"in"`` or ``"out"`` where the record shows the head clearly there, else None."""
    from firmware_protocol.machine import load_machine
    m = load_machine(machine)
    head = rec.get("head_mm")
    for side in ("in", "out"):
        if head is not None and abs(head - m[f"head.{side}_mm"]) <= CLEAR_MM:
            return side
    return None


def _operator(machine, record):
    """tests/scripted_operator.py's person, who says IN or OUT only where the head clearly is, and
    asks for the guide when it stands among the pins."""
    from firmware_protocol.machine import load_machine
    from scripted_operator import ScriptedOperator, record_looker

    class Person(ScriptedOperator):
        def _clear(self):
            return clear_side({"head_mm": self._seen()[1]}, machine)

        def choose(self, question, choices):
            if "in" in choices and "out" in choices and self._clear() is None and "guide" in choices:
                self.asked.append(question)
                return "guide"
            return super().choose(question, choices)

        def confirm(self, question):
            declared = re.search(r"with the head (IN|OUT)\?", question)
            if declared and self._clear() != declared.group(1).lower():
                self.asked.append(question)
                return False
            return super().confirm(question)
    return Person(load_machine(machine), record_looker(str(record)))


def run_guided(args, machine, record, timeout):
    """``wind --resume`` without ``--yes``, its questions answered from the record file as a person
    at the terminal answers them."""
    op = _operator(machine, record)
    proc = subprocess.Popen(STRINGBOT + args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, preexec_fn=_sigint_default)
    chunks, outs, lock = [], [], threading.Lock()

    def pump(stream, into):
        while True:
            b = os.read(stream.fileno(), 4096)
            if not b:
                return
            with lock:
                into.append(b)
    readers = [threading.Thread(target=pump, args=(proc.stderr, chunks), daemon=True),
               threading.Thread(target=pump, args=(proc.stdout, outs), daemon=True)]
    for t in readers:
        t.start()
    deadline, seen, said, last_len, quiet_since = time.monotonic() + timeout, 0, 0, -1, time.monotonic()
    while proc.poll() is None:
        if time.monotonic() > deadline:
            proc.kill()
            proc.wait()
            return "hung", b"".join(outs).decode(), b"".join(chunks).decode()
        time.sleep(0.02)
        with lock:
            text = b"".join(chunks).decode("utf-8", "replace")
        if len(text) != last_len:
            last_len, quiet_since = len(text), time.monotonic()
            continue
        tail = text[seen:]
        if time.monotonic() - quiet_since < 0.15 or not re.search(r"(: |> )$", tail):
            continue
        op.say(" ".join(text[said:].split()))
        said = len(text)
        question = " ".join(tail.split("\n")[-1].split())
        if question.endswith("jog>"):
            answer = op.jog("jog> ")
        elif re.search(r"\[[yY]/[nN]\]:$", question):
            answer = "y" if op.confirm(" ".join(tail.split())) else "n"
        else:
            choices = re.findall(r"\(([^()]*)\):$", question)
            choices = [c.strip() for c in choices[-1].split(",")] if choices else []
            answer = op.choose(" ".join(tail.split()), choices) if choices else ""
        proc.stdin.write((answer + "\n").encode())
        proc.stdin.flush()
        seen = len(text)
    for t in readers:
        t.join(timeout=5)
    return proc.returncode, b"".join(outs).decode(), b"".join(chunks).decode()


# ---- a person at a terminal program, before winding ---------------------------------------------

DISPLACEMENTS = ("out-pin", "out-gap", "ring")


def displacement(machine, kind):
    """The lines a person types into a terminal program (before ``wind``) that leave the machine off
    its start: ``out-pin`` -- out at the gap between pins 2 and 3, then the ring turned until the pin
    is in front of the head (less than half a pitch: that gap stays the nearest, the one to come back
    by); ``out-gap`` -- the head out at that gap; ``ring`` -- the ring turned, the head IN."""
    from firmware_protocol.machine import load_machine
    m = load_machine(machine)
    ring, head = m["controller.ring_axis"], m["controller.head_axis"]
    gap = m["ring.pin0_angle_deg"] + 2.5 * m.pitch_deg
    off = (m.gap_tolerance_deg + m.pitch_deg / 2) / 2
    out = m["head.out_mm"] - m["head.in_mm"]     # the firmware counts from where it started: the head IN
    marlin = m["controller.dialect"] == "marlin"
    homes = m["controller.homing"] or m.values.get("controller.head_homing")
    lines = ["M211 S0"] if marlin else (["$X"] if homes else [])
    lines.append("G90")
    if kind == "ring":
        lines.append(f"G1 {ring}37.3 F3000")
    else:
        lines += [f"G1 {ring}{gap:.4f} F3000", f"G1 {head}{out:.4f} F3000"]
        if kind == "out-pin":
            lines.append(f"G1 {ring}{gap + off:.4f} F3000")
    lines.append("M400" if marlin else "G4 P0")
    return lines


def type_lines(pty, lines, *, then=None, timeout=30.0):
    """Send ``lines`` to the simulator one by one, each answered before the next, then ``then``
    (a last line, e.g. one that a fault is set to meet, not waited for); close the port."""
    import serial
    port = serial.Serial(str(pty), 115200, timeout=0.1)
    try:
        port.read(4096)                                  # the start banner, if it waits
        for line in lines:
            port.write(line.encode() + b"\n")
            heard, deadline = b"", time.monotonic() + timeout
            while b"ok" not in heard and b"error" not in heard.lower() and time.monotonic() < deadline:
                heard += port.read(256)
            if b"ok" not in heard:
                raise RuntimeError(f"the simulator did not take {line!r}: {heard[-200:]!r}")
        if then:
            port.write(then.encode() + b"\n")
            try:
                port.read(256)
            except (serial.SerialException, OSError):
                pass
    finally:
        try:
            port.close()
        except (serial.SerialException, OSError):
            pass


def wait_event(record, event, timeout=30.0):
    """Wait until the simulator's record shows ``event`` (e.g. ``"power on"``): a person waits for the
    machine to come back before they type or wind again."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if any(e.get("event") == event for e in json.loads(Path(record).read_text()).get("events", [])):
                return True
        except (OSError, ValueError):
            pass
        time.sleep(0.05)
    return False


def homes(machine):
    from firmware_protocol.machine import load_machine
    m = load_machine(machine)
    return bool(m["controller.homing"] or m.values.get("controller.head_homing"))
