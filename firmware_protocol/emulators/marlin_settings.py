"""The simulated Marlin's motion settings: M92, M203, M201, M204, M211, and M500/M501/M502/M503.

Marlin keeps its settings in RAM and, after ``M500``, in EEPROM; at boot it
loads them from EEPROM (``echo:V86 stored settings retrieved ...``) or, when
nothing was stored, from the values it was built with (``echo:Hardcoded
Default Settings Loaded``).  The simulated build is configured as its
machine file says (steps per unit, feeds, accelerations, software endstops
wide enough for the ring's travel); ``--set`` changes what it was built
with.  ``M92`` keeps the position in units and recounts the steps; software
endstops (on at every boot unless built otherwise) clamp a move's target, as
Marlin's ``apply_motion_limits`` does.
"""

import logging

from ..settings import MARLIN_REPORTS, MarlinSettings, m503_lines
from .grbl_system import build_steps

__all__ = ["MarlinSettingsMixin", "factory_settings"]

log = logging.getLogger(__name__)


def factory_settings(machine, axes):
    """The settings a Marlin built for ``machine`` starts with (units/s for feeds, as Marlin)."""
    ring, head = machine["controller.ring_axis"], machine["controller.head_axis"]
    ring_steps, head_steps = build_steps(machine)
    s = MarlinSettings(soft_endstops=True)
    for a in axes:
        if a == ring:
            s.steps[a], s.max_feed[a] = ring_steps, machine["ring.feed_deg_per_min"] / 60.0
            s.max_accel[a] = machine["ring.accel_deg_per_s2"]
            pin0, travel = machine["ring.pin0_angle_deg"], machine["ring.travel_deg"]
            home = machine["controller.home_ring_deg"]
            s.soft_min[a], s.soft_max[a] = min(pin0 - travel, home), max(pin0 + travel, home)
        elif a == head:
            s.steps[a], s.max_feed[a] = head_steps, machine["head.feed_mm_per_min"] / 60.0
            s.max_accel[a] = machine["head.accel_mm_per_s2"]
            ends = [machine["head.in_mm"], machine["head.out_mm"]]
            if machine["controller.home_head_mm"] is not None:
                ends.append(machine["controller.home_head_mm"])
            s.soft_min[a], s.soft_max[a] = min([0.0] + ends), max([200.0] + ends)
        else:
            s.steps[a] = 400.0 if a == "Z" else 80.0
            s.max_feed[a] = 5.0 if a == "Z" else 300.0
            s.max_accel[a] = 100.0 if a == "Z" else 3000.0
            s.soft_min[a], s.soft_max[a] = 0.0, 200.0
    top = max([3000.0, machine["ring.accel_deg_per_s2"], machine["head.accel_mm_per_s2"]])
    s.accel.update({"P": top, "R": 3000.0, "T": top})
    return s


class MarlinSettingsMixin:
    """Settings commands of :class:`~firmware_protocol.emulators.marlin.MarlinEmulator`.

    Attributes: ``factory`` (as built), ``eeprom`` (None until ``M500``),
    ``settings`` (in RAM, what motion uses).
    """

    def _init_settings(self, presets):
        self.factory = factory_settings(self.machine, self.axes)
        self.eeprom = None
        self.settings = self.factory.copy()
        self._build = dict(zip((self.ring_i, self.head_i), build_steps(self.machine)))
        for preset in presets:                     # as built: Configuration.h said so
            code, words = preset.value
            self._set_words(self.factory, code, words, preset.text)
        self.settings = self.factory.copy()
        self._apply_settings()

    def _load_at_boot(self):
        """Boot: RAM from EEPROM (or as built); software endstops as built.  -> the line Marlin says."""
        stored = self.eeprom if self.eeprom is not None else self.factory
        self.settings = stored.copy()
        self.settings.soft_endstops = self.factory.soft_endstops
        self._apply_settings()
        if self.eeprom is None:
            return "echo:Hardcoded Default Settings Loaded"
        return "echo:V86 stored settings retrieved (444 bytes; crc 23981)"

    def _apply_settings(self):
        s = self.settings
        self.steps = [s.steps[a] for a in self.axes]
        self.motion.rates = [s.max_feed[a] * 60.0 for a in self.axes]
        self.motion.accels = [min(s.max_accel[a], s.accel.get("T", s.max_accel[a])) for a in self.axes]
        for i, build in self._build.items():
            self._set_step_scale(i, s.steps[self.axes[i]] / build, keep_steps=False)

    def _set_words(self, s, code, words, text):
        target = {"M92": s.steps, "M203": s.max_feed, "M201": s.max_accel, "M204": s.accel}.get(code)
        if code == "M211":
            if "S" in words:
                s.soft_endstops = bool(words["S"])
            return
        letters = "PRT" if code == "M204" else self.axes
        for letter, value in words.items():
            if letter == "S" and code == "M204":
                target["P"] = target["T"] = value        # the old form: S sets both
            elif letter in letters and value > 0:
                target[letter] = value
            else:
                raise ValueError(f"--set {text!r}: {code} takes {', '.join(letters)} with values > 0")

    def _setting_command(self, code, p):
        """M92 / M203 / M201 / M204 / M211: set what is given, report when nothing is."""
        words = {k: v for k, v in p.items() if v is not None}
        if code == "M211" and "S" not in words or code != "M211" and not words:
            self._report(code)
            return 0
        while not self.motion.empty:               # new limits apply to the blocks planned next
            yield lambda: self.motion.empty
        try:
            self._set_words(self.settings, code, words, code)
        except ValueError:
            log.info("%s: ignored words %s", code, words)
        self._apply_settings()
        return 0

    def _report(self, only=None):
        lines = m503_lines(self.settings, self.axes)
        if only is None:
            for line in lines:
                self._emit(line)
            return
        codes = [code for code, _ in MARLIN_REPORTS]
        start = codes.index(only)
        index = sum(3 if c == "M211" else 2 for c in codes[:start])
        for line in lines[index:index + (3 if only == "M211" else 2)]:
            self._emit(line)

    def _M92(self, p):
        return self._setting_command("M92", p)

    def _M203(self, p):
        return self._setting_command("M203", p)

    def _M201(self, p):
        return self._setting_command("M201", p)

    def _M204(self, p):
        return self._setting_command("M204", p)

    def _M211(self, p):
        return self._setting_command("M211", p)

    def _M500(self, p):
        self.eeprom = self.settings.copy()
        self._emit("echo:Settings Stored (444 bytes; crc 23981)")
        return 0

    def _M501(self, p):
        self._emit(self._load_at_boot().replace("Hardcoded Default Settings Loaded",
                                                "EEPROM empty: Hardcoded Default Settings Loaded"))
        return 0

    def _M502(self, p):
        self.settings = self.factory.copy()
        self._apply_settings()
        self._emit("echo:Hardcoded Default Settings Loaded")
        return 0

    def _M503(self, p):
        self._report()
        return 0

    def _soft_limited(self, target):
        """A move's target clamped to the software endstops when they are on (native positions),
        on the axes homed since the firmware started (Marlin's ``apply_motion_limits`` checks
        ``axis_was_homed``: an axis never homed has no limits to trust)."""
        s = self.settings
        if not s.soft_endstops:
            return target
        out = list(target)
        homed = getattr(self, "homed", set())
        for i, a in enumerate(self.axes):
            lo, hi = s.soft_min.get(a), s.soft_max.get(a)
            if lo is not None and hi is not None and a in homed:
                out[i] = min(max(out[i], lo), hi)
        return out
