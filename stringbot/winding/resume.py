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
from pathlib import Path

from ..errors import BadInput, MachineFailure
from ..links import open_link
from .approach import approach
from .locate import TOL, Found, _near, _point, _side, locate, start_point, tolerance  # noqa: F401
from .operator import Operator
from .recover import recover_gcode
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
    if not Path(job.journal_path).exists():
        hint = ("check the --journal path" if job.journal_given
                else "give --journal for one kept elsewhere")
        raise BadInput(f"no winding of this plan to report: journal {str(job.journal_path)!r} does not exist "
                       f"(a winding writes it when it starts; {hint})")
    state = read_journal(job.journal_path)
    job.header_check(state)
    h = state.header
    total = state.steps_total
    lines = [f"journal: {state.path}",
             f"plan: {h.get('plan')} (sha256 {str(h.get('plan_sha256'))[:16]}...), machine {h.get('machine')}",
             f"started: {_fmt_time(h.get('t'))}; last record: "
             f"{_fmt_time(h.get('t') if state.last_time is None else state.last_time)}"]
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
                link_options=None, jog=None, say=None, spool_change=None, ask_thread=None, hands=None,
                check=False, eyes=None):
    """Continue the winding of ``job`` from its journal (or restart at ``from_step``, from 1).

    ``head_side`` is the operator's statement (``--head-side``); ``confirm(question) -> bool``,
    ``choose(question, choices) -> choice`` and ``jog(prompt) -> str`` ask the operator, ``say``
    shows an instruction (None: nobody to ask, ``--yes``).  See :mod:`stringbot.winding.recover`.
    ``spool_change``, ``ask_thread``, ``hands``: a colour plan's spool changes, as for
    :func:`~stringbot.winding.session.wind_plan`; a resume after a stop for a spool change
    (``--yes``) is the operator's word that the thread is on.  ``eyes()``: a dry run's simulated
    operator looking at its machine (:class:`~stringbot.winding.operator.Operator`'s ``look``).
    A journal whose winding never moved the machine has nothing to resume: the winding starts
    afresh (``check``: with the settings check, as :func:`~stringbot.winding.session.wind_plan`).
    """
    if job.dry_run:
        raise BadInput("a dry run's simulated machine lives only as long as its command, so there is "
                       "nothing to resume; rehearse resuming with `stringbot simulate --pty PATH` "
                       "and --port PATH")
    if job.journal_given and not Path(job.journal_path).exists():
        raise BadInput(f"journal {str(job.journal_path)!r} does not exist; nothing to resume "
                       "(check the --journal path, or wind without --resume to start)")
    state = read_journal(job.journal_path)
    job.header_check(state)
    steps, machine = job.steps, job.machine
    if state.finished and from_step is None:
        raise BadInput(f"journal {str(state.path)!r} says the winding is finished; nothing to resume "
                       "(use --from-step N to wind steps again)")
    if from_step is not None and not 1 <= from_step <= len(steps):
        raise BadInput(f"--from-step is {from_step}; expected a step 1..{len(steps)}")
    operator = Operator(head_side=head_side, confirm=confirm, choose=choose, jog=jog, say=say, look=eyes)
    if from_step is None and not state.moved:
        # nothing moved since the journal began (a start refused, or stopped, before any motion)
        from .session import wind_plan
        return wind_plan(job, confirm=confirm, progress=progress, link_options=link_options, check=check,
                         spool_change=spool_change, ask_thread=ask_thread, hands=hands, operator=operator)
    s, m = _journal_point(state)
    if s < len(steps) and m >= len(steps[s].moves):
        s, m = s + 1, 0               # only the step's dwell was left: its moves are all done
    journal = Journal.reopen(job.journal_path, durable=not job.fresh_world)
    link = None
    try:
        link = open_link(job.url, machine, **(link_options or {}))
        winder = Winder(link, steps, machine, journal=journal, progress=progress, confirm=confirm)
        if not job.plan.is_mono:    # the journal says whose thread is on: only a new layer's is asked for
            from .layers import spool_stop_layer, threads_for, tied_layer
            ready = spool_stop_layer(_live_stop(state)) if from_step is None else None
            winder.threads = threads_for(job, journal, tied=tied_layer(state), ready=ready, confirm=confirm,
                                         spool_change=spool_change, ask_thread=ask_thread, hands=hands)
        winder.state = winder.state.CONNECTING
        with winder.stopping_on_ctrl_c("while reconnecting"):
            if hasattr(link, "reconnect"):
                found = recover_gcode(link, job, state, s, m, operator, journal, from_step)
            else:
                found = _servo_found(link, job, state, s, m, operator, journal, from_step)
        log.info("resume: %s; machine at ring %.3f, head %.3f", found.how, *found.here)
        s2, k2 = found.where
        if from_step is None:
            for i in range(state.next_step, s2):
                journal.done(i, steps[i].pin)   # executed, now known from the machine's position
            first_hook = found.approach or (s2 == 0 and k2 <= 1 and job.plan.is_mono)
            if s2 < len(steps) and not first_hook:      # (before the first hook: the tie-on, below)
                winder.ask(f"Resume at pin {steps[s2].pin} (step {s2 + 1} of {len(steps)}, move {k2 + 1})?")
        else:
            winder.ask(f"Restart from step {from_step} (pin {steps[s2].pin}); the steps from there on "
                       "are wound again. Go on?")
        if hasattr(link, "here"):
            # the next line names only the axis its move changes: from the planned start of the
            # move when the machine stands on that move's path, else from where it was found
            link.here = (start_point(steps, s2, machine) if k2 == 0 else _point(steps[s2].moves[k2 - 1])) \
                if found.on_path and s2 < len(steps) else tuple(found.here)
        journal.append({"kind": "resume", "from_step": s2, "from_move": k2, "position_lost": found.lost,
                        "how": found.how})
        if found.approach:                  # before the first hook: the first moves, again
            with winder.stopping("while moving to the start"):
                approach(link, machine, (steps[0].moves[0].ring_deg, machine["head.in_mm"]),
                         tolerance(link, machine), journal=journal, op=operator)
            link.here = start_point(steps, 0, machine)
        if from_step is None and s2 == 0 and k2 <= 1 and job.plan.is_mono:
            winder.ask(f"Tie the thread on at pin {steps[0].pin} if it is not (the first of {len(steps)} "
                       "pins; nothing is hooked yet), then go on?")
        if s2 >= len(steps):
            return winder.wind(len(steps))
        return winder.wind(s2, first_moves=steps[s2].moves[k2:])
    finally:
        if link is not None:
            link.close()
        journal.close()


def _servo_found(link, job, state, s, m, operator, journal, from_step):
    """The servo link's recovery, journaled and located like a G-code machine's."""
    machine, steps = job.machine, job.steps
    try:
        here, lost = _recover_servo(link, job, state, s, m, operator.choose)
        journal.append({"kind": "recover", "banner": False, "alarm": None,
                        "position_wiped": bool(lost), "position": [float(v) for v in here]})
        if from_step is not None:
            if _side(machine, here[1]) != "in":
                raise BadInput("the head is OUT; --from-step needs it IN: resume first, or move it in by hand")
            return Found(here, (from_step - 1, 0), lost, "the servos' positions", on_path=False)
        where = (locate(here, steps, s, m, machine, tolerance(link)) if s < len(steps)
                 else (len(steps), 0))
        if where is None:
            raise MachineFailure(f"the machine stands at ring {here[0]:.3f}, head {here[1]:.3f}, which "
                                 f"is not on the path the journal expects (step {s + 1}, move {m + 1}); "
                                 "check it, then restart with --from-step N")
        return Found(here, where, lost, "the servos' positions")
    except (BadInput, MachineFailure) as exc:
        try:
            journal.append({"kind": "refused", "error": str(exc), "moved": False})
        except OSError:
            log.warning("could not journal the refusal")
        raise


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
