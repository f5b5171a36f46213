"""``wind --questions json``: the operator asked through JSON lines, for a front end (``stringbot serve``).

The winding is the command line's own (the same :func:`~stringbot.winding.wind_plan` and
:func:`~stringbot.winding.resume.resume_plan`, the same checks and exit codes); only the
operator is elsewhere.  Each message to the front end is one JSON object on a line of
standard output; each answer one on a line of standard input::

    -> {"ask": "confirm", "id": 1, "question": "Tie the thread on at pin 176 ..., then go on?"}
    <- {"id": 1, "value": true}
    -> {"ask": "choose", "id": 2, "question": "...", "choices": ["in", "out", "guide"]}
    -> {"ask": "jog", "id": 3, "prompt": "jog> "}          <- {"id": 3, "value": "pin -1"}
    -> {"ask": "thread", "id": 4, "question": "Spool change: ...", "color": "#b22222"}
    -> {"say": "Guided resume: ..."}
    -> {"progress": {"done": 12, "total": 41, "step": 12, "pin": 57, "elapsed_s": 3.1, "eta_s": 40.2,
                     "machine_s": 38.0}}

A Ctrl-C (SIGINT) is the command line's own: feed hold, the journal's stop record, exit 130.
The front end keeps standard input open while the winding runs; when it closes (the front end
is gone, crashed or killed) the winding stops in the same way, as if Ctrl-C was pressed: a
winding nobody can pause or answer does not go on.
"""

import json
import os
import queue
import signal
import sys
import threading
import time

__all__ = ["JsonQuestions"]

#: Progress messages at most this often (the journal has every step; this is for the ETA).
PROGRESS_EVERY_S = 0.2


class JsonQuestions:
    """The operator's callables of ``wind`` (confirm, choose, jog, say, thread) and its progress
    callback, over JSON lines."""

    def __init__(self, *, out=None, inp=None):
        self.out = out or sys.stdout
        self.inp = inp or sys.stdin
        self._answers = queue.Queue()
        self._n = 0
        self._last_progress = 0.0
        self._pending = None
        self._ctrl_c = threading.Event()        # a SIGINT came: standard input's end sends none of its own
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, self._on_sigint)
        self._reader = threading.Thread(target=self._read, name="stringbot-answers", daemon=True)
        self._reader.start()

    # ---- the pipe --------------------------------------------------------------------------
    def _read(self):
        """Answers into the queue; at the end of standard input, Ctrl-C (the front end is gone)."""
        for line in self.inp:
            try:
                msg = json.loads(line)
            except ValueError:
                continue
            if isinstance(msg, dict) and "id" in msg:
                self._answers.put(msg)
        self._answers.put(None)
        if not self._ctrl_c.is_set():
            os.kill(os.getpid(), signal.SIGINT)

    def _on_sigint(self, signum, frame):
        self._ctrl_c.set()
        signal.default_int_handler(signum, frame)

    def _send(self, msg):
        try:
            self.out.write(json.dumps(msg) + "\n")
            self.out.flush()
        except (OSError, ValueError):   # the front end is gone: standard input's end stops the winding
            pass

    def _ask(self, kind, **fields):
        self._flush_progress()
        self._n += 1
        self._send({"ask": kind, "id": self._n, **fields})
        while True:
            try:
                msg = self._answers.get(timeout=0.5)      # a timeout: Ctrl-C gets through at once
            except queue.Empty:
                continue
            if msg is None:             # standard input ended: its SIGINT is on its way (the Ctrl-C path)
                time.sleep(10.0)
                raise KeyboardInterrupt
            if msg.get("id") == self._n:
                return msg.get("value")

    # ---- the operator ------------------------------------------------------------------------
    def confirm(self, question):
        return bool(self._ask("confirm", question=question))

    def choose(self, question, choices):
        choices = [str(c) for c in choices]
        while True:
            value = str(self._ask("choose", question=question, choices=choices))
            if value in choices:
                return value
            self.say(f"{value!r} is not one of {', '.join(choices)}")

    def jog(self, prompt):
        return str(self._ask("jog", prompt=prompt) or "")

    def thread(self, question, color):
        """A spool change: True once the front end says the thread of ``color`` is tied on."""
        return bool(self._ask("thread", question=question, color=color))

    def say(self, text):
        self._send({"say": str(text)})

    # ---- progress ----------------------------------------------------------------------------
    def __call__(self, p):
        """The wind loop's progress callback (at most every :data:`PROGRESS_EVERY_S`)."""
        self._pending = p
        now = time.monotonic()
        if now - self._last_progress >= PROGRESS_EVERY_S or p.done >= p.total:
            self._flush_progress(now)

    def _flush_progress(self, now=None):
        p, self._pending = self._pending, None
        if p is None:
            return
        self._last_progress = time.monotonic() if now is None else now
        self._send({"progress": {"done": p.done, "total": p.total, "step": p.step, "pin": p.pin,
                                 "elapsed_s": round(p.elapsed_s, 2),
                                 "eta_s": None if p.eta_s is None else round(p.eta_s, 1),
                                 "machine_s": round(p.machine_s, 1)}})

    def close(self):
        self._flush_progress()
