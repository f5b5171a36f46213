"""Winding a plan by hand, step by step: where the maker is, what to say, and the saved position.

The maker winds at the frame and is told one step at a time: the pin to go
to (numbered as ``stringbot pins`` and ``stringbot template`` number them:
see :mod:`stringbot.motion.pins`), the way round it, progress and, once a few
steps are done, an ETA from the maker's own pace.  A colour plan says at the
first step of each thread which thread to cut (and tie off where) and which
colour to tie on at which pin.  Nothing here prints or reads keys: the command
line (``stringbot/cli/by_hand.py``) does, and hands in the clock.

State
-----
One :class:`HandWinding` owns the position: ``done``, the steps the maker has
done (0 .. ``total``); the step shown is ``done + 1``; ``done == total`` is
:attr:`Phase.FINISHED`.  :meth:`HandWinding.next`, :meth:`~HandWinding.back`
and :meth:`~HandWinding.go` change it, and each change is saved at once.

The saved position (``PLAN.by-hand``, JSON)
-------------------------------------------
Written whole after every step (temp file, fsync, rename:
:func:`stringbot._files.write_atomic`), beside the plan unless given::

    {"format": "stringbot-by-hand", "version": 1, "plan": "camera.json",
     "plan_sha256": "...", "steps": 1813, "done": 120, "next_pin": 57,
     "paces": [4.1, 3.8, ...], "t": 1733140000.0}

``plan_sha256`` is :meth:`Plan.sha256` (what would be wound): a position for
another plan is refused, naming ``--restart`` and ``--from-step``.
``paces`` are the seconds the last steps took (at most :data:`PACES_KEPT`, over
every session; a step shown longer than :data:`BREAK_S` was a break, one done
in less than :data:`MIN_PACE_S` skipped through: neither is kept); the ETA is
the median of the most recent :data:`PACE_WINDOW` times the steps left.
"""

import enum
import json
import math
import re
import statistics
import time
from dataclasses import dataclass, field

from .._files import check_not_same_file, check_ours, check_output_path, write_atomic
from ..errors import BadInput
from ..motion.pins import pin_list, thread_metres
from ..planner.colour.palette import describe_color

__all__ = ["FORMAT", "VERSION", "Phase", "HandStep", "HandProgress", "SavedPosition", "HandWinding",
           "position_path_for", "read_position", "check_position_path", "PACES_KEPT", "PACE_WINDOW",
           "ETA_AFTER", "BREAK_S", "MIN_PACE_S"]

FORMAT = "stringbot-by-hand"
VERSION = 1
#: paces kept in the position file (the most recent)
PACES_KEPT = 50
#: the ETA takes the median of this many most recent paces
PACE_WINDOW = 15
#: steps timed before an ETA is shown
ETA_AFTER = 3
#: a step shown longer than this (s) was a break, not the maker's pace
BREAK_S = 600.0
#: a step done quicker than this (s) was skipped through, not wound
MIN_PACE_S = 0.3
_SAY_WRAP = {"cw": "clockwise", "ccw": "counter-clockwise", "either": ""}


class Phase(enum.Enum):
    """Where a winding by hand stands."""

    WINDING = "winding"      # a step is shown, to be done
    FINISHED = "finished"    # every step is done


@dataclass(frozen=True)
class HandStep:
    """One step as the maker does it.

    Attributes
    ----------
    index : int
        From 0 (an index into the plan's ``sequence``).
    number : int
        From 1, as shown.
    pin : int
        The pin as the pin list and the template number it.
    plan_pin : int
        The plan's own index of it.
    wrap : {"cw", "ccw", "either"}
        The way round the pin, seen from the front.
    layer : int
        The thread (from 0) this step belongs to.
    color, color_name : str
        Its colour (``#rrggbb``) and name.
    tie_on : str or None
        At the first step of a thread: what to do before it (cut the old thread and tie it off, tie
        this one on), else None.
    next_pin : int or None
        The pin after this one on the same thread (None at its last step).
    thread_left : int
        Steps left on this thread, this one included.
    """

    index: int
    number: int
    pin: int
    plan_pin: int
    wrap: str
    layer: int
    color: str
    color_name: str
    tie_on: str | None
    next_pin: int | None
    thread_left: int


@dataclass(frozen=True)
class HandProgress:
    """Progress: ``done`` of ``total`` steps; the pace and ETA once :data:`ETA_AFTER` steps are timed.

    Attributes
    ----------
    done, total : int
    percent : float
    pace_s, eta_s : float or None
        The median seconds a step of the recent ones, and that times the steps left.
    layer, layers : int
        The thread shown (from 0) and how many the plan has.
    thread_left : int
        Steps left on the thread shown, the shown one included (0 when finished).
    thread_left_m : float or None
        Its thread still to wind, pin centre to pin centre, in metres (None without a frame size).
    """

    done: int
    total: int
    percent: float
    pace_s: float | None
    eta_s: float | None
    layer: int
    layers: int
    thread_left: int
    thread_left_m: float | None


@dataclass
class SavedPosition:
    """A position file's content (see the module's notes)."""

    plan: str
    plan_sha256: str
    steps: int
    done: int
    paces: list = field(default_factory=list)
    t: float = 0.0


def position_path_for(plan_path):
    """Where the position of ``plan_path`` is kept by default: beside it, ``PLAN.by-hand``."""
    return f"{plan_path}.by-hand"


def check_position_path(path, plan_path):
    """Check before any work that ``path`` may hold the position: a regular file or none, not the plan,
    not a file of another kind (a journal, a picture, a plan).

    Raises
    ------
    BadInput
    """
    check_output_path(path, what="position")
    check_not_same_file(path, plan_path, what="position", source_what="plan")
    check_ours(path, "by-hand", what="position", instead="give --position another file")


def _damaged(path, what):
    return BadInput(f"position file {str(path)!r} is damaged ({what}); expected the position that "
                    "`stringbot by-hand` wrote: remove it to start over, or give --position another file")


def read_position(path):
    """The position saved at ``path``, or None when there is none (no file, or an empty one).

    Raises
    ------
    BadInput
        A file that is not a position stringbot wrote, or a damaged one.
    """
    try:
        with open(path, "rb") as f:
            raw = f.read(1 << 20)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise BadInput(f"position file {str(path)!r} cannot be read: {exc.strerror or exc}") from None
    if not raw.strip():
        return None
    try:
        doc = json.loads(raw)
    except ValueError:
        doc = None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise BadInput(f"position file {str(path)!r} is not a by-hand position stringbot wrote; not using it: "
                       "give --position another file (or remove that file)")
    if doc.get("version") != VERSION:
        raise _damaged(path, f"version {doc.get('version')!r}; expected {VERSION}")
    steps, done, sha = doc.get("steps"), doc.get("done"), doc.get("plan_sha256")
    if not isinstance(sha, str) or len(sha) != 64:
        raise _damaged(path, "plan_sha256 is not a sha256")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise _damaged(path, f"steps {steps!r}")
    if isinstance(done, bool) or not isinstance(done, int) or not 0 <= done <= steps:
        raise _damaged(path, f"done {done!r}; expected 0..{steps}")
    paces = doc.get("paces", [])
    if not isinstance(paces, list) or not all(_is_pace(p) for p in paces):
        raise _damaged(path, "paces is not a list of seconds")
    t = doc.get("t", 0.0)
    return SavedPosition(plan=str(doc.get("plan", "")), plan_sha256=sha, steps=steps, done=done,
                         paces=[float(p) for p in paces][-PACES_KEPT:],
                         t=float(t) if _is_pace(t) else 0.0)


def _is_pace(v):
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) and v >= 0


def _steps(plan):
    """Every :class:`HandStep` of ``plan``, in winding order, and the pin list's header as a dict."""
    pl = pin_list(plan)
    rows = pl.rows
    starts = [a for a, *_ in pl.layers] or [0]
    ends = starts[1:] + [len(rows)]
    colors = list(plan.colors)
    steps = []
    for k, (a, b) in enumerate(zip(starts, ends)):
        name = describe_color(colors[k])
        if plan.is_mono:
            tie = f"tie the thread on at pin {rows[a][1]}"
        elif len(colors) == 1:                  # one thread, not black on white: say which
            tie = f"tie the {name} thread on at pin {rows[a][1]}"
        elif k == 0:
            tie = f"tie the {name} thread on at pin {rows[a][1]} (thread 1 of {len(colors)})"
        else:
            old = describe_color(colors[k - 1])
            tie = (f"cut the {old} thread and tie it off at pin {rows[a - 1][1]}; tie the {name} thread on "
                   f"at pin {rows[a][1]} (thread {k + 1} of {len(colors)})")
        for i in range(a, b):
            _step, pin, plan_pin, wrap = rows[i]
            steps.append(HandStep(index=i, number=i + 1, pin=pin, plan_pin=plan_pin, wrap=wrap, layer=k,
                                  color=colors[k], color_name=name, tie_on=tie if i == a else None,
                                  next_pin=rows[i + 1][1] if i + 1 < b else None, thread_left=b - i))
    return steps, dict(pl.header)


class HandWinding:
    """A plan wound by hand: the position (owned here), its saved copy, the pace.

    Parameters
    ----------
    plan : Plan
        A connected plan.
    plan_path : str
        How the position file names the plan.
    position_path : str
        Where the position is saved (:func:`position_path_for` by default; checked with
        :func:`check_position_path` before).
    size_mm : float, optional
        The frame's diameter (a square's side), for the metres of thread left.
    done : int
        The steps done already (0 .. the plan's steps).
    paces : sequence of float
        Seconds the earlier steps took (earlier sessions).
    """

    def __init__(self, plan, *, plan_path, position_path, size_mm=None, done=0, paces=()):
        self.plan = plan
        self.plan_path = str(plan_path)
        self.position_path = str(position_path)
        self.size_mm = size_mm
        self.sha256 = plan.sha256()
        self.steps, self.header = _steps(plan)
        self.total = len(self.steps)
        if not 0 <= done <= self.total:
            raise ValueError(f"done {done}; expected 0..{self.total}")
        self.done = done
        self.paces = [float(p) for p in paces][-PACES_KEPT:]
        self._shown_at = None

    @classmethod
    def open(cls, plan, *, plan_path, position_path=None, size_mm=None, restart=False, from_step=None):
        """The winding of ``plan`` where the maker stopped, or where asked; and how it began.

        Returns
        -------
        (HandWinding, str)
            ``how``: ``"new"`` (no position saved), ``"resumed"``, ``"restarted"`` (``restart``) or
            ``"from step"`` (``from_step``, from 1).  Nothing is written yet.

        Raises
        ------
        BadInput
            ``restart`` with ``from_step``; ``from_step`` outside 1..steps; a position for another plan
            (without ``restart`` or ``from_step``); a position file that is not ours or is damaged.
        """
        position_path = position_path or position_path_for(plan_path)
        if restart and from_step is not None:
            raise BadInput("--restart and --from-step both say where to start; give one of them")
        check_position_path(position_path, plan_path)
        saved = read_position(position_path)
        new = cls(plan, plan_path=plan_path, position_path=position_path, size_mm=size_mm)
        if from_step is not None and not 1 <= from_step <= new.total:
            raise BadInput(f"--from-step {from_step}; expected a step 1..{new.total} (the plan's steps)")
        same = saved is not None and saved.plan_sha256 == new.sha256 and saved.steps == new.total
        if saved is not None and not same and not restart and from_step is None:
            raise BadInput(f"position file {position_path!r} is for another plan (sha256 {saved.plan_sha256[:12]}, "
                           f"step {min(saved.done + 1, saved.steps)} of {saved.steps}), not this one (sha256 "
                           f"{new.sha256[:12]}, {new.total} steps); expected this plan's position: --restart "
                           "starts over (replacing it), --from-step N starts at step N")
        if same:
            new.paces = list(saved.paces)
        if restart:
            return new, "restarted"
        if from_step is not None:
            new.done = from_step - 1
            return new, "from step"
        if same:
            new.done = saved.done
            return new, "resumed"
        return new, "new"

    @property
    def phase(self):
        return Phase.FINISHED if self.done >= self.total else Phase.WINDING

    @property
    def current(self):
        """The :class:`HandStep` to do now (None when finished)."""
        return self.steps[self.done] if self.done < self.total else None

    @property
    def last(self):
        """The last step of the plan."""
        return self.steps[-1]

    def shown(self, now):
        """The maker sees the current step from ``now`` (a monotonic clock, s) on: its pace counts
        from here."""
        self._shown_at = now

    def next(self, now):
        """The shown step is done: time it, go to the next one, save.  False when finished already."""
        if self.phase is Phase.FINISHED:
            return False
        if self._shown_at is not None and MIN_PACE_S <= now - self._shown_at <= BREAK_S:
            self.paces = (self.paces + [round(now - self._shown_at, 3)])[-PACES_KEPT:]
        self.done += 1
        self._shown_at = now
        self.save()
        return True

    def back(self, now):
        """Back to the step before (to undo it), save.  False at the first step."""
        if self.done == 0:
            return False
        self.done -= 1
        self._shown_at = now
        self.save()
        return True

    def go(self, number, now):
        """To step ``number`` (from 1), save.

        Raises
        ------
        BadInput
            A step outside 1..total.
        """
        if isinstance(number, bool) or not isinstance(number, int) or not 1 <= number <= self.total:
            raise BadInput(f"step {number!r}; expected a step 1..{self.total}")
        self.done = number - 1
        self._shown_at = now
        self.save()

    def progress(self):
        """The :class:`HandProgress` now."""
        recent = self.paces[-PACE_WINDOW:]
        pace = statistics.median(recent) if len(recent) >= ETA_AFTER else None
        left = self.total - self.done
        step = self.current
        layer = step.layer if step is not None else self.last.layer
        metres = None
        if step is not None and self.size_mm:
            seq = self.plan.layers[layer].sequence
            offset = self.plan.layer_starts[layer]
            metres = thread_metres(self.plan, self.size_mm, seq[max(step.index - offset - 1, 0):])
        return HandProgress(done=self.done, total=self.total, percent=100.0 * self.done / self.total,
                            pace_s=pace, eta_s=pace * left if pace is not None else None, layer=layer,
                            layers=len(self.plan.colors), thread_left=step.thread_left if step else 0,
                            thread_left_m=metres)

    def utterance(self, step=None):
        """What to say for ``step`` (default: the current one; when finished, that it is done)."""
        step = self.current if step is None else step
        if step is None:
            return f"Done. All {self.total} steps. Tie the thread off at pin {self.last.pin}."
        wrap = _SAY_WRAP[step.wrap]
        wrap = f", {wrap}" if wrap else ""
        if step.tie_on is None:
            return f"pin {step.pin}{wrap}."
        tie = re.sub(r" \(#[0-9a-f]{6}\)", "", step.tie_on.split(" (thread")[0])   # colours by name
        return f"Change thread: {tie}{wrap}." if step.layer else f"{tie[0].upper()}{tie[1:]}{wrap}."

    def to_json(self, *, now=None):
        """The position file's text (see the module's notes)."""
        step = self.current
        doc = {"format": FORMAT, "version": VERSION, "plan": self.plan_path, "plan_sha256": self.sha256,
               "steps": self.total, "done": self.done, "next_pin": step.pin if step else None,
               "paces": self.paces, "t": round(time.time() if now is None else now, 3)}
        return json.dumps(doc) + "\n"

    def save(self):
        """Write the position, whole (temp file, fsync, rename)."""
        write_atomic(self.position_path, self.to_json(), what="position")
