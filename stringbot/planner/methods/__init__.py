"""The planner's methods: the registry that names them, and each method behind it.

``stringbot plan --method`` (its choices and help), the knob checks of
:func:`~stringbot.planner.build.plan_picture`, docs/planner.md (a test checks
that every method has its section there) and the benchmarks read
:data:`METHODS`.  Light on purpose (no numpy): the command line imports it at
start; a method's module is imported when it runs.

Each method is run through one contract: ``run(job)`` (the registry's
``run = "module:function"``) with a :class:`Job` (the chord space, the picture
read at the method's working size, the frame mask, the importance weights,
the line count, the start pin, the thread model and every knob) returns
``(sequence, params, stats)``: the pins in winding order (a list of int, no
pin twice in a row), the knobs it used (recorded in the plan's
``parameters``) and its figures (the plan's ``stats``); or an
:class:`Outcome` when it has more (a chord set that is not one thread, the
drawings it made meanwhile).

The methods: :mod:`.residual` (the default, with :mod:`.canvas`, :mod:`.refine`,
:mod:`.polish`, :mod:`.woven`, :mod:`.woven_helper` and :mod:`.eye`),
:mod:`.euler` (a chord set made one thread, then the same polish), :mod:`.fitness` (the paper's, with
:mod:`.sampling`) and :mod:`.greedy` (ThreadTone's).
"""

from dataclasses import dataclass, field

__all__ = ["Method", "Job", "Outcome", "METHODS", "DEFAULT_METHOD", "DEFAULTS", "get_method", "methods_taking",
           "method_help", "outcome"]

#: The knobs' defaults: the paper's (section 4: pins, size, beta, gamma and T of fitness's ``detail`` style,
#: epsilon, iterations; alpha: docs/planner.md, "alpha"), the residual's refinement and polish (pins they
#: revisit) and ThreadTone's (greedy's weight, line width and loop on its 500-px radius).
DEFAULTS = {"pins": 300, "size": 401, "alpha": 0.0, "beta": 5.0, "gamma": 10.0, "T": 30.0, "epsilon": 2,
            "iterations": 25, "refine": 300, "polish": 1000, "greedy_weight": 15.0, "greedy_width": 3, "greedy_min_loop": 3,
            "greedy_reference_radius": 500.0}


@dataclass(frozen=True)
class Method:
    """One planning method.

    Parameters
    ----------
    name : str
        What ``--method`` takes and the plan's ``method`` records.
    summary : str
        One line for ``plan --help``.
    run : str
        ``"module:function"`` of the method's run (see the module notes).
    knobs : tuple of str
        The method-only options it takes (``--style``, ``--disconnected``, ...); giving one to
        a method that does not take it is refused, naming the methods that do.
    size : int or None
        Its working size in pixels when ``--size`` is not given (None: the planner's 401).
    gray : str
        How it grays a colour picture when ``--gray`` is not given.
    resample : str
        How it scales the picture (``lanczos``, ``bilinear``).
    luminance_weights : str
        ``"module:name"`` of the RGB weights it grays by when its gray is ``luminance`` (``""``:
        skimage's rgb2gray weights).
    start_quarter : bool
        Its first pin is ``pins // 4`` when ``--start-pin`` is not given (else 0).
    picks_start : bool
        It picks its first pin itself when ``--start-pin`` is not given (its job's ``start_pin`` is
        None; the plan records the first pin of its sequence).
    crop : str
        ``"module:function"`` giving its crop of a picture path when none is given (``""``:
        the largest centred circle).
    stops_itself : bool
        With ``--lines auto`` it decides when to stop; else it draws ``500 + 10 (255 - mean
        gray)`` lines (the paper's section 3.3).
    polish_passes : int
        Its passes of inserts and deletes after the polish when ``--polish-passes`` is not given
        (with ``--lines auto`` and the polish on; else none).
    """

    name: str
    summary: str
    run: str
    knobs: tuple = ()
    size: int | None = None
    gray: str = "decolor"
    resample: str = "lanczos"
    luminance_weights: str = ""
    start_quarter: bool = False
    picks_start: bool = False
    crop: str = ""
    stops_itself: bool = False
    polish_passes: int = 0

    def runner(self):
        """The run function (imported now: it may need numpy)."""
        return _resolve(self.run)

    def weights_for(self, gray):
        """The RGB weights it grays by with ``gray`` (None: the planner's own)."""
        return _resolve(self.luminance_weights) if gray == "luminance" and self.luminance_weights else None

    def default_crop(self, path):
        """Its crop of the picture at ``path`` when none is given, or None."""
        return _resolve(self.crop)(path) if self.crop else None


@dataclass
class Job:
    """What a method's run gets: see the module notes.  ``lines`` is an int (the line count;
    ``"auto"`` only for a method that :attr:`~Method.stops_itself`); ``start_pin`` None only for a
    method that :attr:`~Method.picks_start`.  ``knobs`` holds :data:`DEFAULTS` updated with every knob
    as given (None: not given; ``rng``, ``cache``, ``preview`` too); ``reference()`` is the picture as
    ``stringbot score`` reads it, for a method that compares drawings of its own; ``frame_weights``
    (``--face`` only; None without a face) the weights without the face's: all 1, or the importance
    mask's."""

    space: object
    picture: object
    mask: object
    weights: object
    lines: object
    start_pin: int | None
    model: object
    knobs: dict = field(default_factory=dict)
    reference: object = None
    frame_weights: object = None


@dataclass
class Outcome:
    """What a run returns when it has more than ``(sequence, params, stats)``.

    ``chords``: a chord set instead of one thread (``sequence`` is then empty); ``drawings``: drawings
    of the plan made meanwhile (the plan's ``woven_drawings``)."""

    sequence: list
    params: dict
    stats: dict
    chords: list | None = None
    drawings: dict | None = None


def outcome(result):
    """A run's result as an :class:`Outcome`."""
    return result if isinstance(result, Outcome) else Outcome(*result)


def _resolve(dotted):
    import importlib

    module, _, name = dotted.partition(":")
    return getattr(importlib.import_module(module), name)


#: Every method, by name; the first is the default.
METHODS = {m.name: m for m in (
    Method("residual", "chords chosen by what the picture as woven still lacks, then refined",
           run="stringbot.planner.methods.residual:run", knobs=("refine", "polish"),
           gray="luminance", picks_start=True, stops_itself=True),  # the piece is seen by its luminance
    Method("euler", "a chord set chosen with no thread to follow (relaxed densities), made one thread, then polished",
           run="stringbot.planner.methods.euler:run", knobs=("polish",), gray="luminance",
           picks_start=True, stops_itself=True),
    Method("fitness", "the paper's method", run="stringbot.planner.methods.fitness:run",
           knobs=("disconnected", "style", "beta", "gamma", "T")),
    Method("greedy", "ThreadTone as published", run="stringbot.planner.methods.greedy:plan_greedy",
           size=1001, gray="luminance", resample="bilinear",
           luminance_weights="stringbot.planner.picture.read:CV2_LUMINANCE",
           start_quarter=True, crop="stringbot.planner.picture.read:threadtone_crop"),
)}
DEFAULT_METHOD = next(iter(METHODS))


def get_method(name):
    """The :class:`Method` called ``name``; BadInput naming the methods there are."""
    if name not in METHODS:
        from ...errors import BadInput

        raise BadInput(f"--method {name!r}; expected one of {', '.join(METHODS)}")
    return METHODS[name]


def methods_taking(knob):
    """The names of the methods that take ``knob``, e.g. ``["fitness"]`` for ``"style"``."""
    return [m.name for m in METHODS.values() if knob in m.knobs]


def method_help():
    """The ``--method`` help: each method's name and summary."""
    return "; ".join(f"{m.name}: {m.summary}" for m in METHODS.values()) + "."
