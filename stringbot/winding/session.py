"""One ``stringbot wind`` run: files in, link opened, winder run, everything closed.

The command line calls :func:`wind_plan` with what the user typed, a
``confirm(question) -> bool`` for the operator (None with ``--yes``) and a
``progress(Progress)`` callback; nothing here prints.
"""

import logging
from pathlib import Path

from firmware_protocol.machine import load_machine

from .._files import check_ours, check_output_path
from ..errors import BadInput
from ..links import open_link, sim_url
from ..links.settings_check import require_agreement
from ..motion import hook_steps
from ..planner import read_plan
from .approach import approach
from .homing import check_before_homing
from .journal import Journal, journal_path_for, read_journal
from .locate import tolerance
from .loop import Winder
from .operator import Operator

__all__ = ["wind_plan", "Job", "load_job", "dry_run_problem", "UnfinishedJournal", "moved"]

log = logging.getLogger(__name__)


class Job:
    """The plan, the machine and the steps of a winding, and where its journal lives."""

    def __init__(self, plan_path, machine, *, port=None, record=None, journal=None, realtime=False,
                 faults=None):
        self.plan_path = Path(plan_path)
        self.plan = read_plan(plan_path)
        self.machine = machine
        self.steps = hook_steps(self.plan, machine)
        self.dry_run = port is None
        if port is not None and (record or faults or realtime):
            if not str(port).startswith("sim://"):
                raise BadInput("--record, --faults and --realtime are for the simulated machine; "
                               "leave out --port (or give a sim:// URL) to use them")
        # the simulator loads the very machine file given (a user's copy may keep a bundled
        # machine's name but not its geometry), so the dry run checks that file
        self.record = Path(record) if (record and port is None) else None
        if self.record is not None:
            _check_record_path(self.record, self.plan_path)
        self.url = port if port is not None else sim_url(_machine_ref(machine), record=record,
                                                          faults=faults, realtime=realtime)
        self.journal_path = Path(journal) if journal else journal_path_for(plan_path,
                                                                           dry_run=self.dry_run)
        self.journal_given = bool(journal)
        if _same_file(self.journal_path, self.plan_path):
            raise BadInput(f"--journal {str(self.journal_path)!r} is the plan itself; give the "
                           "journal its own file (default: beside the plan, PLAN.journal)")
        if self.record is not None and _same_file(self.record, self.journal_path):
            raise BadInput(f"--record {str(self.record)!r} is the journal's file too; give them "
                           "different files")

    @property
    def fresh_world(self):
        """A ``sim://`` port starts a new simulated machine: nothing from before is on it."""
        return str(self.url).startswith("sim://")

    def header_check(self, state):
        """Refuse a journal written for another plan or machine."""
        h = state.header
        if h.get("plan_sha256") != self.plan.sha256():
            raise BadInput(f"journal {str(state.path)!r} is for another plan (plan {h.get('plan')!r}, "
                           f"sha256 {str(h.get('plan_sha256'))[:12]}...); expected this plan's "
                           f"{self.plan.sha256()[:12]}...; give --journal for this plan's journal")
        if h.get("machine") != self.machine.name:
            raise BadInput(f"journal {str(state.path)!r} is for machine {h.get('machine')!r}, not "
                           f"{self.machine.name!r}; resume on the machine it was started on")
        if h.get("steps") != len(self.steps):
            raise BadInput(f"journal {str(state.path)!r} has {h.get('steps')} steps but the plan "
                           f"has {len(self.steps)}; is it this plan's journal?")


def _same_file(a, b):
    a, b = Path(a), Path(b)
    try:
        if a.exists() and b.exists():
            return a.samefile(b)
        return a.resolve() == b.resolve()
    except OSError:
        return False


def _check_record_path(record, plan_path):
    """Refuse a ``--record`` path that would overwrite something that is not a world record
    (the plan, or any other file), or that is in a folder that does not exist."""
    if _same_file(record, plan_path):
        raise BadInput(f"--record {str(record)!r} is the plan itself; give the world's record its "
                       "own file (e.g. record.json)")
    if record.is_dir():
        raise BadInput(f"--record {str(record)!r} is a folder; expected a file path")
    if not record.parent.is_dir():
        raise BadInput(f"record folder {str(record.parent)!r} does not exist; create it first "
                       f"(for --record {str(record)!r})")
    check_output_path(record, what="--record")     # a device, FIFO or socket is never replaced
    check_ours(record, "record", what="--record", instead="give a new file")


def _machine_ref(machine):
    """What the simulator's ``machine=`` option gets: the machine file's absolute path (its name
    only for a machine that was not read from a file)."""
    path = Path(machine.path) if machine.path else None
    if path is not None and path.is_file():
        return str(path.resolve())
    return machine.name


def load_job(plan_path, machine_name, **kw):
    return Job(plan_path, load_machine(machine_name), **kw)


class UnfinishedJournal(BadInput):
    """A fresh start over a journal whose winding moved the machine and did not finish: only a
    resume knows where it stands (the command line adds the exact resume command)."""


def moved(job):
    """The job's journal shows that the machine moved in a winding that did not finish (so a
    fresh start, which trusts the firmware's position, is not exact: a resume is)."""
    try:
        state = read_journal(job.journal_path)
    except BadInput:
        return False
    return state.moved and not state.finished


def _refuse_unfinished(job):
    """Refuse a fresh start over a journal whose winding moved the machine and did not finish."""
    path = job.journal_path
    if path.exists() and not job.fresh_world:
        try:
            state = read_journal(path)
        except BadInput:
            state = None
        if state is not None and state.moved and not state.finished:
            done = (f"{len(state.done)} of {state.steps_total} steps done" if state.done else
                    "no step done, but the machine moved (homing, or its first moves)")
            raise UnfinishedJournal(
                f"journal {str(path)!r} shows an unfinished winding ({done}); a new start would trust a "
                "position the machine may have lost when it stopped: continue it with --resume (or restart "
                "from step N with --from-step N)")


def _new_journal(job):
    return Journal.create(job.journal_path, plan_path=job.plan_path, plan_sha256=job.plan.sha256(),
                          machine=job.machine.name, steps=len(job.steps), durable=not job.fresh_world)


def wind_plan(job, *, confirm=None, progress=None, link_options=None, check=False, spool_change=None,
              ask_thread=None, hands=None, operator=None, eyes=None):
    """Wind ``job`` from its first step.

    ``operator`` (an :class:`~stringbot.winding.operator.Operator`; default: ``confirm`` alone,
    with ``eyes()`` -> ``(ring_deg, head_mm)`` a simulated operator's look at its machine)
    answers where the head stands before homing when the firmware cannot say
    (:mod:`stringbot.winding.homing`) and, at a terminal, jogs a head OUT away from a gap IN.

    ``check`` (``stringbot wind`` sets it unless ``--no-check``): first compare
    the firmware's settings with the machine file
    (:func:`stringbot.links.settings_check.require_agreement`); a machine that
    disagrees raises ``SettingsDisagree`` before anything moves.

    A colour plan's spool changes (:mod:`stringbot.winding.layers`): ``spool_change`` is
    ``"ask"``, ``"stop"`` or ``"continue"`` (default: ask when there is ``confirm``, else continue
    in a dry run and stop on a port); ``ask_thread(question, color) -> bool`` asks (default:
    ``confirm(question)``); ``hands(color, pin)`` ties a thread on in a simulated world.

    Returns
    -------
    WindResult

    Raises
    ------
    BadInput, MachineFailure, Interrupted
    """
    op = operator if operator is not None else Operator(confirm=confirm, look=eyes)
    _refuse_unfinished(job)
    # the start is recorded once the port is open; over an earlier winding's journal only once the
    # machine agrees too (a machine that disagrees leaves that journal as it was; with no journal
    # there, its refusal shows in --status)
    journal = link = None
    try:
        link = open_link(job.url, job.machine, **(link_options or {}))
        if not job.journal_path.exists():
            journal = _new_journal(job)
        if check:
            require_agreement(link, job.machine)
        if journal is None:
            journal = _new_journal(job)
        winder = Winder(link, job.steps, job.machine, journal=journal, progress=progress,
                        confirm=confirm)
        home = job.machine["controller.homing"] or bool(job.machine.values.get("controller.head_homing"))
        winder.start(home=home, before_homing=None if not hasattr(link, "jog") else
                     lambda: check_before_homing(link, job.machine, op, journal=journal))
        first = job.steps[0]
        # to the start first (the head IN, then the ring), so the thread is tied on where it begins
        with winder.stopping("while moving to the start"):
            approach(link, job.machine, (first.moves[0].ring_deg, job.machine["head.in_mm"]),
                     tolerance(link, job.machine), journal=journal, op=op)
        if job.plan.is_mono:
            winder.ask(f"Tie the thread on at pin {first.pin} (the first of {len(job.steps)} pins), "
                       "then go on?")
        else:                       # the thread's colour, and a spool change before each later layer
            from .layers import threads_for
            winder.threads = threads_for(job, journal, confirm=confirm, spool_change=spool_change,
                                         ask_thread=ask_thread, hands=hands)
        return winder.wind(0)
    finally:
        if link is not None:
            link.close()
        if journal is not None:
            journal.close()


def dry_run_problem(job):
    """After a finished dry run with ``--record``: what the simulated world saw that the plan did
    not ask for (collisions, crashes, or wraps that differ from the plan's sequence), as one line; None
    when the world wound the plan exactly (or there is no record to check)."""
    if not job.dry_run or job.record is None:
        return None
    import json
    try:
        rec = json.loads(job.record.read_text(encoding="utf-8"))
        wraps = [int(w["pin"]) for w in rec["wraps"]]
        collisions = list(rec["collisions"])
        crashes = list(rec.get("crashes", []))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return f"the dry run's record {str(job.record)!r} could not be read back ({exc}); " \
               "the winding is unchecked"
    seq = list(job.plan.sequence)
    problems = []
    if not job.plan.is_mono and wraps == seq:
        from .layers import layer_problems
        wrong = layer_problems(job.plan, rec["wraps"])
        if wrong:
            problems.append(wrong)
    if collisions:
        first = collisions[0]
        problems.append(f"{len(collisions)} collision(s) of the head with pins (first: "
                        f"{first.get('reason', '?')} at ring {first.get('ring_deg', '?')} deg)")
    if crashes:
        problems.append(f"{len(crashes)} crash(es) of the head against the end of its travel "
                        "(head.travel_min_mm / travel_max_mm)")
    if wraps != seq:
        at = next((i for i, (a, b) in enumerate(zip(wraps, seq)) if a != b), min(len(wraps), len(seq)))
        problems.append(f"the world wrapped {len(wraps)} pins for the plan's {len(seq)}, first "
                        f"differing at step {at + 1}")
    if not problems:
        return None
    return (f"dry run on machine file {job.machine.path or job.machine.name!r} is not the plan: "
            + "; ".join(problems) + f" (record {str(job.record)!r}); check the machine file "
            "(ring.pin0_angle_deg, head.in_mm/out_mm, ring geometry)")
