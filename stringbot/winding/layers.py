"""Winding a colour plan layer by layer: the spool changes.

A colour plan's layers are separate threads wound one after the other (the
machine hooks every pin of every layer, each layer's first included).  Before
the first step of a layer the thread of that layer must be tied on, and that
is a person's act (or a machine's that changes thread itself):

1. the machine has executed every step before (the link's ``execute``
   returns only then) and stands still with the head IN, where the last hook
   left it; nothing is sent while the operator works;
2. by ``mode``:

   * ``"ask"`` (a terminal): the operator is told which thread to cut (and tie
     off at the last pin of its layer) and which colour to tie on at which
     pin, and confirms (``ask(question, color)``; the command line wants the
     colour's name typed, never a default);
   * ``"stop"`` (``--yes`` on a port: nobody to ask): the winding stops here,
     raising :class:`~stringbot.errors.SpoolChange` with the same instructions;
     the loop journals the stop (``reason: "spool change"``, ``layer``).  The
     resume command, run once the thread is tied on, is the person's word for
     that layer (``ready``): it goes on without a question;
   * ``"continue"`` (a machine that changes thread itself, a dry run): no
     question, no stop;

3. the tie-on is journaled (``{"kind": "layer", "layer": 1, "color":
   "#b22222", "step": 812, "pin": 17}``, layers and steps counted from 0);
4. ``hands(color, pin)``, when given, does the tie-on in a simulated world:
   a dry run's simulated operator, who does what the host asks, when it asks
   (the command line builds it; nothing here knows the simulator).  A machine
   on a port is never told anything: on a simulator in its own process the
   person ties the thread on there (its operator socket,
   ``stringbot simulate --pty PATH --tie-on COLOUR``).

The first layer's thread is tied on before the winding starts (as a one-thread
plan's is): ``"stop"`` does not stop for it.

On ``--resume`` the journal says which thread is on the machine (its last
``layer`` record): a winding interrupted inside layer 2 goes on with layer
2's thread without a question, one stopped at a spool change asks for the
next thread (or, stopped there by ``"stop"``, takes the resume as the word that
it is on), and ``--from-step`` into another layer asks (stops) for that
layer's thread.
"""

import logging

from ..errors import Interrupted, SpoolChange
from ..planner.colour.palette import describe_color

__all__ = ["Threads", "threads_for", "spool_stop_layer", "layer_problems", "tied_layer", "status_line"]

log = logging.getLogger(__name__)


def tied_layer(state):
    """The layer whose thread the journal last saw tied on (None: none yet)."""
    recs = getattr(state, "layers", None) or []
    return recs[-1]["layer"] if recs else None


MODES = ("ask", "stop", "continue")


class Threads:
    """The layers of a job and the operator's part at each spool change.

    Parameters
    ----------
    job : Job
    journal : Journal
    tied : int or None
        The layer whose thread is on the machine (from the journal; None: none).
    mode : {"ask", "stop", "continue"}
        What happens at a spool change (see the module's notes).
    ask : callable(question, color) -> bool, or None
        Asks the operator to confirm that the thread of ``color`` is tied on (``mode="ask"``).
    hands : callable(color, pin), or None
        A simulated operator's hands: tie the thread on in a simulated world.
    ready : int or None
        A layer whose thread the operator already said is on (the resume after a ``"stop"``
        there): ``"stop"`` does not stop for it again (``"ask"`` still asks).
    """

    def __init__(self, job, journal, *, tied=None, mode="ask", ask=None, hands=None, ready=None):
        if mode not in MODES:
            raise ValueError(f"mode {mode!r}; expected one of {MODES}")
        if mode == "ask" and ask is None:
            raise ValueError("mode 'ask' needs ask(question, color)")
        self.plan = job.plan
        self.journal = journal
        self.tied = tied
        self.mode = mode
        self.ask = ask
        self.hands = hands
        self.ready = ready
        self.starts = list(self.plan.layer_starts)
        self.colors = list(self.plan.colors)

    def runs(self, first, total):
        """``[(a, b), ...]``: steps ``first``.. cut at the layer starts."""
        cuts = [s for s in self.starts if first < s < total]
        edges = [first] + cuts + [total]
        return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if a < b]

    def instructions(self, layer, step):
        """What the operator does before ``step`` of ``layer``: the thread to cut and where to tie it
        off, the colour to tie on and at which pin."""
        n = len(self.colors)
        pin = self.plan.sequence[step]
        color = describe_color(self.colors[layer])
        where = "the first pin of its layer" if step == self.starts[layer] else f"step {step + 1}"
        tie = f"tie the {color} thread on at pin {pin} ({where}, layer {layer + 1} of {n})"
        if self.tied is None:
            return tie[0].upper() + tie[1:]
        old = describe_color(self.colors[self.tied])
        end = self.starts[self.tied] + len(self.plan.layers[self.tied].sequence)
        off = f"at pin {self.plan.sequence[end - 1]}" if end == step else "where it ends"
        return f"cut the {old} thread and tie it off {off}; {tie}"

    def question(self, layer, step):
        if self.tied is None:
            return f"{self.instructions(layer, step)}, then go on?"
        return (f"Spool change: {self.instructions(layer, step)}. The machine holds with the head in. "
                "Go on?")

    def before(self, step):
        """Before step ``step`` is wound: make sure its layer's thread is tied on (ask or stop, journal,
        tell a simulated world)."""
        layer = self.plan.layer_of(step)
        ready, self.ready = self.ready, None    # the operator's word (running the resume): this once
        if layer == self.tied:
            return
        if self.mode == "ask":
            if not self.ask(self.question(layer, step), self.colors[layer]):
                raise Interrupted(f"stopped by the operator at the spool change before step {step + 1} "
                                  f"(layer {layer + 1}); nothing was moved since; resume with --resume")
        elif self.mode == "stop" and self.tied is not None and layer != ready:
            raise SpoolChange(f"spool change before step {step + 1} (layer {layer + 1} of {len(self.colors)}): "
                              f"the machine holds with the head in; {self.instructions(layer, step)}",
                              layer=layer)
        pin = int(self.plan.sequence[step])
        if self.hands is not None:
            self.hands(self.colors[layer], pin)
            log.info("simulated operator tied %s on at pin %d", self.colors[layer], pin)
        self.journal.append({"kind": "layer", "layer": layer, "color": self.colors[layer], "step": step,
                             "pin": pin})
        self.tied = layer


def threads_for(job, journal, *, tied=None, ready=None, confirm=None, spool_change=None, ask_thread=None,
                hands=None):
    """The :class:`Threads` of a ``wind`` or a resume: ``spool_change`` None picks ask (someone to ask),
    continue (a dry run) or stop (a machine on a port); ``ask_thread`` defaults to ``confirm``."""
    mode = spool_change or ("ask" if confirm is not None else "continue" if job.dry_run else "stop")
    if ask_thread is None and confirm is not None:
        def ask_thread(question, color):
            return confirm(question)
    return Threads(job, journal, tied=tied, ready=ready, mode=mode, ask=ask_thread, hands=hands)


def spool_stop_layer(stop):
    """The layer a live stop record (None: none) stopped to have tied on, or None."""
    if stop is not None and stop.get("reason") == "spool change" and isinstance(stop.get("layer"), int):
        return stop["layer"]
    return None


def status_line(plan, state):
    """``--status`` of a colour plan: the layer whose thread the journal last saw tied on."""
    if plan.is_mono:
        return None
    k = tied_layer(state)
    n = len(plan.colors)
    if k is None:
        return f"threads: {n} layers; none tied on yet (layer 1: {describe_color(plan.colors[0])})"
    nxt = plan.layer_of(min(state.next_step, len(plan.sequence) - 1))
    then = "" if nxt == k or state.finished else f"; next: a spool change to layer {nxt + 1} ({describe_color(plan.colors[nxt])})"
    return f"threads: layer {k + 1} of {n} tied on ({describe_color(plan.colors[k])}){then}"


def layer_problems(plan, wraps):
    """Where a world's wraps (record dicts) differ from the plan's layers, as text (None: exactly the plan)."""
    problems = []
    for k, lay in enumerate(plan.layers):
        a = plan.layer_starts[k]
        got = wraps[a:a + len(lay.sequence)]
        pins = [int(w.get("pin", -1)) for w in got]
        colors = {w.get("color") for w in got}
        if pins != list(lay.sequence):
            problems.append(f"layer {k + 1} ({lay.color}) wrapped {len(pins)} pins that differ from its "
                            f"{len(lay.sequence)}")
        elif colors != {lay.color}:
            wrong = sorted(str(c) for c in colors - {lay.color})
            problems.append(f"layer {k + 1} ({lay.color}) was wound with thread {', '.join(wrong)}")
    return "; ".join(problems) or None
