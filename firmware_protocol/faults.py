"""Faults the simulated machine can suffer, and when: ``kind@N`` with N the line count.

N counts the lines the firmware has received since it was created (1 = the
first line; GRBL counts every line end, empty lines and ``$`` commands too,
Marlin every non-empty line; the count survives resets and power cycles, so
``reset@5,reset@9`` fires twice).  Dynamixel machines have their own faults
(see ``docs/dynamixel.md``).
Each fault fires once, when line N has arrived complete:

``garble``
    bytes of line N are corrupted in transit (its middle byte becomes 0x7F,
    DEL): the firmware parses what arrived -- GRBL rejects it with an
    ``error:``, Marlin with a checksum mismatch and ``Resend:`` when the line
    carries one.
``error``
    line N is rejected, not executed: GRBL answers ``error:20``, Marlin
    ``Error:...`` with ``Resend:``.
``drop-ok``
    line N is executed but its response (``ok``) is lost on the way back.
``reset``
    the firmware resets (a brown-out, a watchdog) as line N arrives: line N and
    everything queued are lost, motion stops where it is, GRBL prints
    ``ALARM:3`` if it was moving, then the banner; the firmware's position is
    wiped (0 wherever the axes physically are).
``power``
    power is lost as line N arrives: motion stops where it is, the port drops
    (reads and writes fail), and after :data:`POWER_OFF_SECONDS` the firmware
    starts again with its position lost; the banner waits for the host.
``disconnect``
    the USB cable is pulled as line N arrives: line N is lost and the port
    drops for :data:`DISCONNECT_SECONDS`; the firmware keeps running (queued
    motion completes) and is still there when the port comes back.
"""

import re
from dataclasses import dataclass

__all__ = ["KINDS", "Fault", "FaultPlan", "parse_faults", "FAULTS_FORM",
           "POWER_OFF_SECONDS", "DISCONNECT_SECONDS"]

KINDS = ("disconnect", "reset", "power", "garble", "drop-ok", "error")
FAULTS_FORM = "a comma list of kind@N, kind one of " + ", ".join(KINDS) + " and N >= 1 (e.g. reset@12,garble@30)"
#: Virtual seconds the port stays down after ``power`` (the firmware restarts when it comes back).
POWER_OFF_SECONDS = 1.0
#: Virtual seconds the port stays down after ``disconnect``.
DISCONNECT_SECONDS = 0.5

_ITEM = re.compile(r"^([a-z-]+)@(\d+)$")


@dataclass(frozen=True)
class Fault:
    kind: str
    line: int

    def __str__(self):
        return f"{self.kind}@{self.line}"


def parse_faults(text):
    """``"reset@3,garble@7"`` -> ``[Fault("reset", 3), Fault("garble", 7)]``.

    Raises
    ------
    ValueError
        Naming the bad item and the expected form.
    """
    faults = []
    if text is None or not str(text).strip():
        return faults
    for item in str(text).split(","):
        item = item.strip()
        m = _ITEM.match(item)
        if not m or m.group(1) not in KINDS or int(m.group(2)) < 1:
            raise ValueError(f"bad fault {item!r}; expected {FAULTS_FORM}")
        faults.append(Fault(m.group(1), int(m.group(2))))
    return faults


class FaultPlan:
    """The faults still to fire; the firmware asks it about every line it receives."""

    def __init__(self, faults=()):
        if isinstance(faults, str):
            faults = parse_faults(faults)
        self.pending = sorted(faults, key=lambda f: f.line)
        self.fired = []
        self.lines = 0

    def next_line(self):
        """Count one received line; returns the set of fault kinds that fire on it."""
        self.lines += 1
        kinds = {f.kind for f in self.pending if f.line == self.lines}
        if kinds:
            self.fired.extend(f for f in self.pending if f.line == self.lines)
            self.pending = [f for f in self.pending if f.line != self.lines]
        return kinds

    def __str__(self):
        return ",".join(str(f) for f in self.pending)
