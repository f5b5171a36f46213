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


def union_brute(chords, xy, m, f, width_px):
    """The planners' union of threads, every sample tested against every thread: the share of each of
    the ``m x m`` pixels covered, ``f x f`` samples a pixel, each sample where
    :func:`~stringbot.planner.union.offsets` puts it for a thread of that kind (nearer horizontal:
    offset down its column; nearer vertical: along its row), covered when within half the width of the
    thread's line and between its ends."""
    from stringbot.planner.model.union import offsets

    F = m * f
    down, across = offsets(F)
    yy, xx = np.mgrid[0:F, 0:F] + 0.5
    cov = np.zeros((F, F), dtype=bool)
    for a, b in chords:
        p, q = np.asarray(xy[a]) * F, np.asarray(xy[b]) * F
        d = q - p
        n = np.array([-d[1], d[0]]) / np.hypot(*d)
        if abs(d[0]) >= abs(d[1]):
            x, y, along, lo, hi = xx, yy + down[None, :], xx, *sorted((p[0], q[0]))
        else:
            x, y, along, lo, hi = xx + across[:, None], yy, yy, *sorted((p[1], q[1]))
        near = np.abs((x - p[0]) * n[0] + (y - p[1]) * n[1]) <= width_px * f / 2
        cov |= near & (along >= lo) & (along <= hi)
    return cov.reshape(m, f, m, f).mean(axis=(1, 3))
