"""Winding a colour plan layer by layer: the spool changes.

A colour plan's layers are separate threads wound one after the other (the
machine hooks every pin of every layer, each layer's first included).  Before
the first step of a layer the thread of that layer must be tied on:

1. the machine has executed every step before (the link's ``execute``
   returns only then) and stands still with the head IN, where the last hook
   left it; nothing is sent while the operator works;
2. the operator is told which thread to cut (and tie off at the last pin of
   its layer) and which colour to tie on at which pin, and confirms (``--yes``:
   no question);
3. the tie-on is journaled (``{"kind": "layer", "layer": 1, "color":
   "#b22222", "step": 812, "pin": 17}``, layers and steps counted from 0);
4. a simulated machine's world is told the colour (the dry run's operator,
   :mod:`stringbot.links.operator`), so its record shows which thread went
   round every pin.

On ``--resume`` the journal says which thread is on the machine (its last
``layer`` record): a winding interrupted inside layer 2 goes on with layer
2's thread without a question, one stopped at a spool change asks for the
next thread, and ``--from-step`` into another layer asks for that layer's
thread.
"""

import logging

from ..errors import Interrupted
from ..links.operator import tie_on
from ..planner.palette import describe_color

__all__ = ["Threads", "layer_problems", "tied_layer", "status_line"]

log = logging.getLogger(__name__)


def tied_layer(state):
    """The layer whose thread the journal last saw tied on (None: none yet)."""
    recs = getattr(state, "layers", None) or []
    return recs[-1]["layer"] if recs else None


class Threads:
    """The layers of a job and the operator's part at each spool change.

    Parameters
    ----------
    job : Job
    journal : Journal
    tied : int or None
        The layer whose thread is on the machine (from the journal; None: none).
    confirm : callable(str) -> bool, or None
        Asks the operator; None (``--yes``) asks nothing.
    """

    def __init__(self, job, journal, *, tied=None, confirm=None):
        self.plan = job.plan
        self.url = job.url
        self.journal = journal
        self.tied = tied
        self.confirm = confirm
        self.starts = list(self.plan.layer_starts)
        self.colors = list(self.plan.colors)

    def runs(self, first, total):
        """``[(a, b), ...]``: steps ``first``.. cut at the layer starts."""
        cuts = [s for s in self.starts if first < s < total]
        edges = [first] + cuts + [total]
        return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if a < b]

    def question(self, layer, step):
        n = len(self.colors)
        pin = self.plan.sequence[step]
        color = describe_color(self.colors[layer])
        where = "the first pin of its layer" if step == self.starts[layer] else f"step {step + 1}"
        if self.tied is None:
            return (f"Tie the {color} thread on at pin {pin} ({where}, layer {layer + 1} of {n}), "
                    "then go on?")
        old = describe_color(self.colors[self.tied])
        return (f"Spool change: cut the {old} thread and tie it off where it ends; tie the {color} thread "
                f"on at pin {pin} ({where}, layer {layer + 1} of {n}). The machine holds with the head "
                "in. Go on?")

    def before(self, step):
        """Before step ``step`` is wound: make sure its layer's thread is tied on (ask, journal, tell)."""
        layer = self.plan.layer_of(step)
        if layer == self.tied:
            return
        if self.confirm is not None and not self.confirm(self.question(layer, step)):
            raise Interrupted(f"stopped by the operator at the spool change before step {step + 1} "
                              f"(layer {layer + 1}); nothing was moved since; resume with --resume")
        pin = int(self.plan.sequence[step])
        if tie_on(self.url, self.colors[layer], pin):
            log.info("simulated operator tied %s on at pin %d", self.colors[layer], pin)
        self.journal.append({"kind": "layer", "layer": layer, "color": self.colors[layer], "step": step,
                             "pin": pin})
        self.tied = layer


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
