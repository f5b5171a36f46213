"""Showing long work: a bar on a terminal, a line every so often in a log (ssh, nohup, a service).

``wind`` gets :class:`WindProgress`, ``plan`` :class:`PlanProgress`.  Both run
a small daemon thread that writes to standard error at a steady pace, so that
a log shows life even while one step (a homing, a long pause, a solve) lasts
minutes.
"""

import sys
import threading
import time

__all__ = ["WindProgress", "PlanProgress", "fmt_s", "LOG_EVERY_S"]

#: Without a terminal, a progress line at least this often.
LOG_EVERY_S = 30.0


def fmt_s(seconds):
    """``m:ss`` or ``h:mm:ss``."""
    seconds = int(round(max(0.0, seconds)))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class _Ticker:
    """Calls :meth:`tick` every ``every`` seconds from a daemon thread until :meth:`close`."""

    def __init__(self, every):
        self.every = every
        self.t0 = time.monotonic()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None

    def start(self):
        if self.every and self._thread is None:
            self._thread = threading.Thread(target=self._run, name="stringbot-progress", daemon=True)
            self._thread.start()
        return self

    def _run(self):
        while not self._stop.wait(self.every):
            with self._lock:
                self.tick()

    def tick(self):  # pragma: no cover - each kind says its own line
        raise NotImplementedError

    def close(self):
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)


class WindProgress(_Ticker):
    """The wind loop's progress callback.

    Parameters
    ----------
    every : float or None
        Seconds between progress lines.  None: a bar on a terminal, and without
        one a line every :data:`LOG_EVERY_S` seconds.
    stream : file
        Standard error by default.
    """

    def __init__(self, *, every=None, stream=None):
        self.stream = stream or sys.stderr
        isatty = getattr(self.stream, "isatty", lambda: False)
        self.tty = bool(isatty())
        if every is None and not self.tty:
            every = LOG_EVERY_S
        super().__init__(every)
        self.last = None                  # the latest Progress and when it came
        self.at = None
        self._bar = None
        self._bar_done = 0
        self.started = False

    def __call__(self, p):
        with self._lock:
            self.last, self.at = p, time.monotonic()
            if self.every:
                if not self.started:      # the first step: say that winding is under way
                    self.started = True
                    self._line()
                return
            self._update_bar(p)

    def _update_bar(self, p):
        import click
        if self._bar is None:
            self._bar = click.progressbar(length=p.total, label="winding", show_eta=False, show_pos=True,
                                          item_show_func=lambda _x: self._text, file=self.stream)
            self._bar.__enter__()
            self._bar.update(p.done - 1)
            self._bar_done = p.done - 1
        eta = fmt_s(p.eta_s) if p.eta_s is not None else "?"
        self._text = f"pin {p.pin}  ETA {eta}  (machine time left {fmt_s(p.machine_s)})"
        self._bar.update(p.done - self._bar_done)
        self._bar_done = p.done

    _text = None

    def tick(self):
        self._line()

    def _line(self):
        now = time.monotonic()
        elapsed = fmt_s(now - self.t0)
        p = self.last
        if p is None:
            text = f"winding: {elapsed} elapsed, no step done yet (connecting, homing or waiting)"
        else:
            eta = "?" if p.eta_s is None else fmt_s(max(0.0, p.eta_s - (now - self.at)))
            text = (f"winding: step {p.step} of {p.total} ({100.0 * p.done / max(p.total, 1):.1f} %), "
                    f"pin {p.pin}, {elapsed} elapsed, ETA {eta}")
        self.stream.write(text + "\n")
        self.stream.flush()

    def close(self):
        super().close()
        with self._lock:
            if self._bar is not None:
                self._bar.__exit__(None, None, None)
                self._bar = None


class PlanProgress(_Ticker):
    """The planner's progress callback (see :mod:`stringbot.planner.progress`).

    Quiet for the first ``after`` seconds (a plan usually takes one or two); then,
    on a terminal, one line rewritten in place and cleared at the end; without a
    terminal, a line every ``every`` seconds.
    """

    def __init__(self, *, after=2.0, every=None, stream=None):
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        super().__init__(every if every is not None else (0.5 if self.tty else 10.0))
        self.after = after
        self.stage = "starting"
        self.count = ""
        self._shown = False

    def __call__(self, stage, done=None, total=None):
        with self._lock:
            if stage == "sampling" and self.stage.startswith("sampling"):
                self.count = f" {done} of {total} lines" if total else ""
            else:
                self.stage, self.count = stage, ""

    def tick(self):
        elapsed = time.monotonic() - self.t0
        if elapsed < self.after:
            return
        text = f"planning: {self.stage}{self.count}, {fmt_s(elapsed)} elapsed"
        if self.tty:
            self.stream.write("\r\x1b[K" + text)
        else:
            self.stream.write(text + "\n")
        self._shown = True
        self.stream.flush()

    def close(self):
        super().close()
        with self._lock:
            if self.tty and self._shown:
                self.stream.write("\r\x1b[K")
                self.stream.flush()
