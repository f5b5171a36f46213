"""An operator for tests and benchmarks: answers as a person looking at the machine would.

``look()`` returns what the person sees -- the simulated world's physical ring
angle and head position (``World.record()`` in process, or the record file
written by ``stringbot simulate --record`` in another process) -- and nothing
else: never the journal, never the host's objects.  The answers follow the
host's words: the side of the eyelet, whether a declared position is where the
machine stands, which pin faces the head, and the jog commands that bring the
machine to the reference the guide asks for (the gap it names to bring the
head IN through, then the pin it names at the station).
"""

import json
import re

__all__ = ["ScriptedOperator", "record_looker", "world_looker"]


def world_looker(world_of):
    """``look`` from a live World (``world_of()`` returns it)."""
    def look():
        w = world_of()
        return {"ring_deg": w.ring_deg, "head_mm": w.head_mm}
    return look


def record_looker(path):
    """``look`` from a record file written by another process."""
    def look():
        rec = json.loads(open(path, encoding="utf-8").read())
        return {"ring_deg": rec["ring_deg"], "head_mm": rec["head_mm"]}
    return look


class ScriptedOperator:
    """confirm / choose / jog / say for ``resume_plan`` (or the CLI's prompts), from ``look()``."""

    def __init__(self, machine, look, *, max_jogs=20):
        self.m, self.look = machine, look
        self.asked, self.told, self.jogs = [], [], []
        self.max_jogs = max_jogs
        self._pin = self._gap = None

    # ---- what the operator sees --------------------------------------------------------------
    def _seen(self):
        v = self.look()
        return float(v["ring_deg"]), float(v["head_mm"])

    def side(self):
        """"in" or "out" as the eyelet looks: nearer IN or OUT (for moving it)."""
        m = self.m
        _, head = self._seen()
        return "out" if abs(head - m["head.out_mm"]) < abs(head - m["head.in_mm"]) else "in"

    def clear_side(self):
        """The side a person would *state*: "in"/"out" only when the eyelet is clearly there
        (within a quarter of the stroke of IN or OUT); None when it stands among the pins."""
        m = self.m
        _, head = self._seen()
        quarter = abs(m["head.out_mm"] - m["head.in_mm"]) / 4
        if abs(head - m["head.in_mm"]) <= quarter:
            return "in"
        if abs(head - m["head.out_mm"]) <= quarter:
            return "out"
        return None

    def _angle(self, units, ring):
        """The physical ring angle nearest ``ring`` that puts ``units`` (pin units) at the station."""
        m = self.m
        a = m["ring.pin0_angle_deg"] + units * m.pitch_deg
        return a + 360.0 * round((ring - a) / 360.0)

    def facing(self):
        m = self.m
        ring, _ = self._seen()
        return round((ring - m["ring.pin0_angle_deg"]) / m.pitch_deg) % m.pins

    # ---- answers ------------------------------------------------------------------------------
    def say(self, text):
        self.told.append(text)
        pin = re.search(r"pin (\d+) facing the head station", text)
        gap = re.search(r"the gap between pins (\d+) and (\d+) faces the head", text)
        if pin:
            self._pin = int(pin.group(1))
            self._gap = int(gap.group(1)) if gap else None

    def at_gap(self):
        """A gap between two pins faces the head (within half the machine's gap tolerance)."""
        m = self.m
        ring, _ = self._seen()
        p = (ring - m["ring.pin0_angle_deg"]) / m.pitch_deg
        return abs(p - (round(p - 0.5) + 0.5)) * m.pitch_deg <= m.gap_tolerance_deg / 2

    def choose(self, question, choices):
        self.asked.append(question)
        if "gap" in choices:               # before homing: IN, OUT at a gap, or be guided
            side = self.clear_side()
            if side == "in":
                return "in"
            if side == "out" and self.at_gap():
                return "gap"
            return "guide" if "guide" in choices else choices[0]
        if "in" in choices and "out" in choices:
            side = self.clear_side()
            return side if side is not None or "guide" not in choices else "guide"
        # a servo turn: which of these pins faces the head?
        return str(self.facing()) if str(self.facing()) in choices else choices[0]

    def confirm(self, question):
        self.asked.append(question)
        m = self.m
        ring, head = self._seen()
        declared = re.search(r"ring at (-?[\d.]+) deg .* with the head (IN|OUT)", question)
        if declared:
            r = float(declared.group(1))
            off = abs((ring - r + 180.0) % 360.0 - 180.0)
            return off < m.pitch_deg / 4 and self.clear_side() == declared.group(2).lower()
        faces = re.search(r"Pin (\d+) faces the head station and the head is IN", question)
        if faces:
            return self.facing() == int(faces.group(1)) and self.side() == "in"
        if re.search(r"The head is IN \(the eyelet inside the pin circle\)\?", question):
            return self.clear_side() == "in"
        return True

    def jog(self, prompt):
        """The next jog command towards the reference the guide named."""
        if len(self.jogs) >= self.max_jogs:
            return "quit"
        m = self.m
        ring, head = self._seen()
        h_in = m["head.in_mm"]
        tol = m.gap_tolerance_deg / 4
        close = 0.05                       # as near as a person gets it (a stepper stops on whole steps)
        if self.side() == "out" or abs(head - h_in) > close:
            if self.side() == "out":
                units = (self._gap + 0.5) if self._gap is not None else round(
                    (ring - m["ring.pin0_angle_deg"]) / m.pitch_deg - 0.5) + 0.5
                target = self._angle(units, ring)
                if abs(target - ring) > tol:
                    return self._did(f"ring {target - ring:+.4f}")
            return self._did(f"head {h_in - head:+.4f}")
        if self._pin is not None:
            target = self._angle(self._pin, ring)
            if abs(target - ring) > close:
                return self._did(f"ring {target - ring:+.4f}")
        return "done"

    def _did(self, cmd):
        self.jogs.append(cmd)
        return cmd
