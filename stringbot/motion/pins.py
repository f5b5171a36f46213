"""The pin list for winding a plan by hand: step, pin, wrap direction, with a header.

Wrap directions follow the machine's rule (:func:`stringbot.motion.hooking.wrap_direction`):
``cw`` means the thread goes round the pin clockwise seen from the front (it
arrives on the pin's lower-numbered side and leaves on its higher-numbered
side), so that it runs round the outside of the pin without crossing itself;
``either`` where both ways are alike (the thread comes back the way it came).

On a ring, pins are numbered as the plan numbers them: 0 at the top, clockwise.
On a square frame the list numbers them along the border from the top-left
corner, clockwise (0 is the first pin at or after the corner), which is how a
maker counts nails on a board; the plan's own index is kept in the CSV.
"""

import csv
import io
import math
from dataclasses import dataclass

import numpy as np

from ..errors import BadInput
from .hooking import wrap_direction

__all__ = ["PinList", "pin_list", "format_txt", "format_csv", "square_offset", "thread_metres",
           "PAGE_STEPS"]

PAGE_STEPS = 100
_WRAP = {1: "cw", -1: "ccw", None: "either"}


@dataclass
class PinList:
    """What a pin list says.

    Attributes
    ----------
    rows : list of (step, pin, plan_pin, wrap)
        ``step`` from 1; ``pin`` as the list numbers it; ``plan_pin`` the plan's index.
    header : list of (label, text)
    """

    rows: list
    header: list


def square_offset(pins):
    """The plan index of the first pin at or after the top-left corner of a square frame.

    The planner puts pin ``k`` at ``k * 4 / pins + 0.5`` sides along the border from
    the top-left corner, clockwise (pin 0 mid-top); the list's pin ``h`` is the
    plan's ``(h + offset) mod pins``.
    """
    s = (np.arange(pins) * 4.0 / pins + 0.5) % 4.0
    s = np.where(s > 4.0 - 1e-9, 0.0, s)
    return int(np.argmin(s))


def thread_metres(plan, size_mm):
    """Thread along the chords, pin centre to pin centre, for a frame ``size_mm`` across (m)."""
    xy = np.asarray(plan.pin_xy, dtype=float)
    seq = np.asarray(plan.sequence, dtype=int)
    if len(seq) < 2:
        return 0.0
    return float(np.linalg.norm(xy[seq[1:]] - xy[seq[:-1]], axis=1).sum()) * size_mm / 1000.0


def pin_list(plan, *, plan_name="plan", size_mm=None, size_from="", thread_m=None):
    """The pin list of a connected ``plan``.

    Parameters
    ----------
    plan : Plan
    plan_name : str
        How the header names the plan (its file name).
    size_mm : float, optional
        The ring's diameter (a square frame's side), for the thread length in metres.
    size_from : str
        Where ``size_mm`` came from, for the header (e.g. ``"machine grbl-ring"``).
    thread_m : float, optional
        A better thread length (the machine estimate, with the wraps round pins).

    Raises
    ------
    BadInput
        For a disconnected plan.
    """
    if not plan.connected:
        raise BadInput("plan is a disconnected chord set (field 'connected' is false); expected a "
                       "connected plan with a 'sequence' (plan again without --disconnected)")
    n = plan.pins
    seq = [int(p) for p in plan.sequence]
    offset = square_offset(n) if plan.frame == "square" else 0
    rows = []
    for k, pin in enumerate(seq):
        prev = seq[k - 1] if k > 0 else None
        nxt = seq[k + 1] if k + 1 < len(seq) else None
        rows.append((k + 1, (pin - offset) % n, pin, _WRAP[wrap_direction(prev, pin, nxt, n)]))
    lines = len(seq) - 1
    if plan.frame == "square":
        numbering = (f"{n} on the border of a square frame, numbered from the top-left corner, clockwise "
                     f"(seen from the front); pin 0 is the plan's pin {offset}")
    else:
        numbering = f"{n} on a ring, numbered clockwise from pin 0 at the top (seen from the front)"
    if size_mm:
        metres = thread_m if thread_m is not None else thread_metres(plan, size_mm)
        what = "ring diameter" if plan.frame == "circle" else "frame side"
        src = f", from {size_from}" if size_from else ""
        thread = (f"about {metres:.1f} m for a {size_mm:g} mm {what}{src} "
                  f"({'with' if thread_m is not None else 'without'} the turns round the pins); add slack")
    else:
        thread = (f"{plan.stats.get('thread_diameters', 0):.1f} frame diameters; give --diameter-mm "
                  "or --machine for metres")
    header = [("plan", f"{plan_name} ({plan.method}, sha256 {plan.sha256()[:12]})"),
              ("pins", numbering),
              ("lines", f"{lines} ({len(seq)} pins to go round, the first included: tie the thread on "
                        f"at pin {rows[0][1]} first)"),
              ("thread", thread),
              ("wrap", "cw: round the pin clockwise, ccw: counter-clockwise (seen from the front), "
                       "either: both alike; always round the outside of the pin")]
    return PinList(rows=rows, header=header)


def format_txt(pl, *, page_steps=PAGE_STEPS, title="stringbot pin list"):
    """Text for printing: the header, then ``page_steps`` steps a page (form feeds between)."""
    width = max(len(label) for label, _ in pl.header)
    head = [title] + [f"{label + ':':<{width + 1}} {text}" for label, text in pl.header]
    pages = []
    total = len(pl.rows)
    npages = max(1, math.ceil(total / page_steps))
    for p in range(npages):
        chunk = pl.rows[p * page_steps:(p + 1) * page_steps]
        lines = list(head) if p == 0 else [f"{title}, continued"]
        lines += ["", f"page {p + 1} of {npages}: steps {chunk[0][0]}-{chunk[-1][0]} of {total}", "",
                  f"{'step':>6}  {'pin':>5}  wrap   done"]
        for step, pin, _plan_pin, wrap in chunk:
            lines.append(f"{step:>6}  {pin:>5}  {wrap:<6} [ ]")
        pages.append("\n".join(lines) + "\n")
    return "\f".join(pages)


def format_csv(pl):
    """CSV: ``# label: text`` header lines, then ``step,pin,plan_pin,wrap`` rows."""
    buf = io.StringIO()
    for label, text in pl.header:
        buf.write(f"# {label}: {text}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["step", "pin", "plan_pin", "wrap"])
    w.writerows(pl.rows)
    return buf.getvalue()
