"""``by-hand``'s input: single keys at a terminal, or one command a line from a pipe or a file.

At a terminal the keys are read one by one (cbreak mode: no Enter needed, no
echo; Ctrl-C still interrupts), and the terminal is put back as it was on the
way out, on Ctrl-Z (and back to single keys on ``fg``).  Elsewhere each line
is a command (``next`` or an empty line, ``back``, ``repeat``, ``go N``,
``quit``), so a winding can be scripted; the end of the input is ``quit``.
"""

import enum
import os
import signal
import sys

__all__ = ["Command", "LEGEND", "LINE_COMMANDS", "terminal_commands", "line_commands", "parse_keys", "Cbreak"]


class Command(enum.Enum):
    """What the maker asks for."""

    NEXT = "next"
    BACK = "back"
    REPEAT = "repeat"
    GO = "go"
    KEYS = "keys"
    QUIT = "quit"


LEGEND = ("keys: Space/Enter/n next, b/Backspace back, r repeat (say it again), g go to step, "
          "q quit (the position is kept), ? these keys")
LINE_COMMANDS = "next (or an empty line), back, repeat, go N, quit"

_KEYS = {
    Command.NEXT: (" ", "\r", "\n", "n", "j", "\x1b[C", "\x1b[B", "\x1bOC", "\x1bOB", "\x1b[6~"),
    Command.BACK: ("b", "p", "k", "\x7f", "\x08", "\x1b[D", "\x1b[A", "\x1bOD", "\x1bOA", "\x1b[5~"),
    Command.REPEAT: ("r", "."),
    Command.GO: ("g",),
    Command.KEYS: ("?", "h"),
    Command.QUIT: ("q", "Q", "\x04"),
}
_KEY_OF = {key: cmd for cmd, keys in _KEYS.items() for key in keys}
_WORDS = {"": Command.NEXT, "n": Command.NEXT, "next": Command.NEXT, "b": Command.BACK, "back": Command.BACK,
          "r": Command.REPEAT, "repeat": Command.REPEAT, "q": Command.QUIT, "quit": Command.QUIT,
          "?": Command.KEYS, "help": Command.KEYS, "keys": Command.KEYS}


def parse_keys(data):
    """The keys in ``data`` (text read from a terminal): escape sequences (arrows) whole, else one
    character each."""
    keys, i = [], 0
    while i < len(data):
        if data[i] == "\x1b" and i + 1 < len(data) and data[i + 1] in "[O":
            j = i + 2
            while j < len(data) and not ("@" <= data[j] <= "~"):
                j += 1
            keys.append(data[i:j + 1])
            i = j + 1
        else:
            keys.append(data[i])
            i += 1
    return keys


class Cbreak:
    """The terminal at ``fd`` in cbreak mode for the ``with`` block, put back after (and on Ctrl-Z)."""

    def __init__(self, fd):
        self.fd = fd
        self._saved = None
        self._old_cont = None
        self._old_tstp = None

    def _on(self):
        import termios
        import tty
        tty.setcbreak(self.fd, termios.TCSANOW)

    def _off(self):
        import termios
        termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)

    def __enter__(self):
        import termios
        self._saved = termios.tcgetattr(self.fd)
        self._on()
        if hasattr(signal, "SIGTSTP"):
            self._old_tstp = signal.signal(signal.SIGTSTP, self._on_stop)
            self._old_cont = signal.signal(signal.SIGCONT, self._on_cont)
        return self

    def _on_stop(self, signum, frame):       # Ctrl-Z: the shell gets its terminal back as it was
        self._off()
        signal.signal(signal.SIGTSTP, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGTSTP)

    def _on_cont(self, signum, frame):       # fg: single keys again
        signal.signal(signal.SIGTSTP, self._on_stop)
        self._on()

    def __exit__(self, *exc):
        self._off()
        if self._old_tstp is not None:
            signal.signal(signal.SIGTSTP, self._old_tstp)
            signal.signal(signal.SIGCONT, self._old_cont)
        return False


def _read(fd):
    data = os.read(fd, 64)
    return data.decode("utf-8", "replace") if data else None


def _ask_step(fd, write, total):
    """``g``: the step number typed (digits, Backspace, Enter); None when cancelled (Esc, q, an empty
    number)."""
    write(f"go to step (1-{total}, Enter; Esc cancels): ", end=False)
    digits = ""
    while True:
        data = _read(fd)
        if data is None:
            write("")
            return None
        for key in parse_keys(data):
            if key.isdigit() and len(digits) < 9:
                digits += key
                write(key, end=False)
            elif key in ("\x7f", "\x08") and digits:
                digits = digits[:-1]
                write("\b \b", end=False)
            elif key in ("\r", "\n"):
                write("")
                return int(digits) if digits else None
            elif key in ("\x1b", "q", "\x04"):
                write("")
                return None


def terminal_commands(fd, write, total, *, unknown):
    """The maker's commands from the keys at the terminal ``fd`` (in cbreak mode): ``(Command, arg)``;
    ``write(text, end=True)`` shows the go-to prompt, ``unknown(key)`` a key that does nothing."""
    while True:
        data = _read(fd)
        if data is None:             # the terminal went away
            yield Command.QUIT, None
            return
        for key in parse_keys(data):
            cmd = _KEY_OF.get(key)
            if cmd is Command.GO:
                number = _ask_step(fd, write, total)
                if number is not None:
                    yield Command.GO, number
            elif cmd is not None:
                yield cmd, None
            else:
                unknown(key)


def line_commands(stream, *, unknown):
    """The maker's commands from ``stream``, one a line (see the module's notes); at its end ``QUIT``.
    ``unknown(line)`` hears of a line that is no command."""
    for raw in stream:
        words = raw.strip().lower().split()
        word = words[0] if words else ""
        if word in ("g", "go", "goto") and len(words) == 2 and words[1].isdigit():
            yield Command.GO, int(words[1])
        elif word in _WORDS and len(words) <= 1:
            yield _WORDS[word], None
        else:
            unknown(raw.strip())
    yield Command.QUIT, None


def stdin_is_terminal():
    """Whether standard input is a terminal (keys), not a pipe or a file (lines)."""
    try:
        return os.isatty(sys.stdin.fileno())
    except (AttributeError, ValueError, OSError):
        return False
