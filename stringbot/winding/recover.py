"""Where a G-code machine stands after a stop, and telling it so: the heart of ``--resume``.

The journal leaves the job at (step ``s``, move ``m``): move ``m`` was running or
about to.  Every hooking move is one axis only, so the journal knows the ring
exactly when move ``m`` is a head move, and the head's side exactly when it is
a ring move -- never both.  What the firmware can say is tried first, then what
was measured, then switches, and only then the operator:

1. **The firmware kept its position** (no restart; or a restart that kept it --
   GRBL's soft reset keeps ``MPos`` and raises ``ALARM:3``): its position,
   head axis included, is located on the journal's path within one step.
   Where it is not, the firmware and the journal disagree: that is asked, even
   under ``--yes`` (then refused), never guessed.
2. **The position is gone** (``MPos`` reads 0 after a restart, or an earlier
   attempt learned so):

   * a stop record holding a position measured at rest (the held position
     after Ctrl-C, the reported one after a failed check) is the truth -- a
     board that reboots when its port opens (an Uno) takes this path on every
     resume;
   * ``controller.homing``: home; the head homes first, through the gap the
     ring stands at (a head move was running: the ring is known), or from IN
     (a ring move with the head IN); a pitch turn with the head OUT homes the
     ring alone with the head OUT, turns it to the hook's far gap and brings
     the head IN there;
   * ``controller.head_homing`` (a head switch only): a head move was running,
     so the ring is known: the head homes alone through its gap;
   * otherwise the operator: ``--head-side`` (a statement after looking) when
     only the head's side is unknown; the guided way to a reference
     (:mod:`stringbot.winding.guide`) when the ring was turning.  ``--yes``
     alone never answers.

Before the first hook (a stop while a start homed, or in its first moves: the
journal's ``homing`` and ``approach`` records, with no step move since) the path
is the start's own: homing again (it began from a position checked safe), the
first moves made again from a position found on them, or -- the position lost
without switches -- the operator, as above; then the start goes on as a new one
would (:attr:`Found.approach`).

Every attempt journals what it learned (``recover``) before it asks or refuses,
every declaration (``declared``) and every refusal (``refused``, and whether
anything moved), so that the next attempt starts from what is known and no
sequence of refusals leaves the machine where no command can get it back.
"""

import logging

from ..errors import BadInput, Interrupted, MachineFailure
from ..motion.safety import gap_offset_deg
from .locate import Found, _near, _on_segment, _point, continue_point, locate, side_of, start_point, tolerance

__all__ = ["recover_gcode", "Situation"]

log = logging.getLogger(__name__)


class Situation:
    """What the journal knows of the interrupted move ``m`` of step ``s``."""

    def __init__(self, job, s, m, state=None):
        steps, machine = job.steps, job.machine
        self.steps, self.machine, self.s, self.m = steps, machine, s, m
        # before the first step's moves: homing, or the first moves (the journal's own records)
        self.phase = state.start_phase((s, m)) if state is not None else None
        first = state.approach if self.phase == "approach" else None
        self.jogged = first is not None and first.get("to") is None     # the operator was jogging
        if first is not None and _valid(first.get("from")):
            self.before = tuple(first["from"])
            self.after = tuple(first["to"]) if _valid(first.get("to")) else self.before
        elif s >= len(steps):
            self.before = self.after = _point(steps[-1].moves[-1])
        elif self.phase is not None:
            self.before = self.after = start_point(steps, 0, machine)
        else:
            moves = steps[s].moves
            self.before = _point(moves[m - 1]) if m > 0 else start_point(steps, s, machine)
            self.after = _point(moves[m])
        self.ring_known = abs(self.before[0] - self.after[0]) < 1e-9
        sides = {side_of(machine, self.before[1]), side_of(machine, self.after[1])}
        self.side = sides.pop() if len(sides) == 1 else None      # None: a head move crossing the circle

    @property
    def approach(self):
        """Index of step ``s``'s approach move (its last four: approach, OUT, pitch, IN)."""
        return len(self.steps[self.s].moves) - 4 if self.s < len(self.steps) else 0

    @property
    def pin(self):
        return self.steps[min(self.s, len(self.steps) - 1)].pin

    def gap_text(self, ring_deg):
        gap, _ = gap_offset_deg(self.machine, ring_deg)
        return f"the gap between pins {gap} and {(gap + 1) % self.machine.pins}"

    def doing(self):
        """What the machine was doing, in words."""
        if self.s >= len(self.steps):
            return "after the last pin"
        if self.phase == "homing":
            return f"homing (before the first pin, {self.pin})"
        if self.phase == "approach":
            what = "turning the ring" if not self.ring_known else "moving the head" if self.side is None else "standing"
            return f"{what} to the start (before the first pin, {self.pin})"
        what = ("turning the ring" if not self.ring_known else
                "moving the head" if self.side is None else "standing")
        return f"{what} (pin {self.pin}, step {self.s + 1}, move {self.m + 1})"


def _epoch_facts(state):
    """From the records since the last resume: (stop, wiped earlier, moved since, declared since)."""
    stop, wiped, moved, declared = None, False, False, None
    for rec in state.epoch:
        kind = rec.get("kind")
        if kind == "stop":
            stop = rec
        elif kind == "recover" and rec.get("position_wiped"):
            wiped, declared = True, None
        elif kind == "declared":
            wiped, moved, declared = False, False, rec
        elif kind == "refused" and rec.get("moved"):
            moved = True
    return stop, wiped, moved, declared


def _valid(position):
    return (isinstance(position, (list, tuple)) and len(position) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in position))


class GcodeRecovery:
    """One resume attempt on a G-code machine (see the module's notes)."""

    def __init__(self, link, job, state, s, m, operator, journal, from_step=None):
        self.link, self.job, self.state, self.op, self.journal = link, job, state, operator, journal
        self.machine, self.steps = job.machine, job.steps
        self.sit = Situation(job, s, m, state)
        self.from_step = from_step
        self.moved = False

    # ---- journal ---------------------------------------------------------------------------
    def declare(self, ring, head, how):
        back = self.link.set_position(ring, head)
        self.journal.append({"kind": "declared", "position": [float(ring), float(head)], "how": how})
        log.info("declared ring %.3f, head %.3f (%s); the machine reads back %s", ring, head, how, back)
        return (float(ring), float(head))

    # ---- the attempt -----------------------------------------------------------------------
    def run(self):
        link = self.link
        seen = link.reconnect()
        stop, wiped_before, moved_before, declared = _epoch_facts(self.state)
        restarted = seen.position_lost or bool(stop and stop.get("position_lost"))
        zeros = seen.mpos is not None and all(abs(v) < 1e-9 for v in seen.mpos)
        wiped = (restarted and zeros) or wiped_before
        here_fw = None
        if not wiped and seen.mpos is not None:
            here_fw = link.position()
        self.journal.append({"kind": "recover", **seen.as_record(), "position_wiped": wiped,
                             "position": [float(v) for v in here_fw] if here_fw else None})
        link.restore_modal()
        if self.sit.phase is not None and self.from_step is None:
            if self.sit.jogged or moved_before:
                return self.guided("the machine was jogged at the start (before the first pin) and the host "
                                   "does not know where it stands")
            if self.sit.phase == "homing":
                return self.home_again(here_fw)
        if not wiped:
            if here_fw is None:
                raise MachineFailure("the machine reports no position; check the port and the machine")
            if moved_before and self.from_step is None:
                # jogged by an earlier attempt and not declared: the firmware's position is right,
                # but the journal's path no longer describes the thread
                return self.guided("an earlier resume attempt moved the machine without finishing")
            return self.kept(here_fw, restarted)
        return self.lost(stop if not moved_before else None, moved_before)

    # ---- 1. the firmware kept its position ---------------------------------------------------
    def kept(self, here, restarted):
        sit, machine = self.sit, self.machine
        how = "the firmware's position" + (", kept through its reset" if restarted else "")
        side = side_of(machine, here[1])
        if self.op.head_side is not None and self.op.head_side != side:
            raise BadInput(f"--head-side {self.op.head_side} contradicts the machine's own report: its head "
                           f"stands at {here[1]:.3f} mm, {side.upper()}; look again (leave out --head-side)")
        if self.from_step is not None:
            if side != "in":
                raise BadInput("the head is OUT; --from-step needs it IN: resume first, or move it in by hand")
            return Found(here, (self.from_step - 1, 0), restarted, how, on_path=False)
        if sit.s >= len(self.steps):
            return Found(here, (len(self.steps), 0), restarted, how)
        if sit.phase == "approach":             # on the first moves' path: they are made again from here
            tol = tolerance(self.link, machine)
            if _near(here, sit.before, tol) or _near(here, sit.after, tol) or \
                    _on_segment(here, sit.before, sit.after, tol):
                return Found(here, (0, 0), restarted, how, on_path=False)
        where = None if sit.phase else locate(here, self.steps, sit.s, sit.m, machine,
                                              tolerance(self.link, machine))
        if where is not None:
            return Found(here, where, restarted, how)
        return self.disagree(f"the machine reports ring {here[0]:.3f}, head {here[1]:.3f}, which is not on the "
                             f"path the journal expects ({sit.doing()}: from ring {sit.before[0]:.3f}, head "
                             f"{sit.before[1]:.3f} to ring {sit.after[0]:.3f}, head {sit.after[1]:.3f})")

    def disagree(self, why):
        """The firmware and the journal disagree: the operator decides, never ``--yes``."""
        if self.op.jog is not None and self.op.confirm is not None and self.op.confirm(
                f"{why[0].upper()}{why[1:]}. Be guided to a reference you can check (the head IN, "
                f"pin {self.sit.pin} at the station), so that the winding can go on?"):
            return self.guided(why)
        if self.op.present:
            raise MachineFailure(f"{why}; stopped without moving: check the machine, then resume again")
        raise MachineFailure(f"{why}; run this --resume in a terminal, without --yes, to be guided back to a "
                             "reference (the head IN, a pin at the station), or fix the machine by hand and "
                             "restart with --from-step N")

    # ---- 2. the position is gone --------------------------------------------------------------
    def lost(self, stop, moved_before):
        sit, machine = self.sit, self.machine
        measured = stop.get("position") if stop else None
        if _valid(measured) and not moved_before:
            here = self.declare(measured[0], measured[1], "measured at rest when the winding stopped")
            found = self.kept(here, True)
            found.how = "the position measured when the winding stopped (the firmware had restarted)"
            return found
        if machine["controller.homing"] and not moved_before:
            return self.rehome()
        if self.from_step is not None:
            return self.guided("the firmware lost its position; --from-step needs a known one")
        if moved_before:
            return self.guided("an earlier resume attempt moved the machine after it lost its position")
        if self.op.head_side is not None and sit.side is not None and self.op.head_side != sit.side:
            raise BadInput(f"--head-side {self.op.head_side} contradicts the journal: the head was "
                           f"{sit.side.upper()} while {sit.doing()}; look again, or run without --yes to be "
                           "guided to a reference")
        if not sit.ring_known:
            return self.guided(f"the firmware lost its position while {sit.doing()}: the ring may have stopped "
                               "anywhere on that turn")
        if machine.values.get("controller.head_homing") and sit.side is None:
            return self.home_head()
        return self.side_from_operator()

    def side_from_operator(self):
        """The ring is known (it was not turning); the operator says where the head is."""
        sit, machine, op = self.sit, self.machine, self.op
        ring = sit.before[0]
        side = op.head_side
        where_ring = f"ring {ring:.3f} deg ({sit.gap_text(ring)} at the station)"
        if side is not None and sit.side is not None and side != sit.side:
            raise BadInput(f"--head-side {side} contradicts the journal: the head was {sit.side.upper()} while "
                           f"{sit.doing()}; look again, or run without --yes to be guided to a reference")
        if side is None and op.choose is not None:
            choices = ["in", "out"] + (["guide"] if op.jog is not None else [])
            side = op.choose(f"The firmware lost its position while {sit.doing()}; the journal puts the "
                             f"{where_ring}. Look at the thread head: is it fully IN (at its inner "
                             "position, the eyelet inside the pin circle) or fully OUT (at its outer position)?"
                             + (" If it stopped part way, answer guide: a head declared IN or OUT where it "
                                "is not would offset every later head move (guide: jog to a reference)"
                                if op.jog is not None else ""), choices)
            if side == "guide":
                return self.guided("the operator asked to be guided")
        if side is None:
            raise BadInput(f"the firmware lost its position while {sit.doing()} and this machine has no switch "
                           f"to find it: look at the machine (the journal puts the {where_ring}) and give "
                           "--head-side in or --head-side out if the head stands fully IN or fully OUT; "
                           "if it stopped part way, run without --yes to be guided")
        head = machine["head.in_mm"] if side == "in" else machine["head.out_mm"]
        if op.head_side is None and op.confirm is not None and not op.confirm(
                f"Declare the ring at {ring:.3f} deg ({sit.gap_text(ring)} at the station) with the head "
                f"{side.upper()}?"):
            raise BadInput("the machine is not where the journal says; resume again to be guided to a reference")
        here = self.declare(ring, head, f"the journal's ring, the operator's head side ({side})")
        found = self.kept(here, True)
        found.how = f"the journal's ring and the head side you gave ({side})"
        return found

    def home_head(self):
        """``head_homing``: a head move was running, so the ring stands at a known gap: the head
        homes alone, through that gap."""
        sit, machine, link = self.sit, self.machine, self.link
        self.moved = True
        link.home(["head"])
        home_head = _home_head(machine)
        here = self.declare(sit.before[0], home_head, "the journal's ring; the head homed")
        if abs(home_head - machine["head.in_mm"]) > 1e-9:
            link.move_to(here[0], machine["head.in_mm"], axis="head")
            here = (here[0], machine["head.in_mm"])
        hooked = sit.m == sit.approach + 3              # the head was coming IN at the far gap
        where = continue_point(sit, hooked=hooked)
        return Found(here, where, True, "the head homed through the gap the ring stood at", on_path=False)

    def home_again(self, here_fw):
        """A stop while a start homed from a checked position (the journal's ``homing``): the head
        went IN at the checked gap, or was IN, so homing again is safe; then the first moves."""
        machine, link = self.machine, self.link
        if machine["controller.homing"]:
            return self.rehome()
        start = self.state.homing.get("from")
        ring = here_fw[0] if here_fw is not None else (start[0] if _valid(start) else None)
        if ring is None:
            return self.guided(f"the firmware lost its position while {self.sit.doing()}, and the ring's was "
                               "never known")
        self.moved = True
        link.home(["head"])                 # a head switch only: the ring did not move
        here = self.declare(ring, _home_head(machine), "the ring as before homing; the head homed")
        return Found(here, (0, 0), True, "the head homed again", on_path=False)

    def rehome(self):
        """``homing``: home without taking the head across the pin circle away from a gap."""
        sit, machine, link = self.sit, self.machine, self.link
        if self.from_step is not None:
            # the machine may have been moved by hand since the stop: homing starts only from a
            # position someone checked (the operator, or a dry run's simulated one)
            from .homing import check_before_homing
            check_before_homing(link, machine, self.op, vouched=False)
        home_ring = machine["controller.home_ring_deg"]
        h_in, h_out = machine["head.in_mm"], machine["head.out_mm"]
        turns = round((sit.before[0] - home_ring) / 360.0)
        if self.from_step is None and sit.side == "out" and not sit.ring_known:
            # the pitch turn, head OUT: the ring homes alone (the head stays OUT), then turns to the
            # hook's far gap and the head comes IN there: the pin is hooked
            self.moved = True
            try:
                link.home(["ring"])
            except MachineFailure as exc:
                log.warning("homing the ring alone was refused: %s", exc)
                return self.guided(f"the firmware lost its position while {sit.doing()} (the head OUT) and "
                                   "it cannot home the ring alone")
            self.declare(home_ring + 360.0 * turns, h_out, "the ring homed alone, the head OUT")
            link.move_to(sit.after[0], h_out, axis="ring")
            link.move_to(sit.after[0], h_in, axis="head")
            here = (sit.after[0], h_in)
            return Found(here, continue_point(sit, hooked=True), True,
                         "the ring homed alone with the head OUT, then the hook finished at its far gap",
                         on_path=False)
        self.moved = True
        link.home()                                   # the head first (from IN, or through its gap)
        here = self.declare(home_ring + 360.0 * turns, _home_head(machine), "homed")
        if abs(here[1] - h_in) > 1e-9:
            link.move_to(here[0], h_in, axis="head")
            here = (here[0], h_in)
        if self.from_step is not None:
            return Found(here, (self.from_step - 1, 0), True, "homed", on_path=False)
        hooked = sit.side is None and sit.m == sit.approach + 3
        return Found(here, continue_point(sit, hooked=hooked), True, "homed", on_path=False)

    def guided(self, why):
        from .guide import guide_to_reference
        if self.op.jog is None:
            raise BadInput(f"{why}: only you can say where it stands now.  Run the same command without "
                           "--yes, in a terminal: it guides you to a reference you can check (the head IN, "
                           f"pin {self.sit.pin} at the station) with jog commands")
        self.moved = True
        return guide_to_reference(self, why)


def _home_head(machine):
    h = machine["controller.home_head_mm"]
    return machine["head.in_mm"] if h is None else h


def recover_gcode(link, job, state, s, m, operator, journal, from_step=None):
    """One resume attempt's recovery; journals ``refused`` (and whether it moved anything) on failure."""
    rec = GcodeRecovery(link, job, state, s, m, operator, journal, from_step)
    try:
        found = rec.run()
        if rec.sit.phase is not None and from_step is None and tuple(found.where) == (0, 0):
            found.approach = True       # before the first hook: the first moves are made again
        return found
    except (BadInput, MachineFailure, Interrupted) as exc:
        try:
            journal.append({"kind": "refused", "error": str(exc), "moved": rec.moved})
        except OSError:
            log.warning("could not journal the refusal")
        raise
