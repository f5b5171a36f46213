"""The printed calibration sheet: the marks a photo is found by, the pins to lay it on, the patches' names.

A 1:1 drawing of :class:`~stringbot.planner.calibration.sheet.Sheet` (its module
notes have the layout): the square sheet's edge, the four corner marks (a ring
at the top left, discs at the other corners), every pin (to lay the sheet on
the ring, pin 0 at the top), the cut circle just inside the pins (cut the disc
out to photograph the threads over your own board), each patch's letter
beside it, a title and one line of instructions.  Nothing is printed inside
the cut circle: that is where the photo is measured.  On several pages the
alignment marks go only where the photo is not measured either.
"""

import math

from .drawing import CHAR_EM, Drawing, tile_layout, to_pdf, to_svg
from .template import _alignment_marks, page_label

__all__ = ["sheet_drawing", "sheet_svg", "sheet_pdf"]


def _fit_text(d, text, box, *, tag):
    x0, y0, x1, y1 = box
    size = min(0.8 * (y1 - y0), (x1 - x0) / (CHAR_EM * max(1, len(text))))
    d.text((x0 + x1) / 2, (y0 + y1) / 2 + 0.35 * size, text, size=size, anchor="middle", tag=tag)


def sheet_drawing(sheet, *, name=""):
    """The drawing (mm, origin at the sheet's top-left corner; the ring's centre at ``half_mm, half_mm``)."""
    h = sheet.half_mm
    side = 2 * h
    d = Drawing(side, side, title=f"stringbot calibration sheet{': ' + name if name else ''}, {sheet.pins} pins "
                                  f"on a {sheet.diameter_mm:g} mm circle")
    d.polyline([(0, 0), (side, 0), (side, side), (0, side), (0, 0)], width=0.3, tag="sheet edge")
    for k, (x, y, r) in enumerate(sheet.marks):
        if k == 0:
            inner = sheet.ring_hole * r
            d.circle(x + h, y + h, (r + inner) / 2, width=r - inner, tag="mark 0 (ring)")
        else:
            d.circle(x + h, y + h, r, width=0.1, fill=True, tag=f"mark {k}")
    pin_r = sheet.pin_diameter_mm / 2
    for i, (x, y) in enumerate(sheet.pin_mm()):
        d.circle(x + h, y + h, pin_r, width=0.12, tag=f"pin {i}")
    r = sheet.radius_mm
    margin = h - r
    d.text(h, h - r - 0.2 * margin, "PIN 0", size=0.08 * margin, anchor="middle", tag="pin 0")
    d.circle(h, h, r - 0.5 * sheet.rim_mm, width=0.15, tag="cut circle")
    for tag, text, (x0, y0, x1, y1) in sheet.labels:
        _fit_text(d, text, (x0 + h, y0 + h, x1 + h, y1 + h), tag=tag)
    return d


def sheet_svg(sheet, *, name=""):
    """:func:`sheet_drawing` as SVG text."""
    return to_svg(sheet_drawing(sheet, name=name))


def sheet_pdf(sheet, *, name="", paper="a4"):
    """:func:`sheet_drawing` as PDF bytes, tiled on ``paper`` with alignment marks outside the measured disc."""
    d = sheet_drawing(sheet, name=name)
    _, _, tiles = tile_layout(d.width, d.height, paper=paper)
    h, r = sheet.half_mm, sheet.radius_mm

    def keep(x, y):
        far_from_marks = all(math.hypot(x - h - mx, y - h - my) > 1.5 * mr for mx, my, mr in sheet.marks)
        return math.hypot(x - h, y - h) > r - 0.5 * sheet.rim_mm and far_from_marks

    if len(tiles) > 1:
        _alignment_marks(d, tiles, keep=keep)
    return to_pdf(d, paper=paper, page_label=page_label)
