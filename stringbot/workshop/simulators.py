"""The workshop's simulated machines: one ``stringbot simulate --pty`` process per machine.

A winding on the simulator goes through a pseudo-terminal to a simulator in its own process,
as ``stringbot simulate --pty PATH`` and ``wind --port PATH`` do on the command line, so the
simulated machine outlives the winding: a pulled cable (``disconnect``), a power cut or a
stop is resumed on the same simulated machine, which keeps its thread and its record.  A new
start on the simulator starts a new simulated machine (the faults asked for, a fresh record).

The simulator lives until the next start on it or the workshop's end; it runs in its own
session, so a workshop that crashes leaves it serving, and the next workshop adopts it (the
pty's lock names its process) instead of starting another.
"""

import asyncio
import json
import logging
import os
import signal
import time
from dataclasses import dataclass

from firmware_protocol.pty import holder

from ..errors import BadInput
from .commands import SIMULATOR_DIR, Command, pty_for, simulate_command

__all__ = ["Simulators", "Simulator"]

log = logging.getLogger(__name__)

START_TIMEOUT_S = 20.0


@dataclass
class Simulator:
    """One served simulated machine."""

    machine: str
    pid: int
    command: Command
    faults: str = ""
    realtime: bool = False
    started: float = 0.0
    proc: object = None             # the asyncio process when this workshop started it (None: adopted)

    def alive(self):
        if self.proc is not None:
            return self.proc.returncode is None
        try:
            os.kill(self.pid, 0)
        except OSError:
            return False
        return True


class Simulators:
    """The simulators of a plans folder, by machine name."""

    def __init__(self, folder):
        self.folder = folder
        self.dir = folder / SIMULATOR_DIR
        self.by_machine = {}

    def adopt(self, machines):
        """Simulators left serving by an earlier workshop (found by their pty's lock)."""
        for machine in machines:
            pid = holder(self.folder / pty_for(machine))
            if pid is not None and pid > 0:
                self.by_machine[machine] = Simulator(machine, pid, simulate_command(self.folder, machine=machine),
                                                     started=time.time())
                log.info("adopted the simulator of %s (process %d)", machine, pid)

    def get(self, machine):
        sim = self.by_machine.get(machine)
        return sim if sim is not None and sim.alive() else None

    def port(self, machine):
        """The pty path (relative to the plans folder) of ``machine``'s live simulator, or None."""
        return pty_for(machine) if self.get(machine) is not None else None

    def record_path(self, machine):
        return self.dir / f"{machine}-record.json"

    def record(self, machine):
        """The simulated world's record (wraps, collisions...) or None."""
        try:
            return json.loads(self.record_path(machine).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None

    async def start(self, machine, *, faults=None, realtime=False):
        """A new simulated machine for ``machine`` (any earlier one stopped first)."""
        await self.stop(machine)
        self.dir.mkdir(exist_ok=True)
        cmd = simulate_command(self.folder, machine=machine, faults=faults, realtime=realtime)
        pty = self.folder / pty_for(machine)
        logfile = open(self.dir / f"{machine}.log", "wb")
        try:
            proc = await asyncio.create_subprocess_exec(*cmd.argv(), cwd=str(self.folder),
                                                        stdin=asyncio.subprocess.DEVNULL, stdout=logfile,
                                                        stderr=asyncio.subprocess.PIPE, start_new_session=True)
        finally:
            logfile.close()
        deadline = time.monotonic() + START_TIMEOUT_S
        while holder(pty) != proc.pid or not os.path.exists(os.path.realpath(pty)):
            if proc.returncode is not None or time.monotonic() > deadline:
                err = (await proc.stderr.read()).decode(errors="replace") if proc.returncode is not None else ""
                if proc.returncode is None:
                    proc.kill()
                    await proc.wait()
                lines = [x for x in err.splitlines() if x.startswith("stringbot:")]
                raise BadInput(lines[-1].split(": error: ", 1)[-1] if lines else
                               f"the simulator of {machine} did not start ({cmd.shown()})")
            await asyncio.sleep(0.05)
        asyncio.get_running_loop().create_task(proc.stderr.read())     # keep its stderr drained
        sim = Simulator(machine, proc.pid, cmd, faults=faults or "", realtime=bool(realtime), started=time.time(),
                        proc=proc)
        self.by_machine[machine] = sim
        return sim

    async def wait_port(self, machine, timeout=10.0):
        """Until the simulator's pty is there again: after a pulled cable (``disconnect``) or a power
        cut it comes back once the simulated machine does (a winding started meanwhile would find
        no port, as a user who plugs the cable in too late)."""
        pty = self.folder / pty_for(machine)
        deadline = time.monotonic() + timeout
        while self.get(machine) is not None and not os.path.exists(os.path.realpath(pty)):
            if time.monotonic() > deadline:
                return False
            await asyncio.sleep(0.05)
        return True

    async def stop(self, machine):
        """Stop ``machine``'s simulator (as Ctrl-C: it writes its record and removes its pty)."""
        sim = self.by_machine.pop(machine, None)
        if sim is None or not sim.alive():
            return
        try:
            os.kill(sim.pid, signal.SIGINT)
        except OSError:
            return
        deadline = time.monotonic() + 10.0
        while sim.alive() and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        if sim.alive():
            try:
                os.kill(sim.pid, signal.SIGKILL)
            except OSError:
                pass
        if sim.proc is not None:
            await sim.proc.wait()

    async def stop_all(self):
        for machine in list(self.by_machine):
            await self.stop(machine)

    def snapshot(self):
        out = {}
        for machine, sim in self.by_machine.items():
            if sim.alive():
                out[machine] = {"pid": sim.pid, "pty": pty_for(machine), "faults": sim.faults,
                                "realtime": sim.realtime, "command": sim.command.shown()}
        return out
