"""A command run on a pseudo-terminal as a maker at a keyboard runs it: keys in, the screen out.

The child is the session leader of its own pseudo-terminal (``pty.fork``), so Ctrl-C typed there
(``\\x03``) is a real SIGINT from the terminal, and cbreak mode is a real terminal's.  Reads wait
with generous timeouts; nothing measures durations.
"""

import os
import pty
import re
import select
import signal
import sys
import time

ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


class PtySession:
    """``argv`` (after ``python -c 'from stringbot.cli import main; main()'``) on a new pseudo-terminal."""

    def __init__(self, *args, cwd=None, env=None):
        argv = [sys.executable, "-c", "from stringbot.cli import main; main()", *map(str, args)]
        e = dict(os.environ, **(env or {}))
        e.setdefault("TERM", "xterm")
        pid, fd = pty.fork()
        if pid == 0:                           # the child: exec at once
            try:
                if cwd:
                    os.chdir(cwd)
                os.execve(argv[0], argv, e)
            finally:
                os._exit(127)
        self.pid, self.fd = pid, fd
        self.out = ""                          # everything the screen showed, ANSI codes removed
        self.seen = 0                          # how far expect() has read
        self.code = None

    def _pump(self, timeout):
        r, _, _ = select.select([self.fd], [], [], timeout)
        if not r:
            return False
        try:
            data = os.read(self.fd, 4096)
        except OSError:                        # EIO: the child closed the terminal
            data = b""
        if not data:
            return None
        self.out += ANSI.sub("", data.decode("utf-8", "replace")).replace("\r\n", "\n")
        return True

    def expect(self, pattern, timeout=60):
        """Wait until ``pattern`` (a regex) shows after what was expected before; its match."""
        rx = re.compile(pattern)
        deadline = time.monotonic() + timeout
        while True:
            m = rx.search(self.out, self.seen)
            if m:
                self.seen = m.end()
                return m
            left = deadline - time.monotonic()
            if left <= 0 or self._pump(min(left, 1.0)) is None and not rx.search(self.out, self.seen):
                raise AssertionError(f"{pattern!r} did not show; the screen after the last match:\n"
                                     f"{self.out[self.seen:]}")

    def send(self, keys):
        os.write(self.fd, keys.encode() if isinstance(keys, str) else keys)

    def wait(self, timeout=60):
        """Read the screen to its end and return the exit code."""
        deadline = time.monotonic() + timeout
        while self.code is None:
            got = self._pump(0.2)
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                while self._pump(0.2):
                    pass
                self.code = os.waitstatus_to_exitcode(status)
            elif time.monotonic() > deadline:
                self.kill()
                raise AssertionError(f"still running after {timeout} s; screen:\n{self.out}")
            elif got is None:
                time.sleep(0.05)
        return self.code

    def kill(self):
        try:
            os.kill(self.pid, signal.SIGKILL)
            os.waitpid(self.pid, 0)
        except OSError:
            pass

    def close(self):
        if self.code is None:
            self.kill()
        try:
            os.close(self.fd)
        except OSError:
            pass
