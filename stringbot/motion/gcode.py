"""Hooking moves -> G-code, per firmware dialect (GRBL 1.1, grblHAL, FluidNC, Marlin 2.1).

The dialects differ only where the firmware does: axis letters (stock GRBL has
X, Y, Z only, so its ring is a "linear" axis set to steps per degree), homing
(``$H`` versus ``G28``), declaring the homed position (``G10 L20 P1`` versus
``G92``), the sync point the host waits on (``G4 P0`` versus ``M400``), dwell
units (GRBL's ``G4 P`` is seconds, Marlin's milliseconds) and the end of the
program (``M2`` versus an LCD message, since Marlin has no ``M2``).

The host winds step by step: it sends ``dialect.step_lines(step)``, then
``dialect.sync()``, and records the step once the sync is acknowledged.

A colour plan's program pauses before each layer but the first, in the
dialect's own way (``M0``: GRBL, grblHAL and FluidNC hold until cycle start, ``~``;
Marlin shows an ``M117`` message and waits for the click of its LCD), after
a comment naming the thread to cut and the colour to tie on at which pin.
"""

from .estimate import estimate, format_duration
from .hooking import hook_steps

__all__ = ["GcodeDialect", "GrblDialect", "MarlinDialect", "FLAVOURS", "dialect_for", "gcode_job", "fmt"]


def fmt(value):
    """A number as G-code: at most 4 decimals, no trailing zeros, no ``-0``."""
    text = f"{value:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


class GcodeDialect:
    """What every G-code dialect shares; subclasses set the differences.

    Parameters
    ----------
    machine : firmware_protocol.machine.Machine
    """

    name = "gcode"
    sync_line = "G4 P0"

    def __init__(self, machine, kind=None):
        self.machine = machine
        if kind is not None:        # a firmware_protocol.kinds record: its name and sync line
            self.name, self.sync_line = kind.name, kind.sync_line
        self.ring_axis = machine["controller.ring_axis"]
        self.head_axis = machine["controller.head_axis"]

    # ---- pieces -------------------------------------------------------------------------
    def preamble(self):
        """Modal setup: millimetres, absolute positions, feed in units per minute."""
        return ["G21", "G90", "G94"]

    def home(self):
        """Homing and declaring the homed position; empty unless ``controller.homing``.

        Send these before :meth:`preamble`: GRBL with homing enabled starts
        locked in alarm and refuses G-code until ``$H``.
        """
        if self.machine["controller.homing"]:
            return [self.home_command(), self.set_position(*self.home_position())]
        if self.machine.values.get("controller.head_homing"):
            return [self.home_command(["head"]), self.set_position(None, self.home_position()[1])]
        return []

    def home_position(self):
        """(ring deg, head mm) declared at the home switches."""
        m = self.machine
        head = m["controller.home_head_mm"]
        return m["controller.home_ring_deg"], m["head.in_mm"] if head is None else head

    def home_command(self, axes=None):
        """Home every axis, or only ``axes`` (a list of "ring", "head"): ``$H``, ``$HY``."""
        if not axes:
            return "$H"
        return "$H" + "".join(self._letter(a) for a in axes)

    def _letter(self, axis):
        return {"ring": self.ring_axis, "head": self.head_axis}[axis]

    def jog_lines(self, axis, delta, feed):
        """Move ``axis`` ("ring" or "head") by ``delta`` from wherever it is, then absolute again."""
        return ["G91", f"G1 {self._letter(axis)}{fmt(delta)} F{fmt(feed)}", "G90"]

    def _words(self, ring_deg, head_mm):
        words = [] if ring_deg is None else [f"{self.ring_axis}{fmt(ring_deg)}"]
        return " ".join(words + ([] if head_mm is None else [f"{self.head_axis}{fmt(head_mm)}"]))

    def set_position(self, ring_deg, head_mm):
        """Declare the current position (work coordinates) without moving (None: that axis not)."""
        return f"G10 L20 P1 {self._words(ring_deg, head_mm)}"

    def move_line(self, move, prev=None):
        """One ``G1`` line to ``move``'s absolute target, with its feed.

        ``prev``: the point the machine starts from (a Move or ``(ring_deg, head_mm)``).  Given
        it, the line names only the axes that change, so that a ring move can never move
        the head, nor a head move the ring, whatever the firmware believes of the other
        axis (both axes when ``prev`` is None, or a move changes both).
        """
        words = [f"{self.ring_axis}{fmt(move.ring_deg)}", f"{self.head_axis}{fmt(move.head_mm)}"]
        if prev is not None:
            was = (prev.ring_deg, prev.head_mm) if hasattr(prev, "ring_deg") else tuple(prev)
            changed = [w for w, a, b in zip(words, was, (move.ring_deg, move.head_mm))
                       if fmt(a) != fmt(b)]
            if len(changed) == 1:
                words = changed
        line = "G1 " + " ".join(words)
        return line if move.feed is None else f"{line} F{fmt(move.feed)}"

    def dwell(self, seconds):
        """A pause of ``seconds``."""
        return f"G4 P{fmt(seconds)}"

    def progress(self, step):
        """The progress comment of a step: ``; pin 17 (step 5/2530)`` (steps count from 1)."""
        of = f"/{step.total}" if step.total else ""
        return f"; pin {step.pin} (step {step.index + 1}{of})"

    def step_lines(self, step, prev=None):
        """The lines of one hooking step, the progress comment first.

        ``prev``: where the step starts (the previous step's last Move); each move line
        names only the axis it moves (see :meth:`move_line`).
        """
        lines = [self.progress(step)]
        for mv in step.moves:
            lines.append(self.move_line(mv, prev))
            prev = mv
        if step.dwell_s > 0:
            lines.append(self.dwell(step.dwell_s))
        return lines

    def sync(self):
        """The line whose acknowledgement means all motion so far has finished."""
        return self.sync_line

    def end(self):
        return [self.sync(), "M2"]

    def spool_change(self, message):
        """The pause of a spool change (``message``: what to tie on where, for a display)."""
        return ["M0"]


class GrblDialect(GcodeDialect):
    """GRBL's family (GRBL 1.1, grblHAL, FluidNC: the axes their kind has): ``$H``; ``G4 P0`` as
    the sync point; ``M2`` ends."""

    name = "grbl"


class MarlinDialect(GcodeDialect):
    """Marlin 2.1 with a rotary ``A`` axis: ``G28``/``G92``, ``M400`` sync, dwell in ms, no ``M2``."""

    name = "marlin"
    sync_line = "M400"

    def preamble(self):
        return ["G21", "G90"]           # Marlin has no G94 (feeds are always per minute)

    def home_command(self, axes=None):
        if not axes:
            return f"G28 {self.head_axis} {self.ring_axis}"
        return "G28 " + " ".join(self._letter(a) for a in axes)

    def set_position(self, ring_deg, head_mm):
        return f"G92 {self._words(ring_deg, head_mm)}"

    def dwell(self, seconds):
        return f"G4 P{round(seconds * 1000)}"

    def end(self):
        return [self.sync(), "M117 stringbot: done"]

    def spool_change(self, message):
        return [self.sync(), f"M117 {message}", "M0"]


#: The G-code flavour of each family of firmware (``family`` of :mod:`firmware_protocol.kinds`).
FLAVOURS = {"grbl": GrblDialect, "marlin": MarlinDialect}


def dialect_for(machine):
    """The G-code dialect object for a ``kind = "gcode"`` machine: its family's flavour, with its
    kind's name and sync line.

    Raises
    ------
    BadInput
        For a machine that does not speak G-code (``kind = "dynamixel"``), or of a kind the
        records do not hold.
    """
    from firmware_protocol.kinds import UnknownKind, kind_of

    from ..errors import BadInput
    if machine["controller.kind"] != "gcode":
        raise BadInput(f"machine {machine.name!r} has controller.kind = {machine['controller.kind']!r}; "
                       "expected 'gcode' to write G-code")
    try:
        kind = kind_of(machine)
    except UnknownKind as exc:
        raise BadInput(f"machine {machine.name!r}: {exc}") from None
    return FLAVOURS[kind.family](machine, kind)


def gcode_job(plan, machine, *, plan_name=None):
    """The whole winding job as one G-code program for any sender (UGS, bCNC, OctoPrint).

    Parameters
    ----------
    plan : stringbot.planner.Plan
    machine : firmware_protocol.machine.Machine
    plan_name : str, optional
        Shown in the header comment (e.g. the plan's file name).

    Returns
    -------
    str
        Header comment, homing (if asked: first, since a GRBL with homing
        enabled is locked in alarm until ``$H``), modal setup, the steps each
        with a progress comment, and a clean end; newline-terminated.
    """
    dialect = dialect_for(machine)
    start = dialect.home_position()[0] if machine["controller.homing"] else 0.0
    steps = hook_steps(plan, machine, start_ring_deg=start)
    est = estimate(plan, machine, steps=steps)
    source = (plan.source or {}).get("path", "")
    lines = [
        "; stringbot winding job",
        f"; plan: {plan_name or source or '(unnamed)'} sha256 {plan.sha256()[:16]}",
        f"; machine: {machine.name} ({dialect.name}; ring on {dialect.ring_axis} in degrees, "
        f"head on {dialect.head_axis} in mm)",
        f"; pins: {machine.pins}, steps: {len(steps)}",
        f"; estimated machine time: {format_duration(est.seconds)}",
        f"; thread: {est.thread_m:.1f} m; ring travel {est.ring_travel_deg:.0f} deg "
        f"(shortest-arc lower bound {est.lower_bound_deg:.0f} deg)",
    ]
    changes = {}
    if plan.is_mono:
        lines.append("; tie the thread on at the start; the machine hooks every pin of the sequence")
    else:
        lines, changes = _colour_header(plan, machine, steps, lines)
    lines += dialect.home()         # first: a GRBL that homes starts in alarm and refuses G-code until $H
    lines += dialect.preamble()
    prev = None
    for step in steps:
        if step.index in changes:
            comment, message = changes[step.index]
            lines += [comment] + dialect.spool_change(message)
        lines += dialect.step_lines(step, prev)
        prev = step.moves[-1]
    lines += dialect.end()
    return "\n".join(lines) + "\n"


def _colour_header(plan, machine, steps, lines):
    """A colour plan: the threads in the header, and the spool change before each later layer."""
    from ..planner.colour.palette import color_name
    from .layers import layer_estimates

    layers = layer_estimates(plan, machine, steps=steps)
    n = len(layers)
    first = layers[0]
    lines = lines + [f"; {n} layers, each its own thread, wound in this order (later ones lie on top); "
                     f"{n - 1} spool change(s), each a pause (M0)"]
    for le in layers:
        lines.append(f"; layer {le.index + 1}: {color_name(le.color)} ({le.color}), {le.steps} pins, "
                     f"{le.thread_m:.1f} m of thread, {format_duration(le.seconds)}; tie on at pin {le.tie_on_pin}")
    lines.append(f"; tie the {color_name(first.color)} ({first.color}) thread on at pin {first.tie_on_pin} to "
                 "start; the machine hooks every pin of every layer")
    changes = {}
    for prev, le in zip(layers[:-1], layers[1:]):
        last = plan.sequence[le.first_step - 1]
        name = color_name(le.color)
        comment = (f"; spool change {le.index} of {n - 1}: cut the {color_name(prev.color)} ({prev.color}) thread "
                   f"and tie it off at pin {last}; tie on {name} ({le.color}) at pin {le.tie_on_pin} "
                   f"(layer {le.index + 1} of {n}), then resume")
        changes[le.first_step] = (comment, f"Tie {name} on pin {le.tie_on_pin}")
    return lines, changes
