"""The cases of the cross-process fault matrix (:mod:`bench_fault_matrix`): every bundled machine, every
fault kind a resume can get past, and where in a winding each strikes.

Fault points come from one fault-free probe per machine (in process, ``sim://``, :func:`line_table`):
the line numbers of the moves of random steps, by kind of move (:func:`fault_points`: ``ring``,
``out``, ``hook``, ``hook-sync``, ``in``), and the first moves (:func:`first_points`: the homing line,
the first ring move).  :func:`build_cases` makes the matrix's cases from them; :func:`uno_machine`
the copy of a machine file whose board reboots whenever the port opens.
"""

import json
import random
import re
import signal
import subprocess
import sys
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from matrix_user import DISPLACEMENTS, STRINGBOT, displacement, homes  # noqa: E402

from firmware_protocol.emulators.dynamixel import FAULT_ALIASES, FaultKind  # noqa: E402
from firmware_protocol.faults import FAULT_KINDS  # noqa: E402
from firmware_protocol.machine import bundled_machines, load_machine  # noqa: E402

# the registries: every bundled machine, every fault kind a resume can get past
SERVO = [m for m in bundled_machines() if load_machine(m)["controller.kind"] == "dynamixel"]
GCODE = [m for m in bundled_machines() if m not in SERVO]
LINE_KINDS = [k.name for k in FAULT_KINDS.values() if k.resumable]                 # kind@N
MID_KINDS = [k.name for k in FAULT_KINDS.values() if k.resumable and k.hits == "machine"]   # kind@N+0.5
UNO_KINDS = ["error", "disconnect", "reset"]               # with reset_on_open; reset mid-move
DXL_KINDS = [next((a for a, v in FAULT_ALIASES.items() if v == k.value), k.value) for k in FaultKind]
POINTS = ["ring", "out", "hook", "hook-sync", "in"]
FIRST = ["home", "first"]            # the first moves: the homing line, the first ring move
FIRST_KINDS = ["power", "reboot", "reset"]       # at a first point, as the line arrives and mid-move


@dataclass
class Case:
    machine: str                  # name or machine file path
    label: str                    # machine as shown in the table
    kind: str                     # as shown in the table (e.g. "reset+0.5", "uno-error")
    faults: str = ""
    point: str = ""
    kills: list = field(default_factory=list)     # signal the host after these journaled step counts
    signal: int = signal.SIGKILL                  # SIGKILL (a dead computer) or SIGINT (Ctrl-C)
    sim_kill: int = 0                             # SIGKILL the simulator after this many steps
    setup: str = ""                               # a displacement typed before the first wind
    then: str = ""                                # and one more line (that a fault meets)

    @property
    def name(self):
        return f"{self.label} {self.kind} {self.faults or self.point}".strip()


# ---- the plan and the fault points ------------------------------------------------------------

def make_plan(workdir, machine, lines, picture="camera.png"):
    path = Path(workdir) / f"plan-{Path(machine).stem}.json"
    if not path.exists():
        subprocess.run(STRINGBOT + ["plan", str(ROOT / "examples" / picture), "-o", str(path), "--machine",
                                    machine, "--lines", str(lines), "--size", "201"],
                       check=True, capture_output=True, text=True)
    return path


def line_table(plan_path, machine):
    """A fault-free winding in process: ``[(n, text, head side as line n arrives)]`` as the firmware
    counted them.  Only chooses the fault points; judging never looks at live objects."""
    from firmware_protocol.emulators.gcode_base import GcodeFirmware
    from firmware_protocol.machine import load_machine
    from firmware_protocol.urlhandler import protocol_sim
    from stringbot.links import sim_url
    from stringbot.winding import Job, wind_plan

    table, orig = [], GcodeFirmware._line_faults

    def spy(self, raw):
        table.append((self.faults.lines + 1, bytes(raw).decode("ascii", "replace").strip(),
                      self.world.head_side))
        return orig(self, raw)
    url = sim_url(machine, record=Path(plan_path).with_suffix(".probe.json"))
    GcodeFirmware._line_faults = spy
    try:
        wind_plan(Job(plan_path, load_machine(machine), port=url,
                      journal=Path(plan_path).with_suffix(".probe.journal")), confirm=None,
                  check=True,                 # as the command does: the settings check's lines count
                  eyes=lambda: protocol_sim.look(url))     # the head IN: as the operator says
    finally:
        GcodeFirmware._line_faults = orig
        protocol_sim.forget(url)
    return table


def fault_points(table, machine, rng, wanted=POINTS):
    """One line number per kind of point, each in a different random part of the job."""
    from firmware_protocol.machine import load_machine
    m = load_machine(machine)
    ring_ax, head_ax = m["controller.ring_axis"], m["controller.head_axis"]
    by_kind = defaultdict(list)
    for i, (n, text, side) in enumerate(table):
        words = re.sub(r"^N\d+ |\*\d+$", "", text).split()
        if not words or words[0] not in ("G1", "G0"):
            continue
        axes = {w[0] for w in words[1:]}
        if axes == {ring_ax} or axes == {ring_ax, "F"}:
            kind = "hook" if side == "out" else "ring"
        elif axes <= {head_ax, "F"}:
            kind = "in" if side == "out" else "out"
        else:
            continue
        by_kind[kind].append(n)
        if kind == "hook" and i + 1 < len(table):
            by_kind["hook-sync"].append(table[i + 1][0])
    points = {}
    for k, kind in enumerate(wanted):
        ns = by_kind[kind.split("+")[0]]
        lo, hi = len(ns) * k // (len(wanted) + 1), len(ns) * (k + 2) // (len(wanted) + 1)
        points[kind] = ns[rng.randrange(max(lo, 1), max(hi, lo + 2))] if ns else None
    return points


def first_points(table, machine):
    """The first moves of the job: the homing line (``$H``, ``G28``: machines that home) and the
    first ring move (to the first pin's gap, the head IN)."""
    from firmware_protocol.machine import load_machine
    ring_ax = load_machine(machine)["controller.ring_axis"]
    points = {}
    for n, text, side in table:
        words = re.sub(r"^N\d+ |\*\d+$", "", text).split()
        if not words:
            continue
        if (words[0].startswith("$H") or words[0] == "G28") and "home" not in points:
            points["home"] = n
        if words[0] in ("G1", "G0") and {w[0] for w in words[1:]} <= {ring_ax, "F"} and side == "in":
            points.setdefault("first", n)
    return points


def uno_machine(workdir, name):
    """A copy of the bundled machine file whose board reboots whenever the port opens."""
    path = Path(workdir) / f"{name}-uno.toml"
    text = (ROOT / "machines" / f"{name}.toml").read_text()
    if re.search(r"^reset_on_open\s*=", text, re.M):
        text = re.sub(r"^reset_on_open\s*=\s*\w+", "reset_on_open = true", text, flags=re.M)
    else:
        text = text.replace("[controller]\n", "[controller]\nreset_on_open = true\n", 1)
    path.write_text(text)
    return str(path)


# ---- the matrix -------------------------------------------------------------------------------

def build_cases(workdir, machines, kinds, n_points, kills, seed, plan_for):
    """The cases, and the plan path per machine label."""
    rng = random.Random(seed)
    cases, plans = [], {}
    # the first points taken: one mid-hook, one with the head IN, the other mid-hook ...
    chosen = ["hook", "ring", "in", "out", "hook-sync"][:max(1, n_points)]
    points_of = [p for p in POINTS if p in chosen]
    for name in machines:
        plan = plan_for(name)
        plans[name] = plan
        if name in SERVO:
            steps = len(json.loads(Path(plan).read_text())["sequence"])
            for kind in (k for k in DXL_KINDS if k in kinds or "dynamixel" in kinds):
                for i in range(n_points):
                    s = 1 + (steps - 2) * (i + 1) // (n_points + 1)
                    cases.append(Case(name, name, kind, f"{kind}@{4 * s + 1 + i % 4}"))
            if "first-power" in kinds:          # the first moves: to the start, the first ring move
                for n in (1, 2):
                    cases.append(Case(name, name, "first-power", f"power@{n}", "first"))
        else:
            table = line_table(plan, name)
            for kind in (k for k in LINE_KINDS if k in kinds):
                for point, n in fault_points(table, name, rng, points_of).items():
                    cases.append(Case(name, name, kind, f"{kind}@{n}", point))
            mid = [p for p in points_of if p != "hook-sync"]
            for kind in (k for k in MID_KINDS if f"{k}+0.5" in kinds):
                for point, n in fault_points(table, name, rng, mid).items():
                    cases.append(Case(name, name, f"{kind}+0.5", f"{kind}@{n}+0.5", point))
            for point, n in first_points(table, name).items():     # the first-move cases
                for kind in (k for k in FIRST_KINDS if f"first-{k}" in kinds):
                    cases.append(Case(name, name, f"first-{kind}", f"{kind}@{n}", point))
                    cases.append(Case(name, name, f"first-{kind}+0.5", f"{kind}@{n}+0.5", point))
            if "start" in kinds:                # displaced by a person before the start
                for shift in DISPLACEMENTS:
                    cases.append(Case(name, name, "start", point=shift, setup=shift))
                if homes(name):                 # ... then the power went: the firmware cannot say
                    lines = displacement(name, "out-pin")
                    cases.append(Case(name, name, "start", f"power@{len(lines) + 1}", "out-pin, power",
                                      setup="out-pin", then="G4 P0" if "marlin" not in name else "M400"))
            uno = uno_machine(workdir, name)
            for kind in (k for k in UNO_KINDS if f"uno-{k}" in kinds):
                for point, n in fault_points(table, name, rng, mid).items():
                    spec = f"{kind}@{n}+0.5" if kind == "reset" else f"{kind}@{n}"
                    cases.append(Case(uno, name, f"uno-{kind}", spec, point))
        steps = len(json.loads(Path(plan).read_text())["sequence"])
        if "host-kill" in kinds and kills:
            cases.append(Case(name, name, "host-kill", point=f"{kills} kills",
                              kills=sorted(rng.sample(range(1, steps - 1), kills))))
        if "host-int" in kinds and kills and name not in SERVO:
            for machine, kind in ((name, "host-int"), (uno_machine(workdir, name), "uno-int")):
                cases.append(Case(machine, name, kind, point=f"{kills} Ctrl-C", signal=signal.SIGINT,
                                  kills=sorted(rng.sample(range(1, steps - 1), kills))))
        if "sim-kill" in kinds:
            cases.append(Case(name, name, "sim-kill", point="1 kill", sim_kill=rng.randrange(2, steps - 2)))
    return cases, plans
