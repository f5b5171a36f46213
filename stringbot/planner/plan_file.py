"""The plan file: the contract between the planner and everything else (docs/design.md).

A plan is JSON::

    {"format": "stringbot-plan", "version": 1, "pins": 300, "frame": "circle",
     "pin_xy": [[x, y], ...], "crop": {"cx": .., "cy": .., "r": ..},
     "sequence": [0, 151, 17, ...], "method": "fitness", "parameters": {...},
     "source": {"path": .., "sha256": .., "width": .., "height": ..}, "stats": {...}}

Optional since the thread model: ``diameter_mm`` (the frame's diameter, the
side of a square frame) and ``thread_mm`` (the thread's width), from which
``render`` draws the plan as woven; a plan without them is read with the
defaults, 500 mm and 0.25 mm.

A disconnected plan (``--disconnected``) has ``"connected": false`` and a chord
set ``"chords": [[i, j], ...]`` instead of a sequence; it can be rendered and
scored but not wound.  Unknown fields are ignored (kept in ``extra``); a wrong
or missing required field is a :class:`~stringbot.errors.BadInput` naming it.

Version 2 (colour) has, instead of ``sequence``, the layers in winding order
(later layers lie on top), each one continuous thread, and the board::

    {"format": "stringbot-plan", "version": 2, ...,
     "layers": [{"color": "#1b2550", "sequence": [0, 151, ...]}, {"color": "#c8102e", "sequence": [...]}],
     "background": "#ffffff", ...}

Every plan has layers: a version 1 plan is one layer of black thread
(``#000000``) on a white board, and a plan that is exactly that is still
written as version 1 (so that every reader of version 1 reads it).
:attr:`Plan.sequence` is the pins in the order the machine hooks them: the
layers one after the other (for one layer, its sequence); a chord joins two
pins of the same layer only (:meth:`Plan.chord_list`).
"""

import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._files import write_atomic
from ..errors import BadInput
from .model.thread import ThreadModel

__all__ = ["Plan", "Layer", "read_plan", "write_plan", "FORMAT", "VERSION", "VERSIONS", "MONO_COLOR",
           "MONO_BACKGROUND", "require_one_layer"]

FORMAT = "stringbot-plan"
VERSION = 1          # what a black-on-white, one-layer plan is written as
VERSIONS = (1, 2)    # what is read
FRAMES = ("circle", "square")
MONO_COLOR, MONO_BACKGROUND = "#000000", "#ffffff"
_HEX = re.compile(r"^#[0-9a-f]{6}$")
#: The frame and thread a plan that does not record them was planned for: what ``plan`` used
#: before plans carried ``diameter_mm`` and ``thread_mm``.  Apart from the planner's defaults
#: (thread.DEFAULT_*) on purpose: changing those must not change how an old plan is read.
UNRECORDED_DIAMETER_MM, UNRECORDED_THREAD_MM = 500.0, 0.25


@dataclass(frozen=True)
class Layer:
    """One thread of a plan: its colour and its pins in winding order.

    Attributes
    ----------
    color : str
        ``"#rrggbb"``.
    sequence : list of int
    """

    color: str
    sequence: list[int]

    def chords(self) -> list[tuple[int, int]]:
        """The layer's chords as ``(i, j)`` pairs, in winding order."""
        return list(zip(self.sequence[:-1], self.sequence[1:]))


@dataclass
class Plan:
    """A planned thread painting.

    Attributes
    ----------
    pins : int
        Number of pins on the frame.
    frame : {"circle", "square"}
    pin_xy : ndarray of float, shape (pins, 2)
        Pin positions normalised to the cropped square: x right, y down, in [0, 1].
    crop : dict
        ``{"cx", "cy", "r"}`` in source-image pixels.
    sequence : list of int
        Pins in winding order; each consecutive pair is a chord.  Empty when
        ``connected`` is false.
    method : str
    parameters : dict
        Every knob the planner used.
    source : dict
        ``{"path", "sha256", "width", "height"}`` of the source picture.
    stats : dict
        ``lines``, ``thread_diameters`` (thread length in ring diameters), ...
    connected : bool
        False for a chord set (``chords``) that cannot be wound.
    chords : list of (int, int)
        The chord set of a disconnected plan.
    colors : list of str
        The colour of each layer's thread (``"#rrggbb"``), in winding order.
    layer_starts : list of int
        Where each layer starts in ``sequence`` (the first is 0).
    background : str
        The board, ``"#rrggbb"``.
    diameter_mm, thread_mm : float or None
        The frame's diameter and the thread's width (see :mod:`stringbot.planner.model.thread`);
        None where the plan does not record them (drawn with 500 mm and 0.25 mm).
    woven_drawings : callable or None
        ``woven_drawings(size, board, thread)``: the drawing as woven
        (:func:`~stringbot.planner.model.render.draw_woven`) made already by the
        polish's helper process, or None.  Not saved.
    """

    pins: int
    frame: str
    pin_xy: np.ndarray
    crop: dict[str, Any]
    sequence: list[int]
    method: str
    parameters: dict[str, Any] = field(default_factory=dict)
    source: dict[str, Any] = field(default_factory=dict)
    stats: dict[str, Any] = field(default_factory=dict)
    connected: bool = True
    chords: list[tuple[int, int]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)
    diameter_mm: float | None = None
    thread_mm: float | None = None
    colors: list[str] = field(default_factory=lambda: [MONO_COLOR])
    layer_starts: list[int] = field(default_factory=lambda: [0])
    background: str = MONO_BACKGROUND
    #: the drawing as woven, when the polish's helper made it (not saved)
    woven_drawings: object = field(default=None, repr=False, compare=False)

    def thread_model(self) -> ThreadModel:
        """The plan's :class:`~stringbot.planner.model.thread.ThreadModel` (500 mm / 0.25 mm where not recorded)."""
        return ThreadModel(diameter_mm=float(self.diameter_mm or UNRECORDED_DIAMETER_MM),
                           thread_mm=float(self.thread_mm or UNRECORDED_THREAD_MM))

    @classmethod
    def from_layers(cls, layers, *, background=MONO_BACKGROUND, **kw):
        """A plan of ``layers`` (:class:`Layer` or ``(color, sequence)``, winding order)."""
        layers = [lay if isinstance(lay, Layer) else Layer(*lay) for lay in layers]
        starts, seq = [], []
        for lay in layers:
            starts.append(len(seq))
            seq += [int(p) for p in lay.sequence]
        return cls(sequence=seq, colors=[lay.color for lay in layers], layer_starts=starts,
                   background=background, **kw)

    @property
    def layers(self) -> list[Layer]:
        """The layers in winding order (one for a mono plan)."""
        ends = list(self.layer_starts[1:]) + [len(self.sequence)]
        return [Layer(c, list(self.sequence[a:b])) for c, a, b in zip(self.colors, self.layer_starts, ends)]

    @property
    def is_mono(self) -> bool:
        """One layer of black thread on a white board: what version 1 describes."""
        return len(self.colors) == 1 and self.colors[0] == MONO_COLOR and self.background == MONO_BACKGROUND

    @property
    def version(self) -> int:
        return 1 if self.is_mono else 2

    def layer_of(self, step: int) -> int:
        """The layer (0..) that step ``step`` (an index into ``sequence``) belongs to."""
        k = 0
        while k + 1 < len(self.layer_starts) and self.layer_starts[k + 1] <= step:
            k += 1
        return k

    def chord_list(self) -> list[tuple[int, int]]:
        """All chords as a list of ``(i, j)`` pairs, connected or not (never from one layer to the next)."""
        if self.connected:
            if len(self.layer_starts) == 1:
                return list(zip(self.sequence[:-1], self.sequence[1:]))
            return [c for lay in self.layers for c in lay.chords()]
        return [(c[0], c[1]) for c in self.chords]

    def to_json(self) -> str:
        doc = dict(self.extra)
        doc.update({
            "format": FORMAT,
            "version": self.version,
            "pins": int(self.pins),
            "frame": self.frame,
            "pin_xy": [[round(float(x), 6), round(float(y), 6)] for x, y in np.asarray(self.pin_xy)],
            "crop": self.crop,
            "connected": bool(self.connected),
            "sequence": [int(p) for p in self.sequence],
            "method": self.method,
            "parameters": self.parameters,
            "source": self.source,
            "stats": self.stats,
        })
        for key in ("diameter_mm", "thread_mm"):
            if getattr(self, key) is not None:
                doc[key] = float(getattr(self, key))
        if not self.connected:
            doc["chords"] = [[int(i), int(j)] for i, j in self.chords]
        if self.version == 2:
            del doc["sequence"]
            doc["layers"] = [{"color": lay.color, "sequence": [int(p) for p in lay.sequence]}
                             for lay in self.layers]
            doc["background"] = self.background
        return json.dumps(doc, indent=1, sort_keys=False) + "\n"

    def sha256(self) -> str:
        """Hash of what the machine would do: pins, frame and the chords, in order (and the threads)."""
        h = hashlib.sha256()
        what = [self.pins, self.frame, self.connected, [int(p) for p in self.sequence],
                [[int(i), int(j)] for i, j in self.chords]]
        if not self.is_mono:
            what += [list(self.colors), [int(s) for s in self.layer_starts], self.background]
        h.update(json.dumps(what).encode())
        return h.hexdigest()


def require_one_layer(plan, what):
    """Raise :class:`BadInput` for a plan of several layers given to ``what``, which winds or draws one thread."""
    if len(plan.colors) > 1:
        raise BadInput(f"{what} works on a plan of one thread, but this plan has {len(plan.colors)} colour "
                       f"layers ({', '.join(plan.colors)}); expected a one-colour plan")


def write_plan(plan, path):
    """Write ``plan`` to ``path`` atomically (temp file, fsync, rename)."""
    write_atomic(path, plan.to_json())


def _need(doc, key, types, where, expected):
    if key not in doc:
        raise BadInput(f"{where}: missing field {key!r}; expected {expected}")
    value = doc[key]
    if isinstance(value, bool) and bool not in (types if isinstance(types, tuple) else (types,)):
        raise BadInput(f"{where}: field {key!r} is {value!r}; expected {expected}")
    if not isinstance(value, types):
        raise BadInput(f"{where}: field {key!r} is {type(value).__name__}; expected {expected}")
    return value


def _is_num(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def read_plan(path):
    """Read and check a plan file.

    Raises
    ------
    BadInput
        If the file is missing, is not JSON, or breaks the contract; the message
        names the field and the expected form.
    """
    path = Path(path)
    where = f"plan {str(path)!r}"
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise BadInput(f"{where} does not exist") from None
    except IsADirectoryError:
        raise BadInput(f"{where} is a folder; expected a plan file (JSON)") from None
    except UnicodeDecodeError:
        raise BadInput(f"{where} is not a text file (a picture?); expected a plan file (JSON)") from None
    except OSError as exc:
        raise BadInput(f"{where} cannot be read as text: {exc}; expected a plan file (JSON)") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise BadInput(f"{where} is not JSON ({exc.msg}: line {exc.lineno} column {exc.colno}); expected a "
                       "plan file") from None
    return plan_from_json(doc, where=where)


def plan_from_json(doc, *, where="plan"):
    """Check a decoded plan document and build a :class:`Plan`."""
    if not isinstance(doc, dict):
        raise BadInput(f"{where}: top level is {type(doc).__name__}; expected a JSON object")
    if "format" not in doc:
        raise BadInput(f"{where}: missing field 'format'; expected {FORMAT!r} (is this a stringbot plan?)")
    if doc.get("format") != FORMAT:
        raise BadInput(f"{where}: field 'format' is {doc.get('format')!r}; expected {FORMAT!r}")
    version = _need(doc, "version", int, where, "an integer")
    if version not in VERSIONS:
        raise BadInput(f"{where}: version {version} is not one this stringbot reads; expected "
                       f"{' or '.join(map(str, VERSIONS))}")
    if version == 2:
        where = f"{where} (version 2)"
    pins = _need(doc, "pins", int, where, "an integer >= 3")
    if pins < 3:
        raise BadInput(f"{where}: field 'pins' is {pins}; expected an integer >= 3")
    frame = _need(doc, "frame", str, where, f"one of {', '.join(FRAMES)}")
    if frame not in FRAMES:
        raise BadInput(f"{where}: field 'frame' is {frame!r}; expected one of {', '.join(FRAMES)}")
    pin_xy = _need(doc, "pin_xy", list, where, "a list of [x, y] pairs")
    if len(pin_xy) != pins or not all(
            isinstance(p, list) and len(p) == 2 and all(_is_num(v) and -1e-9 <= v <= 1 + 1e-9 for v in p)
            for p in pin_xy):
        raise BadInput(f"{where}: field 'pin_xy' must be {pins} pairs [x, y] with x and y in [0, 1]")
    crop = _need(doc, "crop", dict, where, "an object {cx, cy, r}")
    for k in ("cx", "cy", "r"):
        if not _is_num(crop.get(k)):
            raise BadInput(f"{where}: field 'crop.{k}' is {crop.get(k)!r}; expected a number")
    connected = doc.get("connected", True)
    if not isinstance(connected, bool):
        raise BadInput(f"{where}: field 'connected' is {connected!r}; expected true or false")
    colors, starts, background = [MONO_COLOR], [0], MONO_BACKGROUND
    if version == 2:
        if not connected:
            raise BadInput(f"{where}: field 'connected' is false; expected a connected plan (layers of threads)")
        layers = _need(doc, "layers", list, where, 'a list of {"color": "#rrggbb", "sequence": [...]}')
        if not layers:
            raise BadInput(f"{where}: field 'layers' is empty; expected at least one layer")
        colors, starts, sequence = [], [], []
        for k, lay in enumerate(layers):
            if not isinstance(lay, dict):
                raise BadInput(f"{where}: layers[{k}] is {type(lay).__name__}; expected "
                               '{"color": "#rrggbb", "sequence": [...]}')
            color = lay.get("color")
            if not isinstance(color, str) or not _HEX.match(color):
                raise BadInput(f"{where}: layers[{k}].color is {color!r}; expected \"#rrggbb\" (lower-case hex)")
            seq = _need(lay, "sequence", list, f"{where}: layers[{k}]", "a list of pin indices")
            _check_sequence(seq, pins, f"{where}: layers[{k}].")
            colors.append(color)
            starts.append(len(sequence))
            sequence += seq
        background = doc.get("background")
        if not isinstance(background, str) or not _HEX.match(background):
            raise BadInput(f"{where}: field 'background' is {background!r}; expected \"#rrggbb\" (lower-case hex)")
    else:
        sequence = _need(doc, "sequence", list, where, "a list of pin indices")
    chords = []
    if connected:
        if version == 1:
            _check_sequence(sequence, pins, f"{where}: ")
    else:
        raw = _need(doc, "chords", list, where, "a list of [i, j] pin pairs")
        for k, c in enumerate(raw):
            if (not isinstance(c, list) or len(c) != 2
                    or not all(isinstance(p, int) and not isinstance(p, bool) and 0 <= p < pins for p in c)
                    or c[0] == c[1]):
                raise BadInput(f"{where}: chords[{k}] is {c!r}; expected [i, j] with i != j in 0..{pins - 1}")
            chords.append((c[0], c[1]))
    size = {}
    for key in ("diameter_mm", "thread_mm"):
        if key not in doc:
            size[key] = None
            continue
        v = doc[key]
        if not (_is_num(v) and v > 0):
            raise BadInput(f"{where}: field {key!r} is {v!r}; expected a number of millimetres > 0")
        size[key] = float(v)
    if (size["thread_mm"] or UNRECORDED_THREAD_MM) >= (size["diameter_mm"] or UNRECORDED_DIAMETER_MM):
        raise BadInput(f"{where}: field 'thread_mm' is not less than 'diameter_mm'; "
                       "expected a thread thinner than the frame")
    method = _need(doc, "method", str, where, "a string")
    parameters = _need(doc, "parameters", dict, where, "an object")
    source = _need(doc, "source", dict, where, "an object {path, sha256, width, height}")
    stats = _need(doc, "stats", dict, where, "an object")
    known = {"format", "version", "pins", "frame", "pin_xy", "crop", "connected", "sequence",
             "chords", "method", "parameters", "source", "stats", "layers", "background"}
    # diameter_mm, thread_mm also stay in extra: whether the plan recorded them (not just the
    # defaults) is for its readers to tell
    extra = {k: v for k, v in doc.items() if k not in known}
    return Plan(pins=pins, frame=frame, pin_xy=np.asarray(pin_xy, dtype=float), crop=crop,
                sequence=list(sequence), method=method, parameters=parameters, source=source,
                stats=stats, connected=connected, chords=chords, extra=extra, colors=colors,
                layer_starts=starts, background=background, **size)


def _check_sequence(sequence, pins, where):
    if len(sequence) < 2:
        raise BadInput(f"{where}field 'sequence' has {len(sequence)} pins; expected at least 2")
    for k, p in enumerate(sequence):
        if not isinstance(p, int) or isinstance(p, bool) or not 0 <= p < pins:
            raise BadInput(f"{where}sequence[{k}] is {p!r}; expected a pin index in 0..{pins - 1}")
        if k and p == sequence[k - 1]:
            raise BadInput(f"{where}sequence[{k}] repeats pin {p}; expected no pin twice in a row")
