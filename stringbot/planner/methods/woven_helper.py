"""The polish on two cores: its canvas drawn while the threads are chosen, and its pins revisited by turns.

The polish (:mod:`stringbot.planner.methods.polish`) is most of a default plan's
time.  On a machine with two cores (:func:`two_cores`):

* :class:`WovenHelper` forks a helper process before the threads are
  chosen.  The chooser sends it each chord as it is chosen, and the helper
  stamps the chord's footprint on the polish's fine canvas meanwhile; when
  the sequence is done it draws it from the footprints it already has and
  polishes it.
* For the polish, the helper forks a twin (:func:`twin`).  The pins are
  revisited in blocks of two (:func:`~stringbot.planner.methods.polish.polish_pins`),
  each block's proposals made before the block ahead of it is settled: the
  two processes take every other block, each making its next block's
  proposals while the other settles the block before, then taking in what
  that settling changed (the values, through shared buffers) and settling
  its own.  So both hold the same drawing after every block, and each
  settles only its own proposals.

Every footprint is what stamping it anywhere else gives, every change is
taken in as the values the other process computed, and every decision is
made on the same drawing in both processes, so the plan is the one a single
process makes, pin for pin (``tests/test_woven_helper.py``).
Anything that goes wrong in a helper costs only time: a twin that is gone
makes the helper fail, and a helper that fails or dies leaves the polish to
the planner's own process (:meth:`WovenHelper.finish` returns None).  The
helpers never report progress nor write to the terminal; they end with
``os._exit``.
"""

import logging
import os
import time

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["WovenHelper", "TwinDrawing", "Partner", "twin", "two_cores"]

#: chords the chooser sends at a time
BATCH = 64


def two_cores():
    """True where the polish uses helper processes: on Linux (where forking a process that has used
    numpy is safe) with two cores of ours; ``$STRINGBOT_PROCESSES`` ``1`` never, ``2`` always (where
    ``os.fork`` exists)."""
    import sys

    want = os.environ.get("STRINGBOT_PROCESSES", "").strip()
    if want not in ("", "1", "2"):
        from ...errors import BadInput

        raise BadInput(f"STRINGBOT_PROCESSES={want!r}; expected 1 (one process) or 2 (a helper and its twin), "
                       "or unset (two on Linux with two cores)")
    if not hasattr(os, "fork") or want == "1":
        return False
    if want == "2":
        return True
    if not sys.platform.startswith("linux"):
        return False
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return cores >= 2


def _fork(body):
    """Run ``body()`` in a forked child that ends with ``os._exit`` (0 when it returned); the pid."""
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child's coverage is not collected
        code = 1
        try:
            from ..progress import reporting

            with reporting(None):  # the terminal is the parent's
                body()
            code = 0
        except BaseException as exc:  # noqa: BLE001 - a helper only ever fails quietly
            log.debug("helper process failed: %r", exc)
        finally:
            os._exit(code)
    return pid


class Partner:
    """One side of a polish in two processes (:func:`~stringbot.planner.methods.polish.polish_pins`).

    The blocks of pins alternate between the sides: side 0 makes and settles
    blocks 0, 2, 4, ..., side 1 the others.  Each side makes its next
    block's proposals while the other settles the block before; then it
    takes in what that settling did to the drawing (:meth:`WovenCanvas.replay
    <stringbot.planner.methods.woven.WovenCanvas.replay>`: the values themselves,
    so both hold the same drawing), settles its own and hands that on.  The
    pipe carries the proposals and a few numbers; the drawing's changes go
    through ``buffers`` (:func:`buffers`: per side, one per pin of a block,
    shared), each written only once the other side has read the block before.
    """

    def __init__(self, conn, side, buffers, pid=None):
        self.conn, self.side, self.pid = conn, side, pid
        self._out, self._in = buffers[side], buffers[1 - side]

    def run(self, blocks, make, settle, replay):
        """Make and settle this side's blocks, replay the other's; returns how many pins were
        rerouted (both sides')."""
        n, rerouted = len(blocks), 0
        mine = range(self.side, n, 2)
        for j in mine:
            proposals = [make(k) for k in blocks[j]]  # against the drawing before block j - 1 is settled
            if j >= 1:
                rerouted += self._take(replay)
            sent = []
            for proposal, buf in zip(proposals, self._out):
                made, change = settle(proposal)
                rerouted += made
                sent.append((proposal, made, None if change is None else _pack(buf, change)))
            self.conn.send(sent)
        if (mine[-1] + 1 if len(mine) else 0) < n:
            rerouted += self._take(replay)
        return rerouted

    def sync(self):
        """Wait until the other side has come here too (between rounds of :func:`polish_rounds
        <stringbot.planner.methods.polish.polish_rounds>`: it has read every change this side sent, so
        the buffers may be written again)."""
        self.conn.send(("sync",))
        if self.conn.recv() != ("sync",):  # EOFError: the other side is gone
            raise RuntimeError("polish: the partners are out of step")

    def _take(self, replay):
        made_here = 0
        for (proposal, made, sizes), buf in zip(self.conn.recv(), self._in):  # EOFError: the other side is gone
            replay(proposal, made, None if sizes is None else _unpack(buf, sizes))
            made_here += made
        return made_here

    def close(self):
        self.conn.close()
        if self.pid is not None:
            os.waitpid(self.pid, 0)
            self.pid = None


def buffers(canvas, block):
    """The shared buffers two :class:`Partner` s hand the drawing's changes over in (made before the
    fork): per side, ``block`` of them, each with room for the error's blurred slope and four chords'
    footprints."""
    import mmap

    chord = canvas.max_samples + 64  # fine pixels of a chord, at most (with room)
    size = 8 * canvas.P * canvas.P + 4 * chord * (8 + 4 + 2 + 4) + 64
    return [[mmap.mmap(-1, size) for _ in range(block)] for _side in range(2)]


_LAYOUT = (np.float64, np.float64, np.int32, np.uint16, np.int32)  # G, d, flat, sf (counts), cu


def _pack(buf, change):
    """Write a change (``((flat, sf, cu, d), G, E)``) into ``buf``; returns what :func:`_unpack` takes."""
    (flat, sf, cu, d), G, E = change
    at = 0
    for arr, dtype in zip((G, d, flat, sf, cu), _LAYOUT):
        view = np.frombuffer(buf, dtype=dtype, count=len(arr), offset=at)
        view[:] = arr
        at = (at + view.nbytes + 7) & ~7  # each array on 8 bytes
    return len(G), len(cu), len(flat), float(E)


def _unpack(buf, sizes):
    nG, nc, nf, E = sizes
    out, at = [], 0
    for n, dtype in zip((nG, nc, nf, nf, nc), _LAYOUT):
        view = np.frombuffer(buf, dtype=dtype, count=n, offset=at)
        out.append(view)
        at = (at + view.nbytes + 7) & ~7  # each array on 8 bytes
    G, d, flat, sf, cu = out
    return (flat, sf, cu, d), G, E


def twin(canvas, seq, order, pin_lines, *, rounds=1, after=None):
    """Fork a twin that polishes every other block of pins with :func:`~stringbot.planner.methods.polish.polish_pins`,
    ``rounds`` times (:func:`~stringbot.planner.methods.polish.polish_rounds`; then calls ``after(canvas, seq)``, the drawing and the sequence polished, and ends); returns this side's
    :class:`Partner`."""
    from multiprocessing.connection import Pipe

    from .polish import BLOCK, polish_rounds

    here, there = Pipe()
    shared = buffers(canvas, BLOCK)

    def body():  # pragma: no cover - runs in the child
        here.close()
        polish_rounds(canvas, seq, order, pin_lines, rounds=rounds, partner=Partner(there, 1, shared))
        there.close()
        if after is not None:
            after(canvas, seq)

    pid = _fork(body)
    there.close()
    return Partner(here, 0, shared, pid)


class TwinDrawing:
    """The preview of a polished plan, drawn by the twin and the helper once the plan is polished.

    Made in the planner's process before the helper is forked (a shared
    buffer and a pipe the two say "done" on); the twin draws the top half of
    the rows (:data:`HALVES` ``[0]``), the helper the bottom half, after it
    has sent the plan back (the reference rendering draws a band of rows as
    those rows of the whole).  Called as a plan's
    ``woven_drawings(size, board, thread)``: the preview
    (:func:`~stringbot.planner.model.render.preview_drawing`: uint8, ``size`` px,
    black thread on white) once both halves are in, or None (another size,
    or a half not drawn: the caller draws it); :meth:`png` the same as PNG
    bytes.

    Parameters
    ----------
    size : int
        The preview's side.
    model : ThreadModel
    """

    def __init__(self, size, model):
        import mmap
        from multiprocessing.connection import Pipe

        self.size, self.model = int(size), model
        self.halves = ((0, self.size // 2), (self.size // 2, self.size))  # the twin's rows, the helper's
        self._buf = mmap.mmap(-1, self.size * self.size)
        self._done, self._say = Pipe(duplex=False)
        self._img = self._png = None
        self._pid = None

    def make(self, canvas, seq, half):  # pragma: no cover - runs in the twin and the helper
        """Draw rows ``halves[half]`` of the polished sequence ``seq`` (the same in both) and say so."""
        from ..model.render import PREVIEW_SAMPLES, woven_image

        r0, r1 = self.halves[half]
        img = woven_image(list(zip(seq[:-1], seq[1:])), canvas.pin_xy, size=self.size,
                          thread_fraction=self.model.fraction, samples=PREVIEW_SAMPLES, rows=(r0, r1))
        self._buf[r0 * self.size:r1 * self.size] = img.tobytes()
        self._say.send_bytes(str(half).encode())  # a few bytes: one write, never mixed with the other's
        self._say.close()

    def sent(self):
        """This process is done with the writing end (it is forked already, or has drawn its half)."""
        self._say.close()

    def adopt(self, pid):
        """Wait for process ``pid`` (the helper, which waits for the twin) once the drawing is in."""
        self._pid = pid

    def _take(self, warn=True):
        """Take the drawing in, once: wait for both halves (or the end of both processes)."""
        if self._done is not None:
            got = set()
            try:
                while len(got) < len(self.halves):
                    got.add(int(self._done.recv_bytes()))
                self._img = np.frombuffer(self._buf, dtype=np.uint8).reshape(self.size, self.size).copy()
            except (EOFError, OSError, ValueError):
                if warn:
                    log.warning("polish: the helper processes did not draw the preview; drawing it here")
            self._done.close()
            self._done = None

    def close(self, *, wait=True, warn=True):
        """Take the drawing in (if it comes) and reap the helper (``wait``: until it has ended)."""
        self._take(warn)
        if self._pid is not None:
            pid, _ = os.waitpid(self._pid, 0 if wait else os.WNOHANG)
            if pid:
                self._pid = None

    def __del__(self):
        try:
            self.close(wait=False, warn=False)  # a helper still ending is left to end on its own
        except Exception:  # noqa: BLE001 - at exit nothing is left to tell
            pass

    def __call__(self, size, board, thread):
        if (int(size), board, thread) != (self.size, 255, 0):
            return None
        self._take()  # the helper is reaped later: its process takes a moment to end
        return self._img

    def png(self, size, board, thread):
        """The drawing as PNG bytes (:func:`~stringbot.planner.model.render.png_bytes` of it), or None."""
        img = self(size, board, thread)
        if img is not None and self._png is None:
            from ..model.render import png_bytes

            self._png = png_bytes(img)
        return self._png if img is not None else None


class WovenHelper:
    """A helper process that holds the polish's canvas, drawing chords while they are chosen.

    Parameters
    ----------
    make_canvas : callable
        ``make_canvas() -> WovenCanvas``, called in the helper.
    space : ChordSpace
        The pins (the helper lays out the polish's chord points while it waits for chords).
    drawing : TwinDrawing, optional
        The preview the twin and the helper draw, half each (then the polish's canvas is not sent back).
    patience : int
        How many of the last chords chosen an automatic run may still cut back
        (:data:`~stringbot.planner.methods.residual.PATIENCE`): the helper draws those before them
        while it waits.
    points : SharedPoints, optional
        The chooser's chord points, which the helper lays out first
        (:class:`~stringbot.planner.methods.shared_points.SharedPoints`).
    """

    def __init__(self, make_canvas, space, *, patience, drawing=None, points=None):
        from multiprocessing.connection import Pipe

        self._conn, child = Pipe()
        self._pending = []
        self.failed = False
        self.drawing = drawing

        def serve():  # pragma: no cover - runs in the child
            self._conn.close()
            if points is not None:
                points.fill()
            _serve(child, make_canvas, space, drawing, patience)

        self.pid = _fork(serve)
        child.close()
        if drawing is not None:
            drawing.sent()
        if points is not None:
            points.sent()

    def _send(self, msg):
        if not self.failed:
            try:
                self._conn.send(msg)
            except OSError:
                self.failed = True

    def add(self, chord):
        """A chord chosen (a pair of pins); sent on in batches of :data:`BATCH`."""
        self._pending.append(chord)
        if len(self._pending) >= BATCH:
            self._flush()

    def _flush(self):
        if self._pending:
            self._send(("chords", np.asarray(self._pending, dtype=np.int32).reshape(-1, 2)))
            self._pending = []

    def finish(self, seq, budget, passes=0, deletes=0, rounds=1):
        """Polish ``seq`` in the helper (``rounds`` of reroutes, ``passes`` of inserts and deletes, then ``deletes`` passes of
        deletes, after it, there alone).

        Returns
        -------
        (seq, stats) as :func:`~stringbot.planner.methods.polish.polish_plan`, or None when the helper failed.
        """
        self._flush()
        self._send(("polish", [int(p) for p in seq], int(budget), time.perf_counter(), int(passes), int(deletes),
                    int(rounds)))
        out = None
        try:
            if not self.failed:
                msg = self._conn.recv()
                if msg[0] == "done":
                    _, seq1, stats = msg
                    out = seq1, stats
        except (EOFError, OSError):
            pass
        finally:
            if out is not None and self.drawing is not None:
                # the helper waits for the twin to draw the preview: it is waited for with the drawing
                self._conn.close()
                self.drawing.adopt(self.pid)
                self.pid = None
            self.close()
        if out is None:
            log.warning("polish: the helper process failed; polishing here")
        return out

    def close(self):
        """End the helper (it ends itself when the pipe closes)."""
        if self.pid is not None:
            self._conn.close()
            os.waitpid(self.pid, 0)
            self.pid = None


def _serve(conn, make_canvas, space, drawing, patience):  # pragma: no cover - runs in the child
    """The helper: stamp chords as they come, and in between lay out the polish's chord points and
    find the drawn chords' grid pixels; polish on ``("polish", seq, budget, sent, passes, deletes, rounds)``."""
    from .polish import polish_lines, polish_plan

    canvas = make_canvas()
    lines = polish_lines(space, canvas)
    chosen, drawn = [], 0  # chords chosen so far, and how many of them are drawn on the fine canvas

    def idle_work():  # while no chords come: the polish's chord points, then the drawn chords' grid pixels
        for a in range(space.pins):
            yield lambda a=a: canvas.row(lines, a)
        done = 0
        while True:
            if done < drawn:
                yield lambda c=chosen[done]: canvas.footprint(*c)
                done += 1
            else:
                yield None

    idle = idle_work()
    while True:
        try:
            while not conn.poll():
                step = next(idle)
                if step is None:
                    break
                step()
            msg = conn.recv()
        except EOFError:
            return
        if msg[0] == "chords":
            for a, b in msg[1].tolist():
                canvas.stamped(a, b)
                chosen.append((a, b))
            # a chord more than patience back is in the plan (an automatic run is cut back by fewer):
            # drawn now, in the plan's order, as a fresh build would
            upto = max(drawn, len(chosen) - patience)
            canvas.draw(chosen[drawn:upto])
            drawn = upto
        elif msg[0] == "polish":
            _, seq, budget, sent, passes, deletes, rounds = msg
            t = time.perf_counter()
            final = list(zip(seq[:-1], seq[1:]))
            if final[:drawn] == chosen[:drawn]:
                canvas.draw(final[drawn:])
                canvas.finish()
            else:  # the sequence changed after it was chosen (refined): drawn afresh
                canvas.build(final)
            t1 = time.perf_counter()
            twins = []

            def partner(*args, **kw):
                mate = twin(*args, **kw, after=None if drawing is None else lambda c, s: drawing.make(c, s, 0))
                twins.append(mate.pid)
                mate.pid = None  # the twin may go on drawing the preview: waited for at the end
                return mate

            try:
                seq, stats = polish_plan(canvas, seq, space, budget=budget, rounds=rounds, passes=passes,
                                         deletes=deletes, partner=partner)
            except BaseException:
                for pid in twins:  # gone or going (an interrupt reaches the twin too)
                    os.waitpid(pid, 0)
                raise
            stats = dict(stats, behind_seconds=round(t - sent, 3), canvas_seconds=round(t1 - t, 3),
                         pins_seconds=round(time.perf_counter() - t1, 3), drawn_early=drawn)
            conn.send(("done", seq, stats))
            if drawing is not None:  # the other half of the preview, while the twin draws its own
                drawing.make(canvas, seq, 1)
            for pid in twins:
                os.waitpid(pid, 0)
            return
