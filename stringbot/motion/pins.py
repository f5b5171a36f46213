"""The pin list for winding a plan by hand: step, pin, wrap direction, with a header.

Wrap directions follow the machine's rule (:func:`stringbot.motion.hooking.wrap_direction`):
``cw`` means the thread goes round the pin clockwise seen from the front (it
arrives on the pin's lower-numbered side and leaves on its higher-numbered
side), so that it runs round the outside of the pin without crossing itself;
``either`` where both ways are alike (the thread comes back the way it came).

A colour plan lists its layers one after the other, each a thread of its own:
the text says before a layer's first step which thread to cut and which colour
to tie on at which pin, the CSV has a ``color`` column; a layer's first pin has
no incoming thread (the thread is tied on there).

On a ring, pins are numbered as the plan numbers them: 0 at the top, clockwise.
On a square frame the list numbers them along the border from the top-left
corner, clockwise (0 is the first pin at or after the corner), which is how a
maker counts nails on a board; the plan's own index is kept in the CSV.
"""

import csv
import io
import math
from dataclasses import dataclass, field

import numpy as np

from .._files import PINS_HEAD
from ..errors import BadInput
from ..planner.colour.palette import describe_color
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
    layers : list of (first_row, color, name, tie_pin)
        A colour plan's layers (empty for a one-thread plan): the index in ``rows`` of each
        layer's first step, its colour, its name and the pin to tie it on at.
    """

    rows: list
    header: list
    layers: list = field(default_factory=list)


def square_offset(pins):
    """The plan index of the first pin at or after the top-left corner of a square frame.

    The planner puts pin ``k`` at ``k * 4 / pins + 0.5`` sides along the border from
    the top-left corner, clockwise (pin 0 mid-top); the list's pin ``h`` is the
    plan's ``(h + offset) mod pins``.
    """
    s = (np.arange(pins) * 4.0 / pins + 0.5) % 4.0
    s = np.where(s > 4.0 - 1e-9, 0.0, s)
    return int(np.argmin(s))


def thread_metres(plan, size_mm, sequence=None):
    """Thread along the chords, pin centre to pin centre, for a frame ``size_mm`` across (m):
    of ``sequence`` (one layer), or of every layer of ``plan`` (no chord between two layers)."""
    if sequence is None:
        return sum(thread_metres(plan, size_mm, lay.sequence) for lay in plan.layers)
    xy = np.asarray(plan.pin_xy, dtype=float)
    seq = np.asarray(sequence, dtype=int)
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
    offset = square_offset(n) if plan.frame == "square" else 0
    rows, layers = [], []
    for lay in plan.layers:
        seq = [int(p) for p in lay.sequence]
        if len(plan.colors) > 1:
            layers.append((len(rows), lay.color, describe_color(lay.color), (seq[0] - offset) % n))
        for k, pin in enumerate(seq):
            prev = seq[k - 1] if k > 0 else None
            nxt = seq[k + 1] if k + 1 < len(seq) else None
            rows.append((len(rows) + 1, (pin - offset) % n, pin, _WRAP[wrap_direction(prev, pin, nxt, n)]))
    lines = sum(max(len(lay.sequence) - 1, 0) for lay in plan.layers)
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
    first = "the first thread" if layers else "the thread"
    header = [("plan", f"{plan_name} ({plan.method}, sha256 {plan.sha256()[:12]})"),
              ("pins", numbering),
              ("lines", f"{lines} ({len(rows)} pins to go round, the first included: tie {first} on "
                        f"at pin {rows[0][1]} first)"),
              ("thread", thread)]
    if layers:
        ends = [a for a, *_ in layers[1:]] + [len(rows)]
        each = []
        for k, ((a, color, name, tie), b) in enumerate(zip(layers, ends)):
            metres = f", about {thread_metres(plan, size_mm, plan.layers[k].sequence):.1f} m" if size_mm else ""
            each.append(f"{k + 1} {name}: steps {a + 1}-{b}, tie on at pin {tie}{metres}")
        colours = list(dict.fromkeys(plan.colors))
        runs = "" if len(colours) == len(layers) else f" runs of {len(colours)} colours (a colour comes back)"
        bare = "; each run's metres without the turns round the pins" if size_mm else ""
        header.append(("threads", f"{len(layers)}{runs}, wound in this order (later ones lie on top{bare}): "
                                  + "; ".join(each)))
        if runs and size_mm:     # what each spool must hold
            spool = {c: sum(thread_metres(plan, size_mm, lay.sequence) for lay in plan.layers if lay.color == c)
                     for c in colours}
            header.append(("colours", "; ".join(f"{describe_color(c)} about {m:.1f} m in {plan.colors.count(c)} "
                                                "run(s)" for c, m in spool.items()) + " (without the turns)"))
    header += [
              ("wrap", "cw: round the pin clockwise, ccw: counter-clockwise (seen from the front), "
                       "either: both alike; always round the outside of the pin")]
    return PinList(rows=rows, header=header, layers=layers)


def format_txt(pl, *, page_steps=PAGE_STEPS, title=PINS_HEAD):
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
        starts = {a: (k, name, tie) for k, (a, _c, name, tie) in enumerate(pl.layers)}
        for step, pin, _plan_pin, wrap in chunk:
            if step - 1 in starts:
                k, name, tie = starts[step - 1]
                cut = "" if k == 0 else "cut the thread; "
                lines.append(f"        -- thread {k + 1} of {len(pl.layers)}: {cut}tie {name} on at pin {tie} --")
            lines.append(f"{step:>6}  {pin:>5}  {wrap:<6} [ ]")
        pages.append("\n".join(lines) + "\n")
    return "\f".join(pages)


def format_csv(pl):
    """CSV: ``# label: text`` header lines, then ``step,pin,plan_pin,wrap`` rows."""
    buf = io.StringIO()
    buf.write(f"# {PINS_HEAD}\n")
    for label, text in pl.header:
        buf.write(f"# {label}: {text}\n")
    w = csv.writer(buf, lineterminator="\n")
    if not pl.layers:
        w.writerow(["step", "pin", "plan_pin", "wrap"])
        w.writerows(pl.rows)
        return buf.getvalue()
    w.writerow(["step", "pin", "plan_pin", "wrap", "color"])
    ends = [a for a, *_ in pl.layers[1:]] + [len(pl.rows)]
    for (a, color, _name, _tie), b in zip(pl.layers, ends):
        w.writerows(row + (color,) for row in pl.rows[a:b])
    return buf.getvalue()
