"""Small synthetic pictures for the planner tests."""

import numpy as np

from stringbot.planner.picture.read import Picture


def picture(gray):
    """A :class:`Picture` of a square gray array (levels 0..255), as if read from a file."""
    n = gray.shape[0]
    return Picture(np.asarray(gray, dtype=np.float32), {"cx": n / 2, "cy": n / 2, "r": n / 2},
                   {"path": "synthetic", "sha256": "0" * 64, "width": n, "height": n}, "gray")


def plan_files(folder, plan):
    """``plan_for(machine)``: the path of ``plan`` made for that machine's thread (written once, in
    ``folder``)."""
    from pathlib import Path

    from stringbot.planner import write_plan

    def plan_for(machine):
        path = Path(folder) / f"plan-{Path(machine).stem}.json"
        if not path.exists():
            write_plan(for_machine(plan, machine), path)
        return path
    return plan_for


def for_machine(plan, machine):
    """``plan`` as ``stringbot plan --machine`` makes it: the machine's ring diameter and thread (a plan
    for another thread-to-diameter ratio is refused by wind, gcode, pins and estimate).  Returns it."""
    from firmware_protocol.machine import load_machine

    m = load_machine(machine)
    plan.diameter_mm, plan.thread_mm = m["ring.diameter_mm"], m["thread.diameter_mm"]
    return plan
