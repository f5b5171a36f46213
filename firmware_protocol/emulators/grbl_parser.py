"""GRBL's G-code parser, as the simulated firmware runs it: words, modal state, error codes.

A block (one line, already stripped of spaces and comments and upcased by the
line reader) is checked the way GRBL 1.1 checks it and either raises
:class:`GrblError` with GRBL's own code or returns the :class:`Action` it
commands (motion to a machine-coordinate target, dwell, program end).  The
parser keeps GRBL's modal state (``$G``), the work coordinate systems
(``G54``..``G59``, persistent like GRBL's EEPROM) and ``G92``, and its own
idea of where the last queued motion ends (``position``), which is what GRBL
plans from.

Arcs (``G2``/``G3``, radius or offset form, in the selected plane) are cut into
straight segments within the arc tolerance (``$12``) as GRBL's ``mc_arc`` does.
Not modelled: probing (``G38.x``),
cutter compensation beyond ``G40``, ``G61``, ``M7`` (a compile-time option, off
in stock builds).
"""

import math
from dataclasses import dataclass, field

from .motion import arc_points

__all__ = ["GrblError", "Action", "ParserState", "GrblParser", "read_words", "fmt"]


class GrblError(Exception):
    """A block GRBL rejects: ``code`` is the number of ``error:N``."""

    def __init__(self, code, detail=""):
        super().__init__(f"error:{code} {detail}".strip())
        self.code = code


@dataclass
class Action:
    """What an accepted block asks of the machine.

    ``kind``: ``"none"``, ``"move"`` (``target`` machine position, ``rapid``,
    ``feed`` units/min, ``inverse_time``), ``"moves"`` (``targets`` list,
    for ``G28``/``G30`` through an intermediate point), ``"dwell"``
    (``seconds``), ``"end"`` (``M2``/``M30``), ``"pause"`` (``M0``/``M1``).
    """

    kind: str = "none"
    target: tuple | None = None
    targets: list = field(default_factory=list)
    rapid: bool = False
    feed: float = 0.0
    inverse_time: bool = False
    seconds: float = 0.0
    line_number: int = 0
    sync: bool = False        # GRBL waits for motion to finish first (an EEPROM write, a WCO change)
    wco: bool = False         # ... and the next status report carries WCO:


@dataclass
class ParserState:
    """GRBL's ``gc_state``: modal groups, feed, spindle, tool and offsets."""

    motion: str = "G0"
    coord: int = 0            # 0..5 for G54..G59
    plane: str = "G17"
    units: str = "G21"
    distance: str = "G90"
    feed_mode: str = "G94"
    program: str = "M0"
    spindle: str = "M5"
    coolant: str = "M9"
    tool: int = 0
    feed: float = 0.0
    speed: float = 0.0
    g92: list = field(default_factory=list)
    tlo: float = 0.0

    def report(self):
        """The ``[GC:...]`` line of ``$G`` (without the line end)."""
        return (f"[GC:{self.motion} G{54 + self.coord} {self.plane} {self.units} {self.distance} "
                f"{self.feed_mode} {self.spindle} {self.coolant} T{self.tool} "
                f"F{_rate(self.feed)} S{_rate(self.speed)}]")


def _rate(value):
    return fmt(value, 0)


def fmt(value, decimals):
    """A number as GRBL's ``printFloat`` writes it (no ``-0``)."""
    sign = "-" if value < 0 and round(-value, decimals) != 0 else ""
    return f"{sign}{abs(value):.{decimals}f}"


def read_words(block):
    """Split a cleaned block (``G0X10.5Y2``) into ``[(letter, value_text, value), ...]``.

    Numbers are read as GRBL's ``read_float`` reads them: an optional sign,
    digits with at most one decimal point, up to the first other character
    (so ``X1.2.3`` is ``X1.2`` followed by a stray ``.``).  Raises GrblError 1
    (something else where a letter must be) or 2 (a letter without digits).
    """
    words = []
    i, n = 0, len(block)
    while i < n:
        letter = block[i]
        if not ("A" <= letter <= "Z"):
            raise GrblError(1, f"expected a letter at {block[i:]!r}")
        i += 1
        j = i
        if j < n and block[j] in "+-":
            j += 1
        digits, point = 0, False
        while j < n and (block[j].isdigit() or (block[j] == "." and not point)):
            if block[j] == ".":
                point = True
            else:
                digits += 1
            j += 1
        text = block[i:j]
        if digits == 0:
            raise GrblError(2, f"bad number after {letter}")
        words.append((letter, text, float(text)))
        i = j
    return words


def grbl_split(value):
    """GRBL's ``int_value`` (``uint8_t``, truncated) and ``mantissa`` (``uint16_t``,
    ``round(100 * (value - int_value))``) of a G/M word: ``M999`` is (231, 11264)."""
    int_value = math.trunc(value) & 0xFF
    diff = 100.0 * (value - int_value)
    mantissa = int(math.floor(abs(diff) + 0.5)) * (1 if diff >= 0 else -1)
    return int_value, mantissa & 0xFFFF


_GROUPS = {  # G word -> modal group
    0: "motion", 1: "motion", 2: "motion", 3: "motion", 38: "motion", 80: "motion",
    4: "nonmodal", 10: "nonmodal", 28: "nonmodal", 30: "nonmodal", 53: "nonmodal", 92: "nonmodal",
    17: "plane", 18: "plane", 19: "plane", 90: "distance", 91: "distance", 93: "feed_mode",
    94: "feed_mode", 20: "units", 21: "units", 40: "cutter", 43: "tlo", 49: "tlo",
    54: "coord", 55: "coord", 56: "coord", 57: "coord", 58: "coord", 59: "coord", 61: "control",
}
_M_GROUPS = {0: "stop", 1: "stop", 2: "stop", 30: "stop", 3: "spindle", 4: "spindle", 5: "spindle",
             8: "coolant", 9: "coolant"}
_VALUE_LETTERS = "FIJKLNPRST"


def _g_word(value, text):
    """(modal group, key) of a G word, with GRBL's checks in GRBL's order: an unknown number is
    error:20, a decimal GRBL does not know error:20 or 23.  ``key`` is the number, or
    ``(number, tenths)`` for G28.1, G30.1, G92.1, G38.x, G43.1; G91.1 is ``"arc_distance"``."""
    ival, mant = grbl_split(value)
    group = _GROUPS.get(ival)
    if group is None:
        raise GrblError(20, f"G{text}")
    if ival in (28, 30, 92) and mant not in (0, 10):
        raise GrblError(20, f"G{text}")
    if ival == 38 and mant not in (20, 30, 40, 50):
        raise GrblError(20, f"G{text}")
    if ival in (90, 91) and mant:
        if mant != 10 or ival == 90:
            raise GrblError(20, f"G{text}")
        return "arc_distance", (91, 1)          # G91.1: IJK incremental, GRBL's only arc mode
    if (ival == 43 and mant != 10) or (ival == 61 and mant):
        raise GrblError(20, f"G{text}")
    if mant and ival not in (28, 30, 92, 38, 43):
        raise GrblError(23, f"G{text}")
    return group, ival if not mant else (ival, mant // 10)


class GrblParser:
    """GRBL's parser and its state for ``axes`` (e.g. ``"XYZ"`` or ``"XYZA"``).

    ``coord_systems`` (G54..G59, G28, G30 stored positions) survive resets like
    GRBL's EEPROM; everything else is reset by :meth:`reset`.
    """

    def __init__(self, axes):
        self.axes = axes
        n = len(axes)
        self.coord_systems = [[0.0] * n for _ in range(6)]
        self.g28 = [0.0] * n
        self.g30 = [0.0] * n
        self.position = [0.0] * n
        self.state = ParserState(g92=[0.0] * n)
        self.arc_tolerance = 0.002      # GRBL $12, mm

    def reset(self, position):
        """Soft reset: default modal state, G92 cleared, planning from ``position``."""
        self.state = ParserState(g92=[0.0] * len(self.axes))
        self.position = list(position)

    def wco(self):
        """Work coordinate offset: active coordinate system + G92 (+ TLO on Z)."""
        off = [c + g for c, g in zip(self.coord_systems[self.state.coord], self.state.g92)]
        if "Z" in self.axes:
            off[self.axes.index("Z")] += self.state.tlo
        return off

    # ---- the block -----------------------------------------------------------------------
    def execute(self, block):
        """Check and apply one cleaned block; returns an :class:`Action` or raises GrblError.

        A block that writes offsets to EEPROM or changes the work coordinate offset
        (``G10``, ``G28.1``/``G30.1``, ``G92``/``G92.1``, another ``G54``..``G59``, a new
        tool length offset) comes with ``sync`` (and ``wco``): GRBL 1.1's
        ``FORCE_BUFFER_SYNC_DURING_EEPROM_WRITE`` / ``..._WCO_CHANGE`` make it wait for
        motion to finish, and the next status report shows ``WCO:``.
        """
        self._sync = self._wco = False
        action = self._execute(block)
        action.sync, action.wco = self._sync, self._wco
        return action

    def read_block(self, block):
        """GRBL's step 2, the words of a block: ``(gcodes, mcodes, values, axis_words)`` (dicts by
        modal group or letter), or GrblError for a bad word, a repeat or a modal group conflict."""
        gcodes, mcodes, values, axis_words = {}, {}, {}, {}
        for letter, text, value in read_words(block):
            if letter == "G":
                group, key = _g_word(value, text)
                if group in gcodes:
                    raise GrblError(21, f"G{text}")
                gcodes[group] = key
            elif letter == "M":
                ival, mant = grbl_split(value)
                if mant > 0:
                    raise GrblError(23, f"M{text}")
                group = _M_GROUPS.get(ival)
                if group is None:
                    raise GrblError(20, f"M{text}")
                if group in mcodes:
                    raise GrblError(21, f"M{text}")
                mcodes[group] = ival
            elif letter in self.axes:
                if letter in axis_words:
                    raise GrblError(25, letter)
                axis_words[letter] = value
            elif letter in _VALUE_LETTERS:
                if letter == "T" and value > 255:
                    raise GrblError(38)
                if letter in values:
                    raise GrblError(25, letter)
                if letter in "FNPST" and value < 0:
                    raise GrblError(4, letter)
                values[letter] = float(grbl_split(value)[0]) if letter == "L" else value
            else:
                raise GrblError(20, f"{letter}{text}")
        return gcodes, mcodes, values, axis_words

    def _execute(self, block):
        st = self.state
        gcodes, mcodes, values, axis_words = self.read_block(block)
        if "N" in values and values["N"] > 9999999:
            raise GrblError(27)
        used = {"N"}

        nonmodal = gcodes.get("nonmodal")
        motion = gcodes.get("motion")
        axis_command = "nonmodal" if nonmodal in (10, 28, 30, 92) else None
        if motion is not None:
            if axis_command:
                raise GrblError(24)
            axis_command = "motion"
        if isinstance(motion, tuple) and motion[0] == 38:
            raise GrblError(20, "probing is not supported by this simulator")
        if gcodes.get("tlo") == (43, 1) and "Z" not in self.axes:
            raise GrblError(37)

        new_motion = motion if motion is not None else st.motion
        if isinstance(new_motion, str):
            new_motion = int(new_motion[1:])
        if axis_words and axis_command is None:
            axis_command = "motion"
        inches = gcodes.get("units", int(st.units[1:])) == 20
        scale = 25.4 if inches else 1.0
        inverse = gcodes.get("feed_mode", int(st.feed_mode[1:])) == 93

        # feed rate
        feed = st.feed
        if "F" in values:
            used.add("F")
            feed = values["F"] * scale if not inverse else values["F"]
        elif inverse:
            feed = 0.0
        # dwell
        if nonmodal == 4:
            if "P" not in values:
                raise GrblError(28, "G4 needs P")
            used.add("P")
        # G10
        if nonmodal == 10:
            if "L" not in values or "P" not in values:
                raise GrblError(28, "G10 needs L and P")
            if not axis_words:
                raise GrblError(26)
            used.update("LP")
            if values["L"] not in (2, 20):
                raise GrblError(20, "G10 L")
            p = int(values["P"])
            if p != values["P"] or p > 6:
                raise GrblError(29 if p > 6 else 20)
        if nonmodal == 53 and new_motion not in (0, 1):
            raise GrblError(30)
        if nonmodal == 92 and not axis_words:
            raise GrblError(26)
        if "S" in values:
            used.add("S")
        if "T" in values:
            used.add("T")
            if values["T"] > 255:
                raise GrblError(38)
        if new_motion == 80 and axis_words and axis_command == "motion":
            raise GrblError(31)
        move_motion = axis_command == "motion" and new_motion in (0, 1)
        if move_motion and new_motion == 1 and feed == 0.0:
            raise GrblError(22)
        arc = None
        if axis_command == "motion" and new_motion in (2, 3):
            if feed == 0.0:
                raise GrblError(22)
            arc = self._check_arc(gcodes, values, axis_words, used, scale, new_motion == 2)
        unused = set(values) - used
        if unused:
            raise GrblError(36, "".join(sorted(unused)))

        # ---- all checks passed: apply ---------------------------------------------------
        action = Action(line_number=int(values.get("N", 0)))
        if "F" in values or inverse:
            st.feed = feed
        if "S" in values:
            st.speed = values["S"]
        if "T" in values:
            st.tool = int(values["T"])
        for group, code in gcodes.items():
            if group == "motion":
                st.motion = f"G{code}"
            elif group == "plane":
                st.plane = f"G{code}"
            elif group == "distance":
                st.distance = f"G{code}"
            elif group == "feed_mode":
                st.feed_mode = f"G{code}"
            elif group == "units":
                st.units = f"G{code}"
            elif group == "coord":
                if st.coord != code - 54:
                    self._sync = self._wco = True
                st.coord = code - 54
            elif group == "tlo":
                tlo = axis_words.get("Z", 0.0) * scale if code == (43, 1) else 0.0
                if tlo != st.tlo:
                    self._sync = self._wco = True
                st.tlo = tlo
        for group, code in mcodes.items():
            if group == "spindle":
                st.spindle = f"M{code}"
            elif group == "coolant":
                st.coolant = f"M{code}"
        absolute = st.distance == "G90"
        wco = self.wco()

        if nonmodal == 4:
            return Action(kind="dwell", seconds=values["P"], line_number=action.line_number)
        if nonmodal == 10:
            idx = int(values["P"]) - 1 if values["P"] else st.coord
            self._sync, self._wco = True, self._wco or idx == st.coord
            cs = self.coord_systems[idx]
            for axis, value in axis_words.items():
                i = self.axes.index(axis)
                if values["L"] == 2:
                    cs[i] = value * scale
                else:  # L20: current position becomes the given work value
                    cs[i] = self.position[i] - st.g92[i] - value * scale
            return action
        if nonmodal in (92, (92, 1)):
            self._sync = self._wco = True
        if nonmodal in ((28, 1), (30, 1)):
            self._sync = True
        if nonmodal == 92:
            for axis, value in axis_words.items():
                i = self.axes.index(axis)
                st.g92[i] = self.position[i] - self.coord_systems[st.coord][i] - value * scale
            return action
        if nonmodal == (92, 1):
            st.g92 = [0.0] * len(self.axes)
            return action
        if nonmodal in ((28, 1), (30, 1)):
            store = self.g28 if nonmodal == (28, 1) else self.g30
            store[:] = self.position
            return action
        if nonmodal in (28, 30):
            stored = self.g28 if nonmodal == 28 else self.g30
            targets = []
            if axis_words:
                targets.append(self._target(axis_words, scale, absolute, wco))
            targets.append(tuple(stored))
            self.position = list(targets[-1])
            return Action(kind="moves", targets=targets, rapid=True, line_number=action.line_number)
        if arc is not None:
            self.position = list(arc[-1])
            return Action(kind="moves", targets=arc, feed=st.feed, inverse_time=inverse,
                          line_number=action.line_number)
        if move_motion and axis_words:
            use_wco = [0.0] * len(self.axes) if nonmodal == 53 else wco
            target = self._target(axis_words, scale, absolute and True, use_wco,
                                  machine=nonmodal == 53)
            self.position = list(target)
            action.kind = "move"
            action.target = target
            action.rapid = new_motion == 0
            action.feed = st.feed
            action.inverse_time = inverse
        stop = mcodes.get("stop")
        if stop in (2, 30):
            st.program = "M0"
            st.motion, st.coord, st.plane, st.distance, st.feed_mode = "G1", 0, "G17", "G90", "G94"
            st.spindle, st.coolant, st.g92 = "M5", "M9", [0.0] * len(self.axes)
            return Action(kind="end", target=action.target, rapid=action.rapid, feed=action.feed,
                          line_number=action.line_number) if action.kind == "none" else action
        if stop in (0, 1) and action.kind == "none":
            return Action(kind="pause", line_number=action.line_number)
        return action

    def _check_arc(self, gcodes, values, axis_words, used, scale, clockwise):
        """GRBL's arc checks; the arc's points (machine coordinates) or GrblError 32/33/35."""
        st = self.state
        plane = gcodes.get("plane", int(st.plane[1:]))
        a0, a1 = {17: ("X", "Y"), 18: ("Z", "X"), 19: ("Y", "Z")}[plane]
        offset_letter = {"X": "I", "Y": "J", "Z": "K"}
        if a0 not in axis_words and a1 not in axis_words:
            raise GrblError(32)
        absolute = gcodes.get("distance", int(st.distance[1:])) == 90
        coord = gcodes["coord"] - 54 if "coord" in gcodes else st.coord
        wco = [c + g for c, g in zip(self.coord_systems[coord], st.g92)]
        target = self._target(axis_words, scale, absolute, wco)
        i0, i1 = self.axes.index(a0), self.axes.index(a1)
        x, y = target[i0] - self.position[i0], target[i1] - self.position[i1]
        if "R" in values:
            used.add("R")
            r = values["R"] * scale
            if x == 0 and y == 0:
                raise GrblError(33)
            h2 = 4.0 * r * r - x * x - y * y
            if h2 < 0:
                raise GrblError(33)
            h = -math.sqrt(h2) / math.hypot(x, y)
            if not clockwise:
                h = -h
            if r < 0:
                h = -h
            offsets = (0.5 * (x - y * h), 0.5 * (y + x * h))
        else:
            l0, l1 = offset_letter[a0], offset_letter[a1]
            if l0 not in values and l1 not in values:
                raise GrblError(35)
            used.update(letter for letter in (l0, l1) if letter in values)
            offsets = (values.get(l0, 0.0) * scale, values.get(l1, 0.0) * scale)
            r = math.hypot(*offsets)
            delta = abs(math.hypot(x - offsets[0], y - offsets[1]) - r)
            if delta > 0.005 and (delta > 0.5 or delta > 0.001 * r):
                raise GrblError(33)
        tol = self.arc_tolerance

        def segments(angle, radius):
            if 2 * radius <= tol:
                return 1
            return math.floor(abs(0.5 * angle * radius) / math.sqrt(tol * (2 * radius - tol)))
        return arc_points(self.position, target, i0, i1, offsets, clockwise, segments)

    def _target(self, axis_words, scale, absolute, wco, machine=False):
        target = list(self.position)
        for axis, value in axis_words.items():
            i = self.axes.index(axis)
            if machine:
                target[i] = value * scale
            elif absolute:
                target[i] = value * scale + wco[i]
            else:
                target[i] = self.position[i] + value * scale
        return tuple(target)


