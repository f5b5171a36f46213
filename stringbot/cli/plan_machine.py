"""The machine a plan is used with (``wind``, ``gcode``, ``pins``, ``estimate``), and whether they agree.

The machine is ``--machine`` or, without it, the one the plan was made for
(``parameters.machine``, written by ``plan --machine``).  A plan keeps the
picture as woven by a thread of ``thread_mm`` on a frame of ``diameter_mm``
(500 mm and 0.25 mm for a plan that does not say, the planner's defaults): on
a machine whose thread is another fraction of its ring the piece comes out
darker (a thicker thread for the frame) or lighter than the plan's preview.
More than :data:`TOLERANCE` apart is refused, naming the command that plans
the picture for this machine, unless ``--force``.
"""

import os
import shlex

from ..errors import BadInput

__all__ = ["TOLERANCE", "plan_machine", "machine_for", "check_thread", "thread_difference", "replan_command"]

#: How far the machine's thread-to-diameter ratio may be from the plan's (relative).
TOLERANCE = 0.05


def plan_machine(plan, plan_path, machine):
    """The :class:`~firmware_protocol.machine.Machine` to use ``plan`` with: ``machine`` (``--machine``
    as given), or when None the plan's ``parameters.machine``.  ``plan_path`` names the plan in
    messages and finds a machine file the plan names by a path relative to its folder.

    Raises
    ------
    BadInput
        No machine given or named, or a named machine that cannot be loaded.
    """
    from firmware_protocol.machine import load_machine

    return load_machine(machine) if machine is not None else _named_machine(plan, plan_path)


def machine_for(plan_path, machine):
    """:func:`plan_machine` for a plan not read yet (it is read only when ``machine`` is None)."""
    from firmware_protocol.machine import load_machine

    from ..planner.plan_file import read_plan

    return load_machine(machine) if machine is not None else _named_machine(read_plan(plan_path), plan_path)


def _named_machine(plan, plan_path):
    from firmware_protocol.machine import MachineFileError, load_machine

    named = plan.parameters.get("machine")
    if not isinstance(named, str) or not named:
        raise BadInput(f"plan {plan_path!r} names no machine (it was made without --machine); give --machine "
                       "NAME (see `stringbot machines`) or a machine file")
    try:
        return load_machine(named)
    except MachineFileError as exc:
        beside = os.path.join(os.path.dirname(os.path.abspath(plan_path)), named)
        if not os.path.isabs(named) and os.path.isfile(beside):
            return load_machine(beside)       # a machine file named relative to where the plan was made
        raise BadInput(f"plan {plan_path!r} was made for machine {named!r} (its parameters.machine), which "
                       f"cannot be loaded ({exc}); give --machine NAME or the machine file's path") from None


def ratios(plan, machine):
    """(the plan's, the machine's) thread-to-diameter ratio; the machine's thread is the width `plan --machine`
    draws it at (``thread.effective_mm`` once calibrated, else ``thread.diameter_mm``)."""
    model = plan.thread_model()
    return model.thread_mm / model.diameter_mm, machine[machine.thread_width_key] / machine["ring.diameter_mm"]


def thread_difference(plan, machine):
    """How much thicker (> 0) or thinner (< 0) the machine's thread is for its ring than the plan's
    for its frame, as a fraction (0.1: 10 % thicker)."""
    planned, actual = ratios(plan, machine)
    return actual / planned - 1.0


def check_thread(plan, plan_path, machine):
    """Raise :class:`BadInput` when the plan's thread-to-diameter ratio differs from the machine's
    by more than :data:`TOLERANCE` of the machine's."""
    planned, actual = ratios(plan, machine)
    if abs(planned - actual) <= (TOLERANCE + 1e-9) * actual:
        return
    d = thread_difference(plan, machine)
    model = plan.thread_model()
    how = "thicker" if d > 0 else "thinner"
    looks = "darker" if d > 0 else "lighter"
    named = plan.parameters.get("machine")
    made = f" (made for machine {named!r})" if isinstance(named, str) and named != machine.name else ""
    raise BadInput(
        f"plan {plan_path!r}{made} is for a {model.thread_mm:g} mm thread on a {model.diameter_mm:g} mm frame but "
        f"machine {machine.name!r} winds a {machine[machine.thread_width_key]:g} mm thread"
        f"{' (its calibrated effective width)' if machine.thread_width_key == 'thread.effective_mm' else ''} on a "
        f"{machine['ring.diameter_mm']:g} mm ring: for its size the thread is {abs(d) * 100:.0f} % {how}, so the "
        f"piece would come out {looks} than the plan's preview; plan it for this machine: "
        f"{replan_command(plan, plan_path, machine)} (or --force to use this plan anyway)")


def replan_command(plan, plan_path, machine):
    """``stringbot plan SOURCE -o NEW --machine NAME [--colors ...]``: the plan's picture, planned for
    ``machine``, beside the plan (a new file: the plan itself stays)."""
    src = plan.source.get("path")
    name = machine.name
    ref = name if _bundled(name) else (machine.path or name)
    stem, ext = os.path.splitext(plan_path)
    parts = ["stringbot", "plan", str(src or "PICTURE"), "-o", f"{stem}-{_slug(name)}{ext or '.json'}",
             "--machine", str(ref)]
    if not plan.is_mono:
        asked = plan.parameters.get("colors_requested")
        parts += ["--colors", asked if isinstance(asked, str) and asked else ",".join(plan.colors)]
        if plan.background != "#ffffff":
            parts += ["--background", plan.background]
    return " ".join(shlex.quote(p) for p in parts)


def _bundled(name):
    from firmware_protocol.machine import bundled_machines
    return name in bundled_machines()


def _slug(name):
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in str(name)) or "machine"
