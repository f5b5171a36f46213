"""Faults the simulated G-code machine can suffer, and when.

Forms (a comma list of them)::

    kind@N            as line N arrives (also kind@line=N)
    kind@N+F          when the motion line N commands is the fraction F (0 < F < 1) of its
                      length done (also kind@line=N+F); a line that moves nothing: as it starts
    kind@t=T          at T seconds of the firmware's virtual clock (0 = when it was created)
    kind@N..M         every line from N to M (kind@N.. and kind@N+: from N on), for the
                      line kinds only

N counts the lines the firmware has received since it was created (1 = the
first line; GRBL counts every line end, empty lines and ``$`` commands too,
Marlin every non-empty line; the count survives resets and power cycles, so
``reset@5,reset@9`` fires twice).  Dynamixel machines have their own faults
(see ``docs/dynamixel.md``).

The kinds are :data:`FAULT_KINDS` (each a :class:`FaultKind`): machine kinds
hit the firmware or the port, moving or not (any form but a range); line kinds
hit line N as it arrives (or a range of lines).  docs/simulator.md says what
each does, byte by byte, on GRBL and on Marlin.
"""

import math
import re
from dataclasses import dataclass

__all__ = ["FaultKind", "FAULT_KINDS", "KINDS", "MACHINE_KINDS", "LINE_KINDS", "Fault", "FaultPlan", "parse_faults",
           "FAULTS_FORM", "FAULTS_HELP", "POWER_OFF_SECONDS", "DISCONNECT_SECONDS", "BOOT_SECONDS"]


@dataclass(frozen=True)
class FaultKind:
    """One kind of fault of the simulated G-code machine: the one place that names it.

    ``hits`` is ``"machine"`` (any *when* but a range: the firmware or the port, moving or not)
    or ``"line"`` (as line N arrives, or a range of lines).  ``summary`` is what happens, in
    one line (``simulate --help``; docs/simulator.md says it at length).  ``event`` names it in
    the world's record (default: its name).  ``resumable``: a resume alone (the operator
    answering questions, no hands on the machine) can finish the job after it; the resume
    tests and the fault matrix run every resumable kind.  A machine kind is fired by the
    emulator's ``_fault_<name>`` (``-`` as ``_``), a line kind applied by its protocol
    (:meth:`GcodeFirmware._line_faults` hands the kinds of each line on).
    """

    name: str
    hits: str
    summary: str
    event: str = ""
    resumable: bool = True

    def __post_init__(self):
        if self.hits not in ("machine", "line"):
            raise ValueError(f"fault kind {self.name!r}: hits {self.hits!r}; expected 'machine' or 'line'")


#: Every fault kind, by name.  Machine kinds in the order they take precedence when several hit
#: one line (the first wins: the line is gone), then the line kinds.
FAULT_KINDS = {k.name: k for k in (
    FaultKind("power", "machine", "power lost: the port drops, the firmware restarts with its position lost",
              event="power off"),
    FaultKind("disconnect", "machine", "the cable pulled: the port drops for 0.5 s, the firmware runs on",
              event="port down"),
    FaultKind("reboot", "machine", "the board restarts: silent for a second, then its banner, its position lost"),
    FaultKind("reset", "machine", "a soft reset: motion stops dead, the queue is lost, the position is kept"),
    FaultKind("freeze", "machine", "the main loop hangs: deaf and mute until power or a reboot",
              resumable=False),
    FaultKind("garble", "line", "the line corrupted in transit (its middle byte DEL)"),
    FaultKind("drop-ok", "line", "the line executed, its ok lost"),
    FaultKind("error", "line", "the line rejected, not executed"),
    FaultKind("ignore", "line", "the line answered ok but not executed"),
)}
MACHINE_KINDS = tuple(k.name for k in FAULT_KINDS.values() if k.hits == "machine")
LINE_KINDS = tuple(k.name for k in FAULT_KINDS.values() if k.hits == "line")
KINDS = tuple(FAULT_KINDS)
FAULTS_FORM = ("a comma list of kind@N, kind@N+F (0<F<1), kind@t=SECONDS or, for "
               + "/".join(LINE_KINDS) + ", kind@N..M / kind@N.. ; kind one of " + ", ".join(KINDS)
               + " and N >= 1 (e.g. reset@12,reset@t=30.5,power@40+0.5,ignore@60..)")
#: The ``--faults`` help of ``stringbot simulate`` and ``wind``.
FAULTS_HELP = ("Faults to inject, a comma list: kind@N (as line N arrives), kind@N+F (F of line N's move done), "
               "kind@t=SECONDS, kind@N..M (" + ", ".join(LINE_KINDS) + "); kinds " + ", ".join(KINDS)
               + " (docs/simulator.md; Dynamixel machines: docs/dynamixel.md).")
#: Virtual seconds the port stays down after ``power`` (the firmware restarts when it comes back).
POWER_OFF_SECONDS = 1.0
#: Virtual seconds the port stays down after ``disconnect``.
DISCONNECT_SECONDS = 0.5
#: Virtual seconds a rebooting board answers nothing (an Arduino's bootloader waits about 1 s).
BOOT_SECONDS = 1.0

_NUM = r"(\d+(?:\.\d*)?|\.\d+)"
_ITEM = re.compile(rf"^([a-z-]+)@(?:(?:line=)?(\d+)(?:\+{_NUM}|(\+|\.\.(\d+)?))?|t={_NUM})$")


@dataclass(frozen=True)
class Fault:
    """One fault: ``kind`` at ``line`` (``line``..``last`` for a range, ``last`` math.inf when
    open), at the ``fraction`` of line ``line``'s motion, or at virtual ``time``."""

    kind: str
    line: int | None = None
    fraction: float | None = None
    time: float | None = None
    last: float | None = None

    @property
    def at_arrival(self):
        """Fires as a line arrives (not at a time or inside a motion)."""
        return self.time is None and self.fraction is None

    def covers(self, n):
        return self.at_arrival and self.line <= n <= (self.line if self.last is None else self.last)

    def when(self):
        """The part after the ``@``."""
        if self.time is not None:
            return f"t={self.time:g}"
        if self.fraction is not None:
            return f"line={self.line}+{self.fraction:g}"
        if self.last is None:
            return str(self.line)
        return f"{self.line}.." + ("" if self.last == math.inf else str(int(self.last)))

    def __str__(self):
        return f"{self.kind}@{self.when()}"


def parse_faults(text):
    """``"reset@3,garble@7"`` -> ``[Fault("reset", 3), Fault("garble", 7)]``.

    Raises
    ------
    ValueError
        Naming the bad item and the expected form.
    """
    faults: list[Fault] = []
    if text is None or not str(text).strip():
        return faults
    for item in str(text).split(","):
        item = item.strip()
        m = _ITEM.match(item)
        if not m or m.group(1) not in KINDS:
            raise ValueError(f"bad fault {item!r}; expected {FAULTS_FORM}")
        kind, line, frac, rng, last, t = m.groups()
        if t is not None:
            fault = Fault(kind, time=float(t))
        elif frac is not None:
            fraction = float(frac)
            fault = Fault(kind, int(line), fraction=fraction)
            if not 0.0 < fraction < 1.0:
                raise ValueError(f"bad fault {item!r}: the fraction of the move must be > 0 and < 1; "
                                 f"expected {FAULTS_FORM}")
        elif rng is not None:
            end = math.inf if last is None else int(last)
            fault = Fault(kind, int(line), last=end)
            if end < int(line):
                raise ValueError(f"bad fault {item!r}: the range ends before it starts; expected {FAULTS_FORM}")
        else:
            fault = Fault(kind, int(line))
        if fault.line is not None and fault.line < 1:
            raise ValueError(f"bad fault {item!r}; expected {FAULTS_FORM}")
        if kind in LINE_KINDS and not fault.at_arrival:
            raise ValueError(f"bad fault {item!r}: {kind} hits a line as it arrives, so it takes "
                             f"{kind}@N or {kind}@N..M, not a time or a fraction of a move")
        if kind in MACHINE_KINDS and fault.last is not None:
            raise ValueError(f"bad fault {item!r}: {kind} fires once, so it takes no range; "
                             f"expected {kind}@N, {kind}@N+F or {kind}@t=SECONDS")
        faults.append(fault)
    return faults


class FaultPlan:
    """The faults still to fire; the firmware asks it about every line it receives, about the
    motion of the line it starts, and about the time."""

    def __init__(self, faults=()):
        if isinstance(faults, str):
            faults = parse_faults(faults)
        self.pending = sorted(faults, key=lambda f: (f.line or 0, f.time or 0.0))
        self.fired = []
        self.lines = 0

    def next_line(self):
        """Count one received line; returns the set of fault kinds that fire on it."""
        self.lines += 1
        n = self.lines
        hits = [f for f in self.pending if f.covers(n)]
        for f in hits:
            if f.line == n:
                self.fired.append(f)
        self.pending = [f for f in self.pending
                        if not (f in hits and (f.last is None or f.last <= n))]
        return {f.kind for f in hits}

    def fractions(self, line):
        """Take the faults that fire inside the motion of ``line`` (``kind@line+F``)."""
        taken = [f for f in self.pending if f.fraction is not None and f.line == line]
        if taken:
            self.pending = [f for f in self.pending if f not in taken]
        return taken

    def mark_fired(self, fault):
        """A fault taken by :meth:`fractions` has fired."""
        self.fired.append(fault)

    def next_time(self):
        """Virtual time of the next timed fault, or None."""
        times = [f.time for f in self.pending if f.time is not None]
        return min(times) if times else None

    def due(self, now, eps=1e-9):
        """Take the timed faults due at ``now``, in time order."""
        due = sorted((f for f in self.pending if f.time is not None and f.time <= now + eps),
                     key=lambda f: f.time)
        if due:
            self.pending = [f for f in self.pending if f not in due]
            self.fired.extend(due)
        return due

    def __str__(self):
        return ",".join(str(f) for f in self.pending)
