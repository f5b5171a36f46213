"""The plans folder as the page sees it: the plans, their previews, estimates and journals.

The folder holds what the command line writes there, by its own names: ``NAME.json`` (a plan)
and ``NAME.png`` (its preview, from ``stringbot plan``), the journals beside the plan
(``NAME.json.journal`` for a real machine, ``NAME.json.dry-run.journal``, and
``NAME.json.simulator.journal`` for the workshop's simulator), the uploaded pictures in
``pictures/`` and the simulators in ``simulator/``.  Nothing here writes a plan: the page
plans with ``stringbot plan``.  An uploaded picture never replaces a file: a name that is
taken by other bytes gets a number (``cat-2.png``).
"""

import hashlib
import logging
import os
from pathlib import Path

from firmware_protocol.machine import MachineFileError, bundled_machines, load_machine

from .._files import sha256_file, write_atomic
from ..errors import BadInput
from ..planner import read_plan
from ..winding.journal import read_journal
from .commands import PICTURES_DIR, Target, check_name, journal_for

__all__ = ["Plans", "machines_list"]

log = logging.getLogger(__name__)

#: Largest picture the page takes (the planner's own limits then apply).
MAX_UPLOAD_BYTES = 64 * 1024 * 1024


def machines_list():
    """The bundled machines, as the page's choice."""
    out = []
    for name in bundled_machines():
        m = load_machine(name)
        out.append({"name": name, "kind": m["controller.dialect"] or m["controller.kind"], "pins": m.pins,
                    "description": m["description"], "homing": bool(m["controller.homing"]),
                    "pitch_deg": m.pitch_deg, "head_in_mm": m["head.in_mm"], "head_out_mm": m["head.out_mm"]})
    return out


def _machine(name):
    try:
        return load_machine(name)
    except (MachineFileError, BadInput):
        return None


class Plans:
    """The plans folder."""

    def __init__(self, folder):
        self.folder = Path(folder)
        self.pictures = self.folder / PICTURES_DIR
        self._cache = {}

    # ---- plans -------------------------------------------------------------------------------
    def path(self, name):
        """The plan file of ``name``; BadInput naming the plans when there is none."""
        name = check_name(name)
        path = self.folder / f"{name}.json"
        if not path.is_file():
            have = ", ".join(self.names()) or "none yet"
            raise BadInput(f"plan {name!r} is not in the plans folder {str(self.folder)!r}; expected one of: {have}")
        return path

    def names(self):
        out = []
        for p in sorted(self.folder.glob("*.json"), key=lambda p: -p.stat().st_mtime):
            if p.name.endswith("-record.json"):
                continue
            if self._read(p) is not None:
                out.append(p.stem)
        return out

    def _read(self, path):
        """The plan at ``path`` (cached by its modification), or None when it is not a plan."""
        try:
            st = path.stat()
        except OSError:
            return None
        key = (str(path), st.st_mtime_ns, st.st_size)
        hit = self._cache.get(key)
        if hit is None:
            try:
                hit = (read_plan(path),)
            except (BadInput, OSError, ValueError):
                hit = (None,)
            if len(self._cache) > 256:
                self._cache.clear()
            self._cache[key] = hit
        return hit[0]

    def plan(self, name):
        plan = self._read(self.path(name))
        if plan is None:
            raise BadInput(f"{name}.json in the plans folder is not a plan stringbot can read")
        return plan

    def info(self, name):
        """What the page shows of plan ``name``: its figures, preview, estimates and journals."""
        plan = self.plan(name)
        s = plan.stats or {}
        machine_name = (plan.parameters or {}).get("machine")
        preview = self.folder / f"{name}.png"
        out = {"name": name, "pins": plan.pins, "frame": plan.frame, "lines": len(plan.chord_list()),
               "steps": len(plan.sequence), "connected": plan.connected, "method": plan.method,
               "colors": list(plan.colors), "background": plan.background, "machine": machine_name,
               "diameter_mm": plan.diameter_mm, "thread_mm": plan.thread_mm, "seconds": s.get("seconds"),
               "source": (plan.source or {}).get("path"),
               "preview": f"/plans/{name}/preview.png?v={int(preview.stat().st_mtime)}" if preview.is_file() else None,
               "estimate": self.estimate(plan, machine_name), "journals": self.journals(name, plan)}
        return out

    def estimate(self, plan, machine_name):
        """Machine time and metres of thread per colour on ``machine_name`` (None without one)."""
        m = _machine(machine_name) if machine_name else None
        if m is None or not plan.connected or plan.frame != "circle" or plan.pins != m.pins:
            return None
        from ..motion import estimate, format_duration
        from ..motion.layers import colour_estimates
        try:
            est = estimate(plan, m)
            colours = colour_estimates(plan, m)
        except BadInput:
            return None
        return {"machine": m.name, "seconds": est.seconds, "time": format_duration(est.seconds),
                "thread_m": round(est.thread_m, 1),
                "colors": [{"color": c.color, "thread_m": round(c.thread_m, 1), "runs": c.runs,
                            "time": format_duration(c.seconds)} for c in colours]}

    def journals(self, name, plan):
        """Each target's journal of the plan: steps done, finished, the last stop; resumable."""
        out = {}
        for target in Target:
            path = self.folder / journal_for(name, target)
            if not path.is_file():
                continue
            try:
                state = read_journal(path)
            except BadInput as exc:
                out[target.value] = {"path": path.name, "error": str(exc)}
                continue
            stop = state.last_stop
            resumed_after = stop is not None and state.resumes and state.resumes[-1].get("t", 0) > stop.get("t", 0)
            out[target.value] = {
                "path": path.name, "machine": state.header.get("machine"), "done": len(state.done),
                "next_step": state.next_step, "total": state.steps_total, "finished": state.finished,
                "moved": state.moved, "resumable": bool(state.moved and not state.finished and target is not
                                                        Target.DRY_RUN),
                "stop": None if stop is None or resumed_after else
                {"reason": stop.get("reason"), "error": stop.get("error"), "step": stop.get("step"),
                 "pin": stop.get("pin"), "layer": stop.get("layer")},
                "same_plan": state.header.get("plan_sha256") == plan.sha256()}
        return out

    def drawing(self, name):
        """What the page draws the piece from: pins, layers (colour, pins), board, thread width."""
        plan = self.plan(name)
        return {"name": name, "pins": plan.pins, "pin_xy": [[round(float(x), 5), round(float(y), 5)]
                                                            for x, y in plan.pin_xy],
                "layers": [{"color": lay.color, "sequence": [int(p) for p in lay.sequence]} for lay in plan.layers],
                "background": plan.background, "connected": plan.connected,
                "thread_fraction": plan.thread_model().fraction}

    def preview(self, name):
        path = self.folder / f"{check_name(name)}.png"
        if not path.is_file():
            raise BadInput(f"plan {name!r} has no preview {path.name!r} in the plans folder")
        return path

    # ---- pictures ----------------------------------------------------------------------------
    def store_picture(self, filename, data):
        """Keep an uploaded picture in ``pictures/`` (never replacing another file); returns
        ``(path relative to the folder, new)``: ``new`` False when those bytes were there already."""
        base = os.path.basename(str(filename or "").replace("\\", "/")) or "picture"
        stem, ext = os.path.splitext(base)
        stem = "".join(c if c.isalnum() or c in "-_" else "-" for c in stem).strip("-_") or "picture"
        ext = "".join(c for c in ext.lower() if c.isalnum() or c == ".")[:6] or ".png"
        if not data:
            raise BadInput(f"picture {base!r} is an empty file (0 bytes); expected a picture (PNG, JPEG, ...)")
        if len(data) > MAX_UPLOAD_BYTES:
            raise BadInput(f"picture {base!r} is {len(data) / 1e6:.0f} MB; expected at most "
                           f"{MAX_UPLOAD_BYTES // (1024 * 1024)} MB")
        self.pictures.mkdir(parents=True, exist_ok=True)
        digest = hashlib.sha256(data).hexdigest()
        for n in range(1, 1000):
            name = check_name(f"{stem}{ext}" if n == 1 else f"{stem}-{n}{ext}", what="picture name")
            path = self.pictures / name
            if not os.path.lexists(path):
                write_atomic(path, data, what="picture")
                return f"{PICTURES_DIR}/{name}", True
            if path.is_file() and not path.is_symlink() and sha256_file(path) == digest:
                return f"{PICTURES_DIR}/{name}", False
        raise BadInput(f"picture {base!r}: a thousand pictures of that name are kept already; give it another name")

    def picture_names(self):
        if not self.pictures.is_dir():
            return []
        return sorted(p.name for p in self.pictures.iterdir() if p.is_file())

    def picture(self, name):
        """An already uploaded picture, by its file name (relative path)."""
        name = check_name(name, what="picture name")
        if not (self.pictures / name).is_file():
            raise BadInput(f"picture {name!r} is not in {str(self.pictures)!r}; expected an upload, or one of: "
                           + (", ".join(self.picture_names()) or "none yet"))
        return f"{PICTURES_DIR}/{name}"
