"""``by-hand --speak``: each step read aloud by espeak-ng, without holding up the keys.

One utterance at a time: a newer one stops the one before (the maker is at the
next pin already).  espeak-ng runs as a child process in a session of its own
(Ctrl-C at the terminal is ours to handle, not its), its output discarded.
"""

import shutil
import subprocess

from ..errors import BadInput

__all__ = ["ESPEAK", "NOT_INSTALLED", "Speaker", "speech_argv", "SPEED_RANGE"]

ESPEAK = "espeak-ng"
NOT_INSTALLED = ("--speak: espeak-ng is not installed (apt-get install espeak-ng, brew install espeak-ng, "
                 "or espeak-ng.org); continuing silently")
#: espeak-ng's own bounds, words per minute
SPEED_RANGE = (80, 450)


def speech_argv(exe, text, *, voice=None, speed=None):
    """The command that says ``text`` (``exe`` is espeak-ng's path)."""
    argv = [exe]
    if voice:
        argv += ["-v", voice]
    if speed:
        argv += ["-s", str(int(speed))]
    return argv + [text]


class Speaker:
    """Says one thing at a time with espeak-ng at ``exe``.

    Parameters
    ----------
    exe : str
    voice : str, optional
        An espeak-ng voice (``espeak-ng --voices``), e.g. ``en-us``, ``de``.
    speed : int, optional
        Words per minute.
    """

    def __init__(self, exe, *, voice=None, speed=None):
        self.exe, self.voice, self.speed = exe, voice, speed
        self._speaking = None       # the utterance under way (a Popen), the only one
        self._stopping = []         # cut short, not yet reaped

    @classmethod
    def find(cls, *, voice=None, speed=None):
        """``(Speaker, None)`` where espeak-ng is on PATH, else ``(None, NOT_INSTALLED)``.

        Raises
        ------
        BadInput
            ``speed`` outside :data:`SPEED_RANGE`; a voice espeak-ng does not have.
        """
        lo, hi = SPEED_RANGE
        if speed is not None and not lo <= speed <= hi:
            raise BadInput(f"--speed {speed}; expected {lo}..{hi} words a minute (espeak-ng's range)")
        exe = shutil.which(ESPEAK)
        if exe is None:
            return None, NOT_INSTALLED
        if voice:
            try:      # -q: nothing said, only the voice looked up (a few ms)
                ok = subprocess.run([exe, "-q", "-v", voice, ""], stdin=subprocess.DEVNULL,
                                    capture_output=True, timeout=10).returncode == 0
            except (OSError, subprocess.SubprocessError):
                ok = False
            if not ok:
                raise BadInput(f"--voice {voice!r}: espeak-ng has no such voice; expected one that "
                               "`espeak-ng --voices` lists, e.g. en, en-us, de, fr")
        return cls(exe, voice=voice, speed=speed), None

    def say(self, text):
        """Start saying ``text``, cutting short what is being said; returns at once."""
        self._cut()
        try:
            self._speaking = subprocess.Popen(speech_argv(self.exe, text, voice=self.voice, speed=self.speed),
                                              stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                              stderr=subprocess.DEVNULL, start_new_session=True)
        except OSError:
            self._speaking = None   # gone since we looked: silent from here, the keys go on

    def _cut(self):
        proc, self._speaking = self._speaking, None
        if proc is not None and proc.poll() is None:
            proc.terminate()
            self._stopping.append(proc)
        self._stopping = [p for p in self._stopping if p.poll() is None]

    def close(self, *, wait_s=2.0):
        """Let the last utterance finish (at most ``wait_s``), then stop whatever still speaks."""
        proc = self._speaking
        if proc is not None:
            try:
                proc.wait(timeout=wait_s)
            except subprocess.TimeoutExpired:
                pass
        self._cut()
        for p in self._stopping:
            try:
                p.wait(timeout=1.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        self._stopping = []
