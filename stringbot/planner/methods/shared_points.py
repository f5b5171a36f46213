"""The chooser's chord points laid out by the polish's helper process (:mod:`.woven_helper`).

The residual chooser (:mod:`.residual`) scores the chords from a pin along
their points (:class:`~stringbot.planner.model.lines.PinLines`), built the
first time it visits the pin: about 0.2 s of its time at 300 pins, the same
whatever the picture.  On two cores the helper process, which has time to
spare while the threads are chosen, lays them out first in a shared buffer
(:class:`SharedPoints`), and the chooser takes each pin's from there once
the helper has said so.
"""

import numpy as np

__all__ = ["SharedPoints"]


class SharedPoints:
    """The chooser's chord points (:class:`~stringbot.planner.model.lines.PinLines`), laid out by the helper.

    Made in the planner's process before the helper is forked: a shared
    buffer with room for every pin's points of each ``PinLines`` given, in
    the order given, and a pipe.  The helper lays them out first
    (:meth:`fill`, in ``order``), writing each pin's into the buffer and then
    saying so; the planner's process takes a pin's points from there once
    the helper has said so (``PinLines.get_with_counts`` asks
    :meth:`points`), and otherwise builds them itself and marks them taken,
    so that the helper skips them.  The points are the same either way
    (``PinLines.build``'s); a helper that is slow or gone costs only time.

    Parameters
    ----------
    lines : sequence of PinLines
        Each is given this as its ``shared``.
    order : sequence of (int, int)
        ``(which of lines, pin)`` in the order the helper lays them out.
    """

    def __init__(self, lines, order):
        import mmap
        from multiprocessing.connection import Pipe

        self.lines = list(lines)
        pins = self.lines[0].space.pins
        sizes = np.array([pl.totals() for pl in self.lines], dtype=np.int64)
        self._at = np.concatenate([[0], np.cumsum(sizes.ravel())]).reshape(-1)  # (which * pins + pin) -> start
        self._buf = mmap.mmap(-1, 4 * max(int(self._at[-1]), 1))
        self._taken = mmap.mmap(-1, len(self.lines) * pins)  # 1: the planner's process built it itself
        self._pins, self._order = pins, [(int(i), int(p)) for i, p in order]
        self._ready, self._say = Pipe(duplex=False)
        self._done = set()
        for pl in self.lines:
            pl.shared = self

    def _key(self, pin_lines, p):
        return next(i for i, pl in enumerate(self.lines) if pl is pin_lines) * self._pins + int(p)

    def points(self, pin_lines, p):
        """Pin ``p``'s points of ``pin_lines`` (int32, flat) if the helper has laid them out, else None
        (and the helper is told to skip them)."""
        key = self._key(pin_lines, p)
        if key not in self._done and self._ready is not None:
            try:
                while self._ready.poll():
                    self._done.update(np.frombuffer(self._ready.recv_bytes(), dtype=np.int64).tolist())
            except (EOFError, OSError):  # the helper is gone: the rest is built here
                self._ready.close()
                self._ready = None
        if key in self._done:
            a, b = int(self._at[key]), int(self._at[key + 1])
            return np.frombuffer(self._buf, dtype=np.int32, count=b - a, offset=4 * a)
        self._taken[key] = 1
        return None

    def sent(self):
        """The planner's process is done with the writing end (the helper is forked)."""
        self._say.close()

    def fill(self):  # pragma: no cover - runs in the helper
        """Lay out the points (in the helper), each pin's unless the planner's process took it."""
        self._ready.close()
        for i, p in self._order:
            key = i * self._pins + p
            if self._taken[key]:
                continue
            flat = self.lines[i].build(p)[2]
            a = int(self._at[key])
            np.frombuffer(self._buf, dtype=np.int32, count=len(flat), offset=4 * a)[:] = flat
            self._say.send_bytes(np.array([key], dtype=np.int64).tobytes())
        self._say.close()
