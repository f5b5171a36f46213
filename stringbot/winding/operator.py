"""The operator, as a resume sees them: what they stated, and how to ask them more.

Nothing here talks to a terminal: the command line builds an :class:`Operator`
from its options and from callables that prompt (none under ``--yes``).
"""

from dataclasses import dataclass
from typing import Callable

__all__ = ["Operator"]


@dataclass
class Operator:
    """What the operator said, and how to ask them.

    Attributes
    ----------
    head_side : "in", "out" or None
        ``--head-side``: the operator's statement, after looking, of where the eyelet is.
        The one answer that needs no terminal.
    confirm : callable(question) -> bool, or None
        A yes/no question (None: ``--yes``, nobody to ask).
    choose : callable(question, choices) -> choice, or None
    jog : callable(prompt) -> str, or None
        One jog command typed by the operator (see :mod:`stringbot.winding.guide`); None when
        there is no terminal.
    say : callable(text) -> None, or None
        Show an instruction.
    look : callable() -> (ring_deg, head_mm), or None
        A dry run's simulated operator's eyes: where the simulated machine physically stands
        (None: a person looks, and answers through the above).
    """

    head_side: str | None = None
    confirm: Callable | None = None
    choose: Callable | None = None
    jog: Callable | None = None
    say: Callable | None = None
    look: Callable | None = None

    @property
    def present(self):
        """Someone can be asked (not ``--yes``)."""
        return self.confirm is not None

    def tell(self, text):
        if self.say is not None:
            self.say(text)
