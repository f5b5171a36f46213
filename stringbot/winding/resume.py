"""``--resume``, ``--from-step`` and ``--status``: continue a winding exactly where it stopped.

Where the journal leaves the job
--------------------------------
The journal records every executed step, and every executed move that ends
with the head OUT (those decide which side of the pin circle the head is on);
a live host adds a ``stop`` record naming the move that was running.  So the
machine is known to stand somewhere on the path from the end of the last
recorded move, along the next move or two.

Finding the machine
-------------------
If the firmware kept its position (no banner on reconnect, no alarm, no reset
seen while winding), its position is located on that path: at a move's end
(that move was executed) or inside a move (re-issuing the move, an absolute
target, finishes the same straight path).  A machine still moving (the host
died, the firmware runs what it had) is waited for; one in feed hold is
flushed (soft reset once stopped; GRBL keeps its position).

If the firmware lost its position (reset, power loss), the head side comes
from the journal, from ``--head-side`` or from the operator.  A machine with
home switches takes the head IN through the gap it stands at (never across a
pin), homes with the head IN (the ring turns freely then), re-declares the
ring's turn count from the journal and goes back along the ring to the
journal's point.  A machine without switches is told where it is (G10 L20 /
G92) after the operator confirms it.  Then the modal state is restored and
the winding continues with the interrupted move.
"""

import datetime
import logging
import math

from ..errors import BadInput, MachineFailure
from ..links import open_link
from .locate import TOL, _near, _point, _side, locate, start_point, tolerance  # noqa: F401
from .journal import Journal, read_journal
from .loop import Winder

__all__ = ["resume_plan", "status_lines", "locate"]

log = logging.getLogger(__name__)

def _fmt_time(t):
    if t is None:
        return "?"
    return datetime.datetime.fromtimestamp(t).strftime("%Y-%m-%d %H:%M:%S")


def status_lines(job):
    """What ``--status`` prints: steps done, when, the last error."""
    state = read_journal(job.journal_path)
    job.header_check(state)
    h = state.header
    total = state.steps_total
    lines = [f"journal: {state.path}",
             f"plan: {h.get('plan')} (sha256 {str(h.get('plan_sha256'))[:16]}...), machine {h.get('machine')}",
             f"started: {_fmt_time(h.get('t'))}; last record: {_fmt_time(state.last_time)}"]
    nxt = state.next_step
    if state.finished:
        lines.append(f"finished: all {total} steps done")
    else:
        pin = job.steps[nxt].pin if nxt < len(job.steps) else None
        lines.append(f"steps done: {len(state.done)} of {total}; next: step {nxt + 1}"
                     + (f" (pin {pin})" if pin is not None else ""))
    if not job.plan.is_mono:
        from .layers import status_line
        lines.append(status_line(job.plan, state))
    if state.resumes:
        lines.append(f"resumed {len(state.resumes)} time(s)")
    stop = state.last_stop
    if stop is not None:
        lines.append(f"last stop: {stop.get('reason')} at {_fmt_time(stop.get('t'))}: {stop.get('error')}")
    if state.torn:
        lines.append("note: a torn last record (a crash while writing) was ignored")
    return lines


def _live_stop(state):
    """The journal's last stop record if nothing was wound after it (no later resume), else None."""
    stop = state.last_stop
    if stop is None or (state.resumes and stop.get("t", 0) < state.resumes[-1].get("t", 0)):
        return None
    return stop


def _journal_point(state):
    """(step, move) the journal leaves the job at, sharpened by a live host's stop record."""
    s, m = state.next_step, state.next_move
    stop = _live_stop(state)
    at = stop.get("at") if stop else None
    if at:
        cand = (int(at["step_index"]), int(at["move"]))
        if cand > (s, m):
            s, m = cand
    return s, m


def resume_plan(job, *, from_step=None, head_side=None, confirm=None, choose=None, progress=None,
                link_options=None):
    """Continue the winding of ``job`` from its journal (or restart at ``from_step``, from 1).

    ``confirm(question) -> bool`` and ``choose(question, choices) -> choice`` ask the
    operator (None: do not ask; ``--yes``).
    """
    if job.dry_run:
        raise BadInput("a dry run's simulated machine lives only as long as its command, so there is "
                       "nothing to resume; rehearse resuming with `stringbot simulate --pty PATH` "
                       "and --port PATH")
    state = read_journal(job.journal_path)
    job.header_check(state)
    steps, machine = job.steps, job.machine
    if state.finished and from_step is None:
        raise BadInput(f"journal {str(state.path)!r} says the winding is finished; nothing to resume "
                       "(use --from-step N to wind steps again)")
    if from_step is not None and not 1 <= from_step <= len(steps):
        raise BadInput(f"--from-step is {from_step}; expected a step 1..{len(steps)}")
    s, m = _journal_point(state)
    if s < len(steps) and m >= len(steps[s].moves):
        s, m = s + 1, 0               # only the step's dwell was left: its moves are all done
    journal = Journal.reopen(job.journal_path, durable=not job.fresh_world)
    link = None
    try:
        link = open_link(job.url, machine, **(link_options or {}))
        winder = Winder(link, steps, machine, journal=journal, progress=progress, confirm=confirm)
        if not job.plan.is_mono:    # the journal says whose thread is on: only a new layer's is asked for
            from .layers import Threads, tied_layer
            winder.threads = Threads(job, journal, tied=tied_layer(state), confirm=confirm)
        winder.state = winder.state.CONNECTING
        where = None
        with winder.stopping_on_ctrl_c("while reconnecting"):
            if hasattr(link, "reconnect"):
                here, lost, where = _recover_gcode(link, job, state, s, m, head_side, confirm, choose)
            else:
                here, lost = _recover_servo(link, job, state, s, m, choose)
        if where is None and from_step is None:
            where = (locate(here, steps, s, m, machine, tolerance(link)) if s < len(steps)
                     else (len(steps), 0))
            if where is None:
                raise MachineFailure(f"the machine stands at ring {here[0]:.3f}, head {here[1]:.3f}, which "
                                     f"is not on the path the journal expects (step {s + 1}, move {m + 1}); "
                                     "check it, then restart with --from-step N")
        if from_step is None:
            s2, k2 = where
            for i in range(state.next_step, s2):
                journal.done(i, steps[i].pin)   # executed, now known from the machine's position
            if s2 < len(steps):
                winder.ask(f"Resume at pin {steps[s2].pin} (step {s2 + 1} of {len(steps)}, move {k2 + 1})?")
        else:
            # after a fix by hand the machine may stand anywhere with the head IN: the
            # restarted step's first move is a ring turn with the head IN, safe from anywhere
            if _side(machine, here[1]) != "in":
                raise BadInput("the head is OUT; --from-step needs it IN: resume first, or move it in by hand")
            s2, k2 = from_step - 1, 0
            winder.ask(f"Restart from step {from_step} (pin {steps[s2].pin}); the steps from there on "
                       "are wound again. Go on?")
        journal.append({"kind": "resume", "from_step": s2, "from_move": k2, "position_lost": lost})
        if s2 >= len(steps):
            return winder.wind(len(steps))
        return winder.wind(s2, first_moves=steps[s2].moves[k2:])
    finally:
        if link is not None:
            link.close()
        journal.close()


def _recover_gcode(link, job, state, s, m, head_side, confirm, choose):
    """Reconnect a G-code machine and find where it stands; returns ((ring, head), position_lost)."""
    lost = link.reconnect().position_lost
    stop = state.last_stop
    if stop is not None and stop.get("position_lost") and not state_resumed_after(state, stop):
        lost = True
    here = None if lost else link.position()
    where = None
    if here is None:
        lost = True
        here, where = _lost_position(link, job, s, m, head_side, confirm, choose)
    link.restore_modal()
    return here, lost, where


def state_resumed_after(state, stop):
    return bool(state.resumes) and state.resumes[-1].get("t", 0) > stop.get("t", 0)


def _lost_position(link, job, s, m, head_side, confirm, choose):
    """The firmware lost its position: decide where the machine is and tell it (homing if it can)."""
    machine, steps = job.machine, job.steps
    if s >= len(steps):
        before = after = _point(steps[-1].moves[-1])
    else:
        before = _point(steps[s].moves[m - 1]) if m > 0 else start_point(steps, s, machine)
        after = _point(steps[s].moves[m])
    sides = {_side(machine, before[1]), _side(machine, after[1])}
    if len(sides) == 1:
        side = sides.pop()
    elif head_side is not None:
        side = head_side
    elif choose is not None:
        side = choose("The machine lost its position while the thread head was moving in or out. "
                      "Look at it: is the eyelet inside the pin circle (in) or outside (out)?", ["in", "out"])
    else:
        raise BadInput("the machine lost its position while the thread head was moving in or out; "
                       "look at it and give --head-side in or --head-side out")
    if _side(machine, before[1]) == side:
        here, point = before, (s, m)
    else:
        here, point = after, _next(steps, s, m + 1)     # the head move had finished
    pins = machine.pins
    gap = (here[0] - machine["ring.pin0_angle_deg"]) / machine.pitch_deg
    if confirm is not None and not confirm(
            f"The firmware lost its position. The journal puts the ring at {here[0]:.3f} deg (pin "
            f"position {gap % pins:.1f}) with the head {side.upper()}. Is that where it stands?"):
        raise BadInput("the machine is not where the journal says; move it there by hand "
                       "(or restart with --from-step N)")
    link.set_position(*here)
    if machine["controller.homing"]:
        head_in = machine["head.in_mm"]
        if side == "out":
            link.move_to(here[0], head_in, axis="head")       # back in through the gap it stands at
            here = (here[0], head_in)
            point = _after_point(steps, s, here)
        link.home()                                           # the head is IN: the ring turns freely
        home_ring = machine["controller.home_ring_deg"]
        home_head = machine["controller.home_head_mm"]
        home_head = head_in if home_head is None else home_head
        turns = round((here[0] - home_ring) / 360.0)
        link.set_position(home_ring + 360.0 * turns, home_head)
        if home_head != head_in:
            link.move_to(home_ring + 360.0 * turns, head_in, axis="head")
        link.move_to(here[0], head_in, axis="ring")
    return here, point


def _next(steps, s, k):
    """(step, move) after move ``k - 1`` of step ``s``, rolling over to the next step."""
    if s < len(steps) and k >= len(steps[s].moves):
        return (s + 1, 0)
    return (s, k)


def _after_point(steps, s, here):
    """The head came IN at ``here`` during step ``s``: through the approach gap (the hook is
    undone: go on from the move after the approach) or the far gap (the hook is done)."""
    moves = steps[s].moves
    for k in range(len(moves) - 1, -1, -1):
        if _near(_point(moves[k]), here):
            return _next(steps, s, k + 1)
    raise MachineFailure(f"the head came in at ring {here[0]:.3f}, which is neither gap of step {s + 1}; "
                         "check the machine, then restart with --from-step N")


def _recover_servo(link, job, state, s, m, choose=None):
    """Bring a servo link up after a stop; where the ring lost its turn count, restore it.

    The encoders are exact within a servo turn; only the ring's turn count goes with
    the power.  Where it went, the ring stands at ``reading + k * turn`` for some
    whole ``k``, somewhere between two points the journal knows:

    * the link saw the power go (its stop record says ``position_lost``): at its
      last reading with torque on, kept in the stop record;
    * the link failed otherwise (a pulled cable) and the power went later: between
      that reading and the target of the interrupted move (the servo went on);
    * the host died too (no stop record): between the interrupted move's start
      and its target.

    One candidate on that stretch is taken; several (a stretch longer than a servo
    turn) are put to the operator as the pins that would face the head, and
    without an operator the resume stops rather than guess.
    """
    steps, machine = job.steps, job.machine
    link.identify()
    here = link.prepare(home=False)
    here = tuple(link.position() if here is None else here)
    if not getattr(link, "position_lost", False):
        return here, False            # the servos kept power: their turn count is right
    if s < len(steps):
        start = _point(steps[s].moves[m - 1]) if m > 0 else start_point(steps, s, machine)
        target = _point(steps[s].moves[m]) if m < len(steps[s].moves) else start
    else:
        start = target = _point(steps[-1].moves[-1])
    stop = _live_stop(state)
    reading = stop.get("position") if stop else None
    if _valid_position(reading):
        start = (float(reading[0]), float(reading[1]))
        if stop.get("position_lost"):
            target = start
    turn = 360.0 / machine["controller.gear_ratio"]
    lo, hi = min(start[0], target[0]), max(start[0], target[0])
    tol = tolerance(link)[0]
    k0, k1 = math.floor((lo - here[0]) / turn) - 1, math.ceil((hi - here[0]) / turn) + 1
    candidates = [here[0] + k * turn for k in range(k0, k1 + 1) if lo - tol <= here[0] + k * turn <= hi + tol]
    if hi - lo < turn / 2 or len(candidates) <= 1:
        ring = candidates[0] if len(candidates) == 1 else start[0]  # else: the turns nearest start
    else:
        def facing(ring_deg):
            return round((ring_deg - machine["ring.pin0_angle_deg"]) / machine.pitch_deg) % machine.pins

        pins = [str(facing(c)) for c in candidates]
        if choose is None:
            if hasattr(link, "torque_off"):
                link.torque_off()     # as the power left it: the next resume sees the turn count lost
            raise MachineFailure(f"after the power loss the ring could be at any of {len(candidates)} servo "
                                 f"turns (pins {', '.join(pins)} facing the head); run --resume without "
                                 "--yes and say which pin faces the head", step=s, pin=steps[min(s, len(steps) - 1)].pin)
        question = (f"The servos lost power on a {hi - lo:.0f}-degree stretch of ring travel, longer than "
                    f"one servo turn ({turn:g} degrees of ring): the encoder cannot tell which turn the ring "
                    f"is on. Look at the ring: which of pins {', '.join(pins)} is at (or next to) the thread head?")
        ring = candidates[pins.index(str(choose(question, pins)))]
    return tuple(link.set_position(ring, here[1])), False


def _valid_position(position):
    return (isinstance(position, (list, tuple)) and len(position) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in position))
