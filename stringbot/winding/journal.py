"""The winding journal: append-only JSON lines, each fsync'd, a torn last line tolerated.

One record per line.  The first is the header::

    {"kind": "start", "format": "stringbot-journal", "version": 1, "plan": "...",
     "plan_sha256": "...", "machine": "grbl-ring", "steps": 2001, "t": 1763790000.0}

then, as the winding goes::

    {"kind": "move", "step": 17, "move": 1, "t": ...}     move 1 of step 17 executed
    {"kind": "done", "step": 17, "pin": 42, "t": ...}     step 17 EXECUTED (its sync answered)
    {"kind": "stop", "reason": "interrupted" | "failed" | "spool change", "error": "...", "step": 18,
     "pin": 7, "head": "in" | "out" | "unknown", "position": [ring_deg, head_mm] | null, "t": ...}
                                          ("spool change": a colour plan stopped for a person to tie
                                          on the thread of its "layer" (from 0), ``--yes`` on a port)
    {"kind": "recover", "banner": true, "alarm": "ALARM:3", "alarm_cleared": true,
     "mpos": [x, y, z], "position_wiped": false, "position": [ring_deg, head_mm] | null, "t": ...}
                                          what a resume attempt learned on reconnecting (written
                                          before it asks or refuses anything)
    {"kind": "declared", "position": [ring_deg, head_mm], "how": "...", "t": ...}
                                          a resume told the firmware where it stands (G10 L20 / G92)
    {"kind": "refused", "error": "...", "t": ...}           a resume attempt that refused
    {"kind": "resume", "from_step": 18, "t": ...}          a --resume (or --from-step) began here
    {"kind": "layer", "layer": 1, "color": "#b22222", "step": 812, "pin": 17, "t": ...}
                                                           a colour plan: that layer's thread tied on
    {"kind": "homing", "from": [ring_deg, head_mm] | null, "how": "...", "t": ...}
                                          homing is about to start from a position checked safe
                                          (null: the operator's word, the firmware knew none)
    {"kind": "approach", "from": [ring_deg, head_mm] | null, "to": [ring_deg, head_mm] | null, "t": ...}
                                          a first move (head IN, then the ring to the job's start)
                                          is about to be sent; ``to`` null: the operator jogs from there
    {"kind": "finished", "t": ...}

A step is recorded only once the machine has executed it.  A record is written
with one ``write`` and ``fsync``; a crash can leave only the last line torn
(no newline, or not JSON), and reading ignores such a line.  A damaged line
anywhere else means the file is not a journal this code wrote: refused.
"""

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from .._files import check_output_path, output_error, problem
from ..errors import BadInput

__all__ = ["Journal", "JournalState", "read_journal", "journal_path_for"]

FORMAT = "stringbot-journal"
VERSION = 1


def journal_path_for(plan_path, *, dry_run=False):
    """Default journal path: beside the plan (``plan.json.journal``; dry runs apart)."""
    plan_path = Path(plan_path)
    suffix = ".dry-run.journal" if dry_run else ".journal"
    return plan_path.with_name(plan_path.name + suffix)


@dataclass
class JournalState:
    """What a journal says."""

    path: Path
    header: dict
    done: list = field(default_factory=list)         # executed step indices, in order
    stops: list = field(default_factory=list)        # the stop records
    resumes: list = field(default_factory=list)
    layers: list = field(default_factory=list)       # the "layer" records (threads tied on), in order
    finished: bool = False
    last_time: float | None = None
    torn: bool = False                                # a torn last line was ignored

    @property
    def steps_total(self):
        return self.header.get("steps")

    next_step: int = 0                                # the first step not yet executed
    next_move: int = 0                                # the first move of it not yet executed
    epoch: list = field(default_factory=list)         # stop/recover/declared/refused since the last resume
    homing: dict | None = None                        # the last "homing" record (a start's checked homing)
    approach: dict | None = None                      # the last "approach" record, if no step moved since
    moved: bool = False                               # anything was sent that moves the machine

    def start_phase(self, point):
        """Where a stop before the first step's moves left the job at journal point ``point``
        ``(step, move)``: ``"approach"`` (a first move was sent, see :attr:`approach`),
        ``"homing"`` (a checked homing began, :attr:`homing`), or None (the journal's path is
        the steps', or nothing moved)."""
        if tuple(point) != (0, 0) or self.done:
            return None
        if self.approach is not None:
            return "approach"
        if self.homing is not None:
            return "homing"
        return None

    @property
    def last_stop(self):
        return self.stops[-1] if self.stops else None


def read_journal(path):
    """Read a journal; raises :class:`BadInput` when it is missing or not a journal."""
    path = Path(path)
    if not path.exists():
        raise BadInput(f"journal {str(path)!r} does not exist; nothing to resume "
                       "(wind without --resume to start, or give --journal)")
    if path.is_dir():
        raise BadInput(f"journal path {str(path)!r} is a folder; expected a journal file")
    if not path.is_file():            # a FIFO would block the read, a device would never end
        raise BadInput(f"journal {str(path)!r} is not a regular file; expected a journal file")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise BadInput(f"journal {str(path)!r} cannot be read: {problem(exc)}") from None
    lines = data.split(b"\n")
    complete, tail = lines[:-1], lines[-1]
    records = []
    torn = bool(tail.strip())
    for n, raw in enumerate(complete, 1):
        try:
            rec = json.loads(raw)
            if not isinstance(rec, dict) or "kind" not in rec:
                raise ValueError
        except ValueError:
            if n == len(complete) and not tail.strip():
                torn = True           # a torn last line that happens to end in a newline
                break
            raise BadInput(f"journal {str(path)!r} line {n} is damaged; expected one JSON record "
                           "per line (is this a stringbot journal?)") from None
        records.append(rec)
    if not records or records[0].get("kind") != "start" or records[0].get("format") != FORMAT:
        raise BadInput(f"journal {str(path)!r} does not start with a stringbot journal header")
    if records[0].get("version") != VERSION:
        raise BadInput(f"journal {str(path)!r} is version {records[0].get('version')!r}; "
                       f"expected {VERSION}")
    steps = records[0].get("steps")
    if not _is_int(steps) or steps < 1:
        raise BadInput(f"journal {str(path)!r} line 1 is damaged: steps is {steps!r}; expected the "
                       "plan's step count (a whole number, at least 1)")
    state = JournalState(path=path, header=records[0], torn=torn)
    for n, rec in enumerate(records[1:], 2):
        _check_record(path, n, rec, steps)
        kind = rec.get("kind")
        if kind in ("done", "move", "homing", "approach", "resume") or (kind == "refused" and rec.get("moved")):
            state.moved = True
        if kind == "done":
            state.done.append(rec["step"])
            state.next_step = rec["step"] + 1
            state.next_move = 0
            state.approach = None
        elif kind == "move":
            if rec["step"] == state.next_step:
                state.next_move = rec["move"] + 1
            state.approach = None
        elif kind == "homing":
            state.homing, state.approach = rec, None
        elif kind == "approach":
            state.approach = rec
        elif kind == "stop":
            state.stops.append(rec)
            state.epoch.append(rec)
            at = rec.get("at") or {}
            if at.get("step_index", 0) > 0 or at.get("move", 0) > 0:
                state.moved = True      # a step's move was running
        elif kind in ("recover", "declared", "refused"):
            state.epoch.append(rec)
        elif kind == "resume":
            state.resumes.append(rec)
            state.epoch = []
            state.homing = state.approach = None    # the resume re-established the position
            # --from-step moves the next step: steps from there on are to be wound again
            start = rec.get("from_step", state.next_step)
            state.done = [s for s in state.done if s < start]
            state.next_step = start
            state.next_move = rec.get("from_move", 0)
        elif kind == "layer":
            state.layers.append(rec)
        elif kind == "finished":
            state.finished = True
        state.last_time = rec.get("t", state.last_time)
    return state


def _is_int(v):
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


# per kind: field -> (required, check, expected form); steps are indices 0..steps-1
_FIELDS = {
    "done": {"step": (True, "step", "a step index 0..{last}"),
             "pin": (True, "index", "a pin number (a whole number >= 0)")},
    "move": {"step": (True, "step", "a step index 0..{last}"),
             "move": (True, "index", "a move index (a whole number >= 0)")},
    "layer": {"layer": (True, "index", "a layer index (a whole number >= 0)"),
              "step": (True, "step", "a step index 0..{last}"),
              "color": (False, "str", "a colour #rrggbb")},
    "resume": {"from_step": (False, "step_or_end", "a step index 0..{steps}"),
               "from_move": (False, "index", "a move index (a whole number >= 0)")},
    "recover": {"banner": (False, "bool", "true or false"),
                "alarm": (False, "str_or_null", "a text"),
                "alarm_cleared": (False, "bool", "true or false"),
                "position_wiped": (False, "bool", "true or false"),
                "mpos": (False, "position", "null or a list of axis positions (numbers)"),
                "position": (False, "position", "null or [ring_deg, head_mm]")},
    "homing": {"from": (False, "position", "null or [ring_deg, head_mm]"),
               "how": (False, "str", "a text")},
    "approach": {"from": (False, "position", "null or [ring_deg, head_mm]"),
                 "to": (False, "position", "null or [ring_deg, head_mm]")},
    "declared": {"position": (True, "position", "[ring_deg, head_mm]"),
                 "how": (False, "str", "a text")},
    "refused": {"error": (False, "str_or_null", "a text"),
                "moved": (False, "bool", "true or false")},
    "stop": {"reason": (False, "str", "a text"),
             "error": (False, "str_or_null", "a text"),
             "next_step": (False, "step_or_end", "a step index 0..{steps}"),
             "at": (False, "at", 'null or {{"step_index": 0..{steps}, "move": a whole number >= 0}}'),
             "position": (False, "position", "null or a list of axis positions (numbers)"),
             "layer": (False, "index", "a layer index (a whole number >= 0)")},
}


def _valid(check, v, steps):
    if check == "step":
        return _is_int(v) and 0 <= v < steps
    if check == "step_or_end":
        return _is_int(v) and 0 <= v <= steps
    if check == "index":
        return _is_int(v) and v >= 0
    if check == "str":
        return isinstance(v, str)
    if check == "bool":
        return isinstance(v, bool)
    if check == "str_or_null":
        return v is None or isinstance(v, str)
    if check == "at":
        return v is None or (isinstance(v, dict) and _valid("step_or_end", v.get("step_index"), steps)
                             and _valid("index", v.get("move"), steps))
    if check == "position":
        # the firmware's axes in its order (GRBL: x, y, z) or a servo link's (ring_deg, head_mm)
        return v is None or (isinstance(v, list) and all(_is_number(x) for x in v))
    raise AssertionError(check)


def _check_record(path, n, rec, steps):
    """Refuse record ``n`` (line number) whose fields are missing or of the wrong form."""
    def damaged(what, expected):
        raise BadInput(f"journal {str(path)!r} line {n} is damaged: {what}; expected {expected}")

    kind = rec.get("kind")
    if not isinstance(kind, str):
        damaged(f"kind is {kind!r}", "a record kind (done, move, stop, resume, finished)")
    if kind == "start":
        damaged("a second header", "one header, on line 1")
    t = rec.get("t")
    if t is not None and not _is_number(t):
        damaged(f"{kind} record's t is {t!r}", "a time in seconds (a number)")
    for name, (required, check, expected) in _FIELDS.get(kind, {}).items():
        if name not in rec:
            if required:
                damaged(f"{kind} record without {name}", f"{name} as {expected.format(last=steps - 1, steps=steps)}")
            continue
        if not _valid(check, rec[name], steps):
            damaged(f"{kind} record's {name} is {rec[name]!r}",
                    expected.format(last=steps - 1, steps=steps))


class Journal:
    """An open journal, appended to as the winding goes.

    Use :meth:`create` for a new winding, :meth:`reopen` to append after a resume.
    """

    def __init__(self, path, fd, durable=True):
        self.path = Path(path)
        self._fd = fd
        self.durable = durable

    @classmethod
    def create(cls, path, *, plan_path, plan_sha256, machine, steps, durable=True):
        """A new journal.  ``durable=False`` skips fsync: only for a simulated machine that
        lives in this process (it dies with the process, so there is nothing to resume)."""
        path = Path(path)
        check_output_path(path, what="journal")   # a regular file (through a symlink) or nothing yet
        if path.exists():
            _check_overwritable(path, plan_path)
        fd = None
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)   # less the umask
            j = cls(path, fd, durable)
            j.append({"kind": "start", "format": FORMAT, "version": VERSION, "plan": str(plan_path),
                      "plan_sha256": plan_sha256, "machine": machine, "steps": steps})
        except OSError as exc:
            if fd is not None:
                os.close(fd)
            raise output_error(path, exc, what="journal") from None
        _fsync_dir(path.parent)
        return j

    @classmethod
    def reopen(cls, path, *, durable=True):
        path = Path(path)
        data = path.read_bytes()
        keep = len(data)
        if data and not data.endswith(b"\n"):
            keep = data.rfind(b"\n") + 1          # drop a torn last line
        else:
            last = data[:-1].rfind(b"\n") + 1
            try:
                json.loads(data[last:keep])
            except ValueError:
                keep = last                        # a torn last line that ended in a newline
        try:
            if keep < len(data):
                os.truncate(path, keep)
            fd = os.open(path, os.O_WRONLY | os.O_APPEND)
        except OSError as exc:
            raise output_error(path, exc, what="journal") from None
        return cls(path, fd, durable)

    def append(self, record):
        """Write one record and fsync it before returning."""
        record = dict(record)
        record.setdefault("t", round(time.time(), 3))
        line = json.dumps(record, separators=(",", ":")) + "\n"
        if self._fd is None:
            raise RuntimeError("journal is closed")
        os.write(self._fd, line.encode("utf-8"))
        if self.durable:
            os.fsync(self._fd)

    def done(self, step, pin):
        self.append({"kind": "done", "step": int(step), "pin": int(pin)})

    def close(self):
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


_HEADER_START = b'{"kind":"start","format":"' + FORMAT.encode() + b'"'


def _check_overwritable(path, plan_path):
    """A new journal replaces only an old journal (or an empty file): never the plan, a picture
    or anything else that happens to be at ``path``."""
    try:
        if plan_path is not None and Path(plan_path).exists() and path.samefile(plan_path):
            raise BadInput(f"journal {str(path)!r} is the plan itself; give the journal its own file")
        with open(path, "rb") as f:
            head = f.read(len(_HEADER_START))
    except OSError as exc:
        raise BadInput(f"journal {str(path)!r} cannot be read ({exc.strerror or exc}); "
                       "expected a journal file to replace") from None
    if head and not head.startswith(_HEADER_START):
        raise BadInput(f"journal {str(path)!r} exists and is not a stringbot journal; not "
                       "overwriting it: give --journal a new file (or remove that one)")


def _fsync_dir(folder):
    try:
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        pass
