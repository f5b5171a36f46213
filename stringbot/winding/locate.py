"""Where on the journal's path a machine stands: tolerances, path segments, sides; where the job goes on.

The journal leaves a job at (step, move); the machine stands at the end of the
last executed move or on the straight segment of the next one or two.
:func:`locate` finds a reported position on that path within
:func:`tolerance` (one step of each axis plus rounding, from the link or the
machine file).
"""

from dataclasses import dataclass

from ..motion.positions import position_tolerance

__all__ = ["TOL", "tolerance", "locate", "start_point", "side_of", "Found", "continue_point"]

TOL = 0.01       # the least tolerance (degrees / mm) whatever the machine


def _near(a, b, tol=(TOL, TOL)):
    return abs(a[0] - b[0]) <= tol[0] and abs(a[1] - b[1]) <= tol[1]


def _on_segment(p, a, b, tol=(TOL, TOL)):
    """``p`` strictly inside the straight segment a -> b (the moves are straight lines)."""
    dr, dh = b[0] - a[0], b[1] - a[1]
    length2 = dr * dr + dh * dh
    if length2 <= TOL * TOL:
        return False
    t = ((p[0] - a[0]) * dr + (p[1] - a[1]) * dh) / length2
    if t <= 0.0 or t >= 1.0:
        return False
    q = (a[0] + t * dr, a[1] + t * dh)
    return _near(p, q, tol)


def tolerance(link, machine=None):
    """(ring_deg, head_mm) within which ``locate`` accepts a position: the link's
    ``position_tolerance`` (one step of each axis plus rounding for a G-code link, the arrival
    tolerance for a servo), else the machine file's steps (see
    :func:`stringbot.motion.positions.position_tolerance`); never below :data:`TOL`."""
    own = getattr(link, "position_tolerance", None)
    if own is None:
        if machine is None:
            return (TOL, TOL)
        own = position_tolerance(machine)
    if isinstance(own, (int, float)):
        own = (own, own)
    return (max(TOL, float(own[0])), max(TOL, float(own[1])))


def _point(move):
    return (move.ring_deg, move.head_mm)


def start_point(steps, s, machine):
    """Where step ``s`` starts: the end of step ``s - 1`` (the job's start for step 0)."""
    if s == 0:
        return (steps[0].moves[0].ring_deg, machine["head.in_mm"])
    return _point(steps[s - 1].moves[-1])


def locate(p, steps, s, m, machine, tol=(TOL, TOL)):
    """Where on the path from (step ``s``, move ``m``) on the machine at ``p`` stands.

    Returns ``(step, move)``: continue with that move of that step (``move`` 0 of
    the next step when ``p`` is the end of step ``s``), or None if ``p`` is not on
    the path.  ``tol``: (ring_deg, head_mm) how far ``p`` may be from the path
    (see :func:`tolerance`).
    """
    for step_i in (s, s + 1):
        if step_i >= len(steps):
            if step_i == len(steps) and _near(p, _point(steps[-1].moves[-1]), tol):
                return (len(steps), 0)
            break
        moves = steps[step_i].moves
        first = m if step_i == s else 0
        prev = _point(moves[first - 1]) if first > 0 else start_point(steps, step_i, machine)
        for k in range(first, len(moves)):
            target = _point(moves[k])
            if _near(p, prev, tol) or _on_segment(p, prev, target, tol):
                return (step_i, k)
            prev = target
        if _near(p, prev, tol):
            return (step_i + 1, 0)
    return None


def side_of(machine, head_mm):
    return _side(machine, head_mm)


def _side(machine, head_mm):
    h_in, h_out = machine["head.in_mm"], machine["head.out_mm"]
    return "out" if abs(head_mm - h_out) < abs(head_mm - h_in) else "in"


@dataclass
class Found:
    """Where the machine stands and where the job goes on."""

    here: tuple                 # (ring_deg, head_mm), job coordinates, as the firmware now knows it
    where: tuple                # (step, move) to continue with
    lost: bool                  # the firmware had lost its position (or restarted)
    how: str                    # how the position was found, for the journal and the log
    on_path: bool = True        # ``here`` lies on the journal's path (else: a ring move with the head IN follows)
    approach: bool = False      # before the first hook: the first moves (head IN, ring to the start) follow


def continue_point(sit, *, hooked):
    """(step, move) to go on from, with the head IN somewhere on the ring: the next step when
    the interrupted step's pin is hooked, else the interrupted step from its approach (a ring
    move with the head IN: safe from anywhere)."""
    if sit.s >= len(sit.steps):
        return (len(sit.steps), 0)
    if hooked:
        return (sit.s + 1, 0)
    return (sit.s, min(sit.m, sit.approach))
