"""The colour plan's order: threads laid in runs, a colour coming back, within a spool-change budget.

The planner lays threads in winding order on the :class:`~.model.Piece`, each
new one on top.  A *run* is one continuous thread of one colour (a layer of
the plan file); between two runs the maker changes the spool.  At most
``spool_changes + 1`` runs.

1. *The draft* (:func:`free_runs`, on a coarser grid, its thread twice as
   wide for half the lines): every colour is its own thread at its own pin,
   and each step lays the (colour, chord) that lowers the error most, a colour once chosen going on for at least
   ``min_run`` chords: the order the picture asks for, with as many spool
   changes as that takes (40-70 on the test pictures).
2. *The schedule* (:func:`fit_schedule`): the draft's runs merged down to the
   budget, the shortest first: a run goes, its lines to the nearest run of
   its colour, so that each colour keeps its share of the lines and roughly
   its place in the order; the last run of a colour goes only when there are
   more colours than runs.  The schedule does not end with the thread of most
   contrast with the board (its last run joins its run before, if it has one).
   Scaled to the plan's lines, a run under ``min_run`` joins its colour's nearest
   run, else the one before it (:func:`no_short_runs`).
3. *The plan* (:func:`follow`, on the working grid): each run of the schedule
   in turn, for its share of the lines.  A run starts at an end of the chord
   of its colour that lowers the error most, anywhere on the frame, and goes
   on from pin to pin, each time the chord from the current pin that lowers
   the error most; it ends early when none does (its lines pass to the next
   run).

A chord is laid at most once in a colour, never one spanning fewer than a
thirtieth of the pins (the rim's short chords); the last ``min_loop`` pins are
not gone back to.  When the draft already keeps to the budget and was drawn on
the working grid, it is the plan.
"""

import logging

import numpy as np

from ..progress import report

log = logging.getLogger(__name__)

__all__ = ["Runner", "free_runs", "fit_schedule", "no_short_runs", "follow", "plan_runs", "draft_schedule", "RUN_DEFAULTS"]

#: ``late``: the darkest thread's runs that start in the last this share of the lines join its run before
#: (:func:`fit_schedule`)
RUN_DEFAULTS = {"spool_changes": 8, "min_run": 100, "min_loop": 3, "late": 0.7}
#: chords spanning fewer than ``pins // SHORT`` pins are never laid (10 of 300: the rim's dense short chords;
#: coffee's plain luminance SSIM 0.349 -> 0.360 at Prem-Dharshan's line count, the colour error alike)
SHORT = 30
#: the draft looks at the other colours every this many chords of a run (once it has ``min_run``)
LOOK = 5


class _Fans:
    """The chords from each pin with their pixels, built lazily."""

    def __init__(self, space, indptr, indices, weights):
        self.space, self.indptr, self.indices, self.weights = space, indptr, indices, weights
        self.cache = {}

    def get(self, p):
        fan = self.cache.get(p)
        if fan is None:
            row = self.space.index[p]
            others = np.flatnonzero(row >= 0)
            chords = row[others]
            lo = self.indptr[chords]
            counts = self.indptr[chords + 1] - lo
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            pos = np.arange(counts.sum()) - np.repeat(starts, counts) + np.repeat(lo, counts)
            fan = self.cache[p] = (others, chords, self.indices[pos].astype(np.int64), starts,
                                   self.weights[chords].astype(np.float64))
        return fan


class _Everywhere:
    """Every chord's gain for a colour, judged by every ``stride``-th of its pixels, the best few again by all."""

    def __init__(self, indptr, indices, weights, *, stride=4, exact=48):
        counts = np.diff(indptr)
        thin = (counts + stride - 1) // stride
        self.indptr = np.concatenate([[0], np.cumsum(thin)])
        pos = (np.arange(int(thin.sum())) - np.repeat(self.indptr[:-1], thin)) * stride + np.repeat(indptr[:-1], thin)
        self.indices = indices[pos]
        self.scale = weights * (counts / thin)
        self.full = (indptr, indices, weights)
        self.exact = int(exact)

    def best(self, S, skip):
        """``(gain, chord)`` of the chord that lowers the error most (``skip``: chords not to take)."""
        g = self.scale * np.add.reduceat(S.take(self.indices), self.indptr[:-1])
        g[skip] = np.inf
        top = np.argpartition(g, self.exact)[:self.exact] if len(g) > self.exact else np.arange(len(g))
        indptr, indices, weights = self.full
        exact = [(float(weights[c] * S[indices[indptr[c]:indptr[c + 1]]].sum()), int(c)) for c in top
                 if np.isfinite(g[c])]
        return min(exact) if exact else (np.inf, -1)


class Runner:
    """Threads laid on a :class:`~.model.Piece` by the chords of a working grid.

    Parameters
    ----------
    space : ChordSpace
    indptr, indices : ndarray
        Chord pixels on the piece's grid (:func:`stringbot.planner.model.chords.chord_pixels`).
    weights : ndarray of float, shape (m,)
        Each chord's share of its pixels (:func:`~.model.chord_weights_px`).
    piece : Piece
        Updated in place.
    min_loop : int
        A thread never goes back to its last ``min_loop`` pins.
    fine : (indptr, indices, weights), optional
        The chords on the piece's fine grid (a piece with :class:`~.model.Fine`): the steps judge them
        there, by ``piece.S2``.
    like : Runner, optional
        A runner on the same chords (and fine chords): its fans are shared (``--face``'s plans laid in turn).
    """

    def __init__(self, space, indptr, indices, weights, piece, *, min_loop=RUN_DEFAULTS["min_loop"], fine=None,
                 like=None):
        self.space, self.piece, self.min_loop = space, piece, int(min_loop)
        if like is not None:        # the same chords: their fans (built as they are needed) shared
            self.fans, self.everywhere = like.fans, like.everywhere
        else:
            self.fans = _Fans(space, indptr, indices, weights) if fine is None else _Fans(space, *fine)
            self.everywhere = _Everywhere(indptr, indices, weights)
        self.laid = np.zeros((piece.K, space.m), dtype=bool)   # a chord is laid once in a colour
        self.laid |= space.span < space.pins // SHORT
        self.lines = 0

    def fresh(self):
        """A runner on the same grid over the bare board."""
        out = Runner.__new__(Runner)
        out.space, out.piece, out.min_loop = self.space, self.piece.fresh(), self.min_loop
        out.fans, out.everywhere = self.fans, self.everywhere
        out.laid = np.zeros_like(self.laid)
        out.laid |= self.space.span < self.space.pins // SHORT
        out.lines = 0
        return out

    def anywhere(self, k):
        """``(gain, chord)``: colour ``k``'s chord that lowers the error most, anywhere."""
        return self.everywhere.best(self.piece.S[k], self.laid[k])

    def step(self, k, seq):
        """``(gain, next pin, chord)``: colour ``k``'s best chord from the end of ``seq``."""
        others, chords, pix, starts, w = self.fans.get(seq[-1])
        S = self.piece.S if self.piece.fine is None else self.piece.S2      # judged on the fine grid if any
        gain = w * np.add.reduceat(S[k].take(pix), starts)
        gain[self.laid[k, chords]] = np.inf
        for q in seq[-self.min_loop:]:
            i = int(np.searchsorted(others, q))
            if i < len(others) and others[i] == q:
                gain[i] = np.inf
        i = int(np.argmin(gain))
        return float(gain[i]), int(others[i]), int(chords[i])

    def lay(self, k, seq, nxt, chord):
        """Lay colour ``k``'s thread from the end of ``seq`` to pin ``nxt`` (chord ``chord``) on top."""
        self.piece.lay(k, seq[-1], nxt)
        self.laid[k, chord] = True
        seq.append(nxt)
        self.lines += 1

    def start(self, k, first=None):
        """A new thread of colour ``k``: ``[pin]``, at an end of its best chord (or at ``first``)."""
        if first is not None:
            return [int(first)]
        gain, chord = self.anywhere(k)
        return None if chord < 0 or gain >= 0 else [int(self.space.ends[chord, 0])]


def free_runs(runner, lines, *, min_run=RUN_DEFAULTS["min_run"]):
    """The draft: each step the best (colour, chord), every colour its own thread (see the module notes).

    Returns
    -------
    list of (int, list of int)
        ``(colour, pins)`` of each run, in winding order (a colour's runs continue one thread).
    """
    K = runner.piece.K
    seqs = [runner.start(k) for k in range(K)]
    runs, active = [], -1
    while runner.lines < lines:
        move = None
        n = len(runs[-1][1]) - 1 if runs else 0
        if active >= 0 and (n < min_run or n % LOOK):     # the other colours are looked at every LOOK chords
            move = runner.step(active, seqs[active]) + (active,)
        if move is None or move[0] >= 0:
            options = [runner.step(k, seqs[k]) + (k,) for k in range(K) if seqs[k] is not None]
            move = min(options, default=None)
        if move is None or move[0] >= 0:
            break
        gain, nxt, chord, k = move
        if k != active:
            runs.append((k, [seqs[k][-1]]))
            active = k
        runner.lay(k, seqs[k], nxt, chord)
        runs[-1][1].append(nxt)
        if runner.lines % 200 == 0:
            report("colour (draft)", runner.lines, lines)
    return runs


def fit_schedule(runs, most, *, darkest=None, late=0.0):
    """The draft's runs ``[(colour, pins)]`` merged down to at most ``most`` runs: ``[(colour, lines)]``.

    The shortest run goes first, its lines to the nearest run of its colour; a
    colour's last run goes only while there are more colours than runs.  Then
    the schedule does not end with colour ``darkest`` (the thread of most
    contrast with the board) while it has a run before: its last run's lines
    go to that run (the last run lies on top of all; a dark one there is the
    plan's most visible texture).  Before that, ``darkest``'s runs that start
    in the last ``late`` share of the lines join its last run before them
    (0: none): the dark thread's detail lies under the others' late runs
    rather than coming back over them (the plain luminance SSIM with 8 and 32
    changes, docs/planner.md, "Colour").
    """
    sched = _tidy([[k, len(seq) - 1] for k, seq in runs])
    while len(sched) > most:
        colours = [k for k, _ in sched]
        movable = [j for j in range(len(sched)) if colours.count(colours[j]) > 1] or list(range(len(sched)))
        i = min(movable, key=lambda j: (sched[j][1], j))
        n = sched[i][1]
        same = _nearest_of_colour(sched, i)
        if same is not None:
            sched[same][1] += n
        del sched[i]
        sched = _tidy(sched)
    if darkest is not None and late > 0:        # the darkest's runs in the last ``late`` of the lines join back
        starts = np.cumsum([0] + [n for _, n in sched])
        before = None
        for run, at in zip(sched, starts):
            if run[0] == darkest and at < (1.0 - late) * starts[-1]:
                before = run
            elif run[0] == darkest and before is not None:
                before[1] += run[1]
                run[1] = 0
        sched = _tidy(sched)
    while sched and sched[-1][0] == darkest and sum(k == darkest for k, _ in sched) > 1:
        k, n = sched.pop()
        sched[max(j for j in range(len(sched)) if sched[j][0] == k)][1] += n
        sched = _tidy(sched)
    return [(k, n) for k, n in sched]


def no_short_runs(schedule, least):
    """``schedule`` ``[(colour, lines)]`` without runs of fewer than ``least`` lines (a spool change for a
    few lines: the draft's last run, cut where its budget ended): the shortest goes first, its lines to
    the nearest run of its colour, else to the run before it (after it, for the first); one run stays."""
    sched = _tidy([[k, n] for k, n in schedule])
    while len(sched) > 1 and min(n for _, n in sched) < least:
        i = min(range(len(sched)), key=lambda j: (sched[j][1], j))
        n = sched[i][1]
        same = _nearest_of_colour(sched, i)
        sched[same if same is not None else (i - 1 if i > 0 else 1)][1] += n
        del sched[i]
        sched = _tidy(sched)
    return [(k, n) for k, n in sched]


def _nearest_of_colour(sched, i):
    """The index of the run of ``sched[i]``'s colour nearest to run ``i`` (the earlier of two), or None."""
    same = [j for j in range(len(sched)) if j != i and sched[j][0] == sched[i][0]]
    return min(same, key=lambda j: (abs(j - i), j)) if same else None


def _tidy(sched):
    """Neighbouring runs of one colour joined, empty ones left out."""
    out = []
    for k, n in sched:
        if out and out[-1][0] == k:
            out[-1][1] += n
        elif n > 0:
            out.append([k, n])
    return out


def follow(runner, lines, schedule, *, first=None):
    """Lay the runs of ``schedule`` ``[(colour, lines)]`` in turn (see the module notes); returns the runs."""
    runs, spare = [], 0
    for j, (k, n) in enumerate(schedule):
        want = n + spare if j < len(schedule) - 1 else lines - runner.lines
        seq = runner.start(k, first if not runs else None)
        if seq is None:
            spare = want
            continue
        while len(seq) - 1 < want and runner.lines < lines:
            gain, nxt, chord = runner.step(k, seq)
            if gain >= 0:
                break
            runner.lay(k, seq, nxt, chord)
            if runner.lines % 200 == 0:
                report("colour", runner.lines, lines)
        spare = want - (len(seq) - 1)
        if len(seq) >= 2:
            runs.append((k, seq))
    return runs


def plan_runs(draft, final, lines, *, spool_changes=RUN_DEFAULTS["spool_changes"], min_run=RUN_DEFAULTS["min_run"],
              first=None, thicker=1.0, late=RUN_DEFAULTS["late"]):
    """Lay up to ``lines`` threads in at most ``spool_changes + 1`` runs (see the module notes).

    Parameters
    ----------
    draft : Runner
        On the draft's grid (it is used up).
    final : callable or None
        ``final()``: a fresh :class:`Runner` on the working grid; None: the draft's grid is the working grid.
    lines : int
        Line budget over all runs.
    spool_changes : int
    min_run : int
        Fewest chords of a run of the draft before another colour may take over (at most a ``2 K``-th of
        ``lines``, ``K`` the colours).
    first : int, optional
        The first run's first pin (None: where its best chord is).
    thicker : float
        The draft's thread is this many times the plan's: it lays ``lines / thicker`` chords.
    late : float
        The darkest thread's runs in the last this share of the lines join its run before (:func:`fit_schedule`).

    Returns
    -------
    list of (int, list of int)
        ``(colour index, pin sequence)`` of each run, in winding order.
    """
    runs, schedule = draft_schedule(draft, lines, spool_changes=spool_changes, min_run=min_run, thicker=thicker,
                                    late=late)
    if final is None and first is None and len(runs) <= spool_changes + 1:
        return runs
    return follow(final() if final is not None else draft.fresh(), lines, schedule, first=first)


def draft_schedule(draft, lines, *, spool_changes=RUN_DEFAULTS["spool_changes"], min_run=RUN_DEFAULTS["min_run"],
                   thicker=1.0, late=RUN_DEFAULTS["late"]):
    """``(the draft's runs, the schedule [(colour, lines)])`` of :func:`plan_runs` (its parameters)."""
    # the draft's thread may be ``thicker``: each of its chords then stands for as many of the plan's; a short
    # plan's draft still gives every colour a run (its runs at most a (2 K)-th of the lines)
    short = max(1, int(round(lines / thicker)))
    runs = free_runs(draft, short, min_run=max(1, min(int(round(min_run / thicker)), short // (2 * draft.piece.K))))
    lum = draft.piece.lum                   # the board's luminance, then each thread's
    schedule = fit_schedule(runs, spool_changes + 1, darkest=int(np.argmax(np.abs(lum[1:] - lum[0]))), late=late)
    total = sum(n for _, n in schedule)
    if total:
        schedule = [(k, max(1, int(round(n * lines / total)))) for k, n in schedule]
        schedule = no_short_runs(schedule, min(int(min_run), lines // (2 * draft.piece.K)))
    log.info("colour: the draft's %d runs fitted to %d: %s", len(runs), len(schedule), schedule)
    return runs, schedule
