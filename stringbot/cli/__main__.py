"""``python -m stringbot.cli``."""

from . import main

main()
