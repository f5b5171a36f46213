"""The workshop's state and actions, apart from HTTP: plan, check, wind, resume, answer, stop.

:class:`Workshop` owns the plans folder's view (:class:`~.plans.Plans`), the simulators
(:class:`~.simulators.Simulators`) and the windings, one per machine at a time
(:class:`~.winding.Winding`); the web server (:mod:`.server`) only calls it.  Every action is a
``stringbot`` command (:mod:`.commands`), so each has its command line, which the page shows.
"""

import asyncio
import json
import logging
import time

from ..errors import BadInput
from .commands import Target, check_command, journal_for, parse_target, plan_command, record_for, tie_on_command, \
    wind_command
from .plans import Plans, machines_list
from .simulators import Simulators
from .winding import Conflict, Winding

__all__ = ["Workshop", "Busy", "Conflict", "run_command"]

log = logging.getLogger(__name__)

#: The longest a plan or a check may take before the page gives up on it.
COMMAND_TIMEOUT_S = 900.0


class Busy(Conflict):
    """The machine (or its port) is winding already: one winding per machine at a time."""


async def run_command(cmd, *, timeout=COMMAND_TIMEOUT_S):
    """Run ``cmd`` to its end: ``(exit code, stdout lines, stderr lines)``."""
    proc = await asyncio.create_subprocess_exec(*cmd.argv(), cwd=str(cmd.cwd), stdin=asyncio.subprocess.DEVNULL,
                                                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    try:
        out, err = await asyncio.wait_for(proc.communicate(), timeout)
    except asyncio.TimeoutError:
        proc.kill()
        await proc.wait()
        raise BadInput(f"{cmd.shown()} took more than {COMMAND_TIMEOUT_S:.0f} s; stopped") from None
    return proc.returncode, out.decode(errors="replace").splitlines(), err.decode(errors="replace").splitlines()


def _error_line(err, code):
    """The command line's one line (``stringbot: error: ...``), without its prefix."""
    lines = [x for x in err if x.startswith("stringbot:")]
    if not lines:
        return f"the command exited {code}: " + (err[-1] if err else "no message")
    line = lines[-1]
    return line.split(": error: ", 1)[1] if ": error: " in line else line.split(": ", 1)[-1]


class Workshop:
    """The plans folder, its simulators and its windings."""

    def __init__(self, folder):
        self.folder = folder
        self.plans = Plans(folder)
        self.sims = Simulators(folder)
        self.machines = machines_list()
        self.windings = {}              # machine name -> its current (or last) Winding
        self.plans_version = 0
        self._planning = asyncio.Lock()

    def start(self):
        self.sims.adopt([m["name"] for m in self.machines])

    async def close(self):
        """The workshop's end: each winding stopped the Ctrl-C way (journaled, resumable), then the simulators."""
        for w in self.windings.values():
            w.stop()
        deadline = time.monotonic() + 30.0
        while any(w.active for w in self.windings.values()) and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        await self.sims.stop_all()

    def _machine(self, name):
        name = str(name or "").strip()
        if name not in {m["name"] for m in self.machines}:
            raise BadInput(f"unknown machine {name!r}; expected one of: "
                           + ", ".join(m["name"] for m in self.machines))
        return name

    # ---- plan ------------------------------------------------------------------------------------
    async def plan(self, form, upload=None):
        """``stringbot plan`` from the page's form: ``upload`` (file name, bytes) or ``form['picture']``
        (a picture uploaded before).  Returns the plan's info, the command and what it printed."""
        new = False
        if upload is not None:
            picture, new = self.plans.store_picture(*upload)
        elif form.get("picture"):
            picture = self.plans.picture(form["picture"])
        else:
            raise BadInput("no picture; expected a picture file (PNG, JPEG, ...) to upload")
        try:
            cmd, name = plan_command(self.folder, form, picture)
        except BadInput:
            self._forget(picture, new)
            raise
        async with self._planning:      # one plan at a time: a plan takes both cores
            code, out, err = await run_command(cmd)
        if code != 0:
            self._forget(picture, new)
            raise BadInput(_error_line(err, code))
        self.plans_version += 1
        said = out + [x for x in err if x.startswith("stringbot: warning")]
        return {"plan": self.plans.info(name), "command": cmd.shown(), "said": said}

    def _forget(self, picture, new):
        """A picture uploaded for a plan that was refused goes again (it was never the user's file on disk)."""
        if new:
            try:
                (self.folder / picture).unlink()
            except OSError:
                pass

    # ---- check -----------------------------------------------------------------------------------
    async def check(self, form):
        """``stringbot machines check`` on the chosen machine and target."""
        machine, target = self._machine(form.get("machine")), parse_target(form.get("target"))
        self._refuse_busy(machine, target, form.get("port"))
        port = form.get("port") if target is Target.PORT else self.sims.port(machine)
        cmd = check_command(self.folder, machine=machine, target=target, port=port)
        code, out, err = await run_command(cmd, timeout=120.0)
        if code == 2:
            raise BadInput(_error_line(err, code))
        return {"command": cmd.shown(), "code": code, "agree": code == 0, "said": out + err}

    # ---- wind ------------------------------------------------------------------------------------
    def _refuse_busy(self, machine, target, port):
        w = self.windings.get(machine)
        if w is not None and w.active:
            raise Busy(f"machine {machine!r} is winding {w.plan_name!r} (step {w.snapshot()['done']} of {w.total}); "
                       "one winding per machine at a time: wait for it to end, or stop it")
        if target is Target.PORT:
            for other in self.windings.values():
                if other.active and other.target is Target.PORT and _port_of(other) == str(port):
                    raise Busy(f"port {port!r} is in use by the winding of {other.plan_name!r} on machine "
                               f"{other.machine!r}; one winding per port")

    async def wind(self, form):
        """Start (or, with ``form['resume']``, resume) a winding; returns its snapshot."""
        machine, target = self._machine(form.get("machine")), parse_target(form.get("target"))
        name = form.get("plan")
        plan = self.plans.plan(name)
        resume = str(form.get("resume", "")).lower() in ("1", "true", "on", "yes")
        port = str(form.get("port") or "").strip() or None
        self._refuse_busy(machine, target, port)
        faults = str(form.get("faults") or "").strip() or None
        realtime = str(form.get("realtime", "")).lower() in ("1", "true", "on", "yes")
        check = str(form.get("check", "on")).lower() not in ("0", "false", "off", "no")
        if target is Target.SIMULATOR:
            if not resume:
                self._refuse_unfinished(name, target)
                _check_faults(faults)           # before the simulator that serves now is stopped
                await self.sims.start(machine, faults=faults, realtime=realtime)
            elif self.sims.get(machine) is None:        # a resume finds a simulated machine that was switched off
                await self.sims.start(machine, realtime=realtime)
            await self.sims.wait_port(machine)
        cmd = wind_command(self.folder, plan_name=name, machine=machine, target=target, port=port, faults=faults,
                           realtime=realtime, resume=resume, check=check)
        layers = [(lay.color, first) for lay, first in zip(plan.layers, plan.layer_starts)]
        w = Winding(cmd, machine=machine, plan_name=name, target=target,
                    journal=self.folder / journal_for(name, target), sequence=plan.sequence, layers=layers,
                    resume=resume, on_end=self._ended)
        self.windings[machine] = w
        await w.start()
        return w.snapshot()

    def _refuse_unfinished(self, name, target):
        """A new simulated machine for a plan whose simulator journal is unfinished would lose the
        winding it can still resume: say so (the command line would refuse the start too)."""
        j = self.plans.journals(name, self.plans.plan(name)).get(target.value)
        if j and j.get("resumable"):
            raise BadInput(f"journal {j['path']!r} shows an unfinished winding ({j['done']} of {j['total']} steps "
                           "done); continue it with Resume (--resume), or wind a new plan")

    def _ended(self, w):
        """A winding ended: the record check of a simulated one; the plans list changed (journals)."""
        self.plans_version += 1
        if w.target is Target.SIMULATOR and w.code == 0:
            w.check = self.record_check(w.plan_name, w.machine)
        elif w.target is Target.DRY_RUN and w.code in (0, 1):
            w.check = self.record_check(w.plan_name, w.machine, target=Target.DRY_RUN)

    def record_check(self, name, machine, *, target=Target.SIMULATOR):
        """The simulated world's record against the plan: ``{"exact": bool, "text": ...}``."""
        from firmware_protocol.machine import load_machine

        from ..winding.session import Job, dry_run_problem

        rec = self.folder / record_for(name, machine, target)
        try:
            job = Job(self.plans.path(name), load_machine(machine), record=rec)
            problem = dry_run_problem(job)
            wraps = len(json.loads(rec.read_text(encoding="utf-8"))["wraps"])
        except (BadInput, OSError, ValueError, KeyError) as exc:
            return {"exact": False, "text": f"the record {rec.name!r} could not be checked: {exc}"}
        if problem:
            return {"exact": False, "text": problem}
        return {"exact": True, "text": f"the simulated machine wound the plan exactly: {wraps} wraps, the plan's "
                                       f"sequence pin for pin, no collision (record {rec.relative_to(self.folder)})"}

    def winding(self, machine):
        w = self.windings.get(self._machine(machine))
        if w is None:
            raise BadInput(f"machine {machine!r} has no winding in this workshop")
        return w

    async def answer(self, machine, form):
        """The page's answer to the winding's question (a spool change on the workshop's simulator:
        the thread is tied on there first, as ``stringbot simulate --tie-on`` does)."""
        w = self.winding(machine)
        try:
            ask_id = int(form.get("id"))
        except (TypeError, ValueError):
            raise BadInput(f"answer id {form.get('id')!r}; expected the question's number") from None
        value = form.get("value")
        q = w.question
        if q is not None and q.get("id") == ask_id and q["ask"] == "thread" and value is True \
                and w.target is Target.SIMULATOR:
            pin = w.next_pin()
            cmd = tie_on_command(self.folder, machine=w.machine, color=q["color"], pin=pin)
            code, out, err = await run_command(cmd, timeout=30.0)
            if code != 0:
                raise BadInput(_error_line(err, code))
            w.say(" ".join(out) + f"  ({cmd.shown()})")
        w.answer(ask_id, value)
        return w.snapshot()

    def stop(self, machine):
        w = self.winding(machine)
        if not w.stop():
            raise Conflict(f"the winding of {w.plan_name!r} on {machine!r} has ended already")
        return w.snapshot()

    # ---- what every page sees --------------------------------------------------------------------
    def snapshot(self):
        return {"windings": {m: w.snapshot() for m, w in self.windings.items()},
                "simulators": self.sims.snapshot(), "plans_version": self.plans_version}


def _check_faults(faults):
    """``--faults`` refused as ``stringbot simulate`` refuses it."""
    from firmware_protocol.faults import parse_faults

    try:
        parse_faults(faults)
    except ValueError as exc:
        raise BadInput(f"--faults {faults!r}: {exc}") from None


def _port_of(w):
    args = list(w.command.args)
    return args[args.index("--port") + 1] if "--port" in args else None
