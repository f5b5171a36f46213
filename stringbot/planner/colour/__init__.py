"""Colour thread paintings: the threads, the planner, the piece as woven in colour.

``palette``  thread colours (names, ``#rrggbb``), sRGB <-> linear light <-> CIELAB, the ``auto:N`` palette
``model``    the woven piece in colour and the joint (colour, chord) greedy
``build``    picture -> colour Plan (the plan file's ``layers``)
``render``   a colour plan as woven, and its colour score
``frames``   a colour plan growing in winding order (``stringbot animate``)

``palette`` imports nothing of the others, so the motion and winding layers may
use it (colour names) without the planner's numerics.
"""
