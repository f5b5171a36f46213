"""One winding as the workshop runs it: ``stringbot wind ... --questions json`` in a child process.

The child is the command line's own winding (its checks, its journal, its exit codes); the
workshop relays its questions to the page and the page's answers back, and holds what the
page shows.  The live state comes from the journal, the truth (each executed step, the tie-ons,
the stop records), read as it grows (each time the page's state is looked at); the child's progress messages add the ETA.

Stop is SIGINT to the child: the command line's Ctrl-C, which holds the feed, waits for the
machine to stand still, journals the stop and exits 130; ``--resume`` then continues exactly.
The child runs in its own session (a Ctrl-C meant for the workshop's terminal is not its), and
its standard input stays open while it runs: if the workshop dies, the child sees its end and
stops the Ctrl-C way, so nothing is lost (the journal says where to resume).
"""

import asyncio
import enum
import json
import logging
import os
import signal
import time
from collections import deque
from pathlib import Path

__all__ = ["Winding", "Phase", "Outcome"]

log = logging.getLogger(__name__)

#: Lines of what the winding said that the page keeps.
SAID_LINES = 12


class Phase(enum.Enum):
    """Where a winding of the workshop stands (one owner: its :class:`Winding`)."""

    RUNNING = "running"         # the child winds (or connects, checks, homes)
    ASKING = "asking"           # the child waits for the operator's answer
    STOPPING = "stopping"       # Ctrl-C sent: the machine is being held, the stop journaled
    ENDED = "ended"             # the child exited: see the outcome


class Outcome(enum.Enum):
    """How a winding ended: the command line's exit code."""

    FINISHED = 0
    FAILED = 1
    REFUSED = 2
    SPOOL_CHANGE = 3
    STOPPED = 130
    OTHER = -1

    @classmethod
    def of(cls, code):
        try:
            return cls(code)
        except ValueError:
            return cls.OTHER


class Conflict(Exception):
    """A request the winding's state does not allow (an answer to a question no longer asked)."""


class _JournalTail:
    """The journal's records as it grows: read from where the last read ended (a journal
    replaced by a fresh start is read from its start)."""

    def __init__(self, path):
        self.path = Path(path)
        self._ino = None
        self._offset = 0
        self._rest = b""
        self.done = None            # the last executed step: (index, pin)
        self.stop = None            # the last stop record
        self.layer = None           # the last tie-on record
        self.records = 0

    def read(self):
        try:
            st = os.stat(self.path)
        except OSError:
            return
        if st.st_ino != self._ino or st.st_size < self._offset:
            self.__init__(self.path)
            self._ino = st.st_ino
        if st.st_size == self._offset:
            return
        with open(self.path, "rb") as f:
            f.seek(self._offset)
            chunk = f.read(st.st_size - self._offset)
        self._offset += len(chunk)
        lines = (self._rest + chunk).split(b"\n")
        self._rest = lines.pop()
        for line in lines:
            try:
                rec = json.loads(line)
            except ValueError:
                continue
            self.records += 1
            kind = rec.get("kind")
            if kind == "done":
                self.done = (int(rec["step"]), int(rec["pin"]))
            elif kind == "stop":
                self.stop = rec
            elif kind == "layer":
                self.layer = rec
            elif kind in ("resume", "start"):
                self.stop = None


class Winding:
    """One ``stringbot wind`` child and what the page shows of it.

    Parameters
    ----------
    command : Command
    machine, plan_name, target : str
    journal : Path
        The journal the child writes (read as it grows).
    sequence : list of int
        The plan's pins, every layer's in winding order (its steps).
    layers : list of (color, first step)
        A colour plan's layers (one for a one-thread plan).
    on_end : callable(Winding) or None
        Called once the child has exited (the record check, the page's plans).
    """

    def __init__(self, command, *, machine, plan_name, target, journal, sequence, layers, resume=False,
                 on_end=None):
        self.command = command
        self.machine, self.plan_name, self.target = machine, plan_name, target
        self.tail = _JournalTail(journal)
        self.sequence = list(sequence)
        self.total = len(self.sequence)
        self.layers = layers
        self.resume = resume
        self.on_end = on_end
        self.phase = Phase.RUNNING
        self.outcome = None
        self.code = None
        self.question = None
        self.progress = None
        self.progress_at = None
        self.said = deque(maxlen=SAID_LINES)
        self.said_count = 0         # lines said in all (the page's new ones: the last count - its last)
        self.last_line = None       # the command line's last "stringbot: ..." line
        self.summary = None         # its "wound N pins ..." line
        self.check = None           # the record check of a simulated winding, when it ended
        self.started = time.time()
        self.ended = None
        self.proc = None
        self._asked = 0
        self._tasks = []

    # ---- the child ---------------------------------------------------------------------------
    async def start(self):
        self.tail.read()
        self.proc = await asyncio.create_subprocess_exec(
            *self.command.argv(), cwd=str(self.command.cwd), stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE, start_new_session=True)
        loop = asyncio.get_running_loop()
        self._tasks = [loop.create_task(self._read_out()), loop.create_task(self._read_err())]
        loop.create_task(self._wait())
        return self

    async def _read_out(self):
        async for raw in self.proc.stdout:
            line = raw.decode(errors="replace").rstrip("\n")
            if not line.startswith("{"):
                if line.strip():
                    self.summary = line
                    self.say(line)
                continue
            try:
                msg = json.loads(line)
            except ValueError:
                self.say(line)
                continue
            if "ask" in msg:
                self.question = msg
                self._asked += 1
                self.phase = Phase.ASKING if self.phase is Phase.RUNNING else self.phase
            elif "progress" in msg:
                self.progress, self.progress_at = msg["progress"], time.monotonic()
            elif "say" in msg:
                self.say(msg["say"])

    def say(self, text):
        self.said.append(text)
        self.said_count += 1

    async def _read_err(self):
        async for raw in self.proc.stderr:
            line = raw.decode(errors="replace").rstrip("\n")
            if line.startswith("stringbot:"):
                self.last_line = line
            if line.strip():
                self.say(line)

    async def _wait(self):
        self.code = await self.proc.wait()
        for task in self._tasks:
            await task                  # everything it wrote has been read
        self.tail.read()
        self.outcome = Outcome.of(self.code)
        self.question = None
        self.ended = time.time()
        try:
            self.proc.stdin.close()
        except (OSError, RuntimeError):
            pass
        self.phase = Phase.ENDED
        if self.on_end is not None:
            try:
                self.on_end(self)
            except Exception:       # the page's view of it must not take the server down
                log.exception("after the winding of %s", self.plan_name)

    # ---- the page's actions ------------------------------------------------------------------
    def answer(self, ask_id, value):
        """The operator's answer to question ``ask_id``; a :class:`Conflict` when it is no longer
        the question asked (another page answered it, or the winding moved on)."""
        q = self.question
        if self.phase is Phase.ENDED or q is None or q.get("id") != ask_id:
            raise Conflict("that question is no longer asked (answered on another page, or the winding "
                           "moved on); the page shows the current one")
        if q["ask"] == "choose" and str(value) not in q["choices"]:
            from ..errors import BadInput
            raise BadInput(f"answer {value!r}; expected one of {', '.join(q['choices'])}")
        self.question = None
        self.phase = Phase.RUNNING
        self.proc.stdin.write((json.dumps({"id": ask_id, "value": value}) + "\n").encode())

    def stop(self):
        """Ctrl-C to the child: feed hold, the stop journaled, resumable."""
        if self.phase is Phase.ENDED:
            return False
        if self.phase is not Phase.STOPPING:
            self.phase = Phase.STOPPING
            self.question = None
            try:
                os.kill(self.proc.pid, signal.SIGINT)
            except OSError:
                return False
        return True

    def next_pin(self):
        """The pin of the first step not yet executed (where a thread is tied on at a spool change)."""
        self.tail.read()
        done = self.tail.done[0] + 1 if self.tail.done else 0
        return self.sequence[min(done, self.total - 1)]

    @property
    def active(self):
        return self.phase is not Phase.ENDED

    # ---- what the page shows -----------------------------------------------------------------
    def snapshot(self):
        """What the page shows; the journal read up to now first (the truth of what was wound)."""
        self.tail.read()
        done_rec = self.tail.done
        done = done_rec[0] + 1 if done_rec else 0
        p = self.progress
        eta = None
        if p is not None and p.get("eta_s") is not None and self.phase is not Phase.ENDED:
            eta = max(0.0, p["eta_s"] - (time.monotonic() - self.progress_at))
        layer = None
        if len(self.layers) > 1:         # the thread on the machine: the last hooked step's layer
            at = min(max(done - 1, 0), self.total - 1)
            layer = max(k for k, (_, first) in enumerate(self.layers) if first <= at)
        return {
            "machine": self.machine, "plan": self.plan_name, "target": self.target.value,
            "phase": self.phase.value, "resume": self.resume, "started": self.started, "command": self.command.shown(),
            "done": done, "total": self.total, "pin": done_rec[1] if done_rec else None,
            "eta_s": None if eta is None else round(eta), "elapsed_s": round((self.ended or time.time()) - self.started),
            "layer": layer, "question": self._question(done), "asked": self._asked, "said": list(self.said), "said_count": self.said_count,
            "pid": None if self.proc is None else self.proc.pid,
            "outcome": None if self.outcome is None else self.outcome.name.lower().replace("_", " "),
            "code": self.code, "line": self.last_line, "summary": self.summary, "check": self.check,
            "stop": _stop_summary(self.tail.stop),
        }


    def _question(self, done):
        q = self.question
        if q is None or q.get("ask") != "thread":
            return q
        from ..planner.colour.palette import color_name
        return {**q, "pin": self.sequence[min(done, self.total - 1)], "name": color_name(q["color"])}


def _stop_summary(stop):
    if stop is None:
        return None
    return {"reason": stop.get("reason"), "error": stop.get("error"), "step": stop.get("step"),
            "pin": stop.get("pin"), "layer": stop.get("layer")}
