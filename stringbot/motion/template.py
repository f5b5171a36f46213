"""The drilling template of a ring: every pin centre at 1:1, numbered, from the machine's geometry.

Pin ``i`` sits on the circle of diameter ``ring.diameter_mm`` (through the pin
centres) at ``360 * i / pins`` degrees clockwise from the top, seen from the
front (the side the painting is looked at): the numbering the plan and the
machine use (pin ``i`` faces the head station at ring axis ``pin0_angle_deg +
i * 360 / pins``).  The template marks every pin centre (a circle of the pin's
diameter and a cross), its number, pin 0 and the counting direction, the
centre, and a 100 mm ruler to check the print's scale before drilling.
"""

import math

from ..errors import BadInput
from .drawing import CHAR_EM, Drawing, to_pdf, to_svg

__all__ = ["ring_template", "pin_centres", "template_svg", "template_pdf", "RULER_MM"]

RULER_MM = 100.0


def pin_centres(pins, diameter_mm, *, centre=(0.0, 0.0)):
    """``[(x, y), ...]`` in mm (x right, y down) of every pin centre, pin 0 at the top, clockwise."""
    cx, cy = centre
    r = diameter_mm / 2.0
    return [(cx + r * math.sin(2 * math.pi * i / pins), cy - r * math.cos(2 * math.pi * i / pins))
            for i in range(pins)]


def _check(pins, diameter_mm, pin_diameter_mm):
    if isinstance(pins, bool) or not isinstance(pins, int) or not 3 <= pins <= 5000:
        raise BadInput(f"--pins {pins!r}; expected a whole number 3..5000")
    if not (isinstance(diameter_mm, (int, float)) and math.isfinite(diameter_mm) and 10 <= diameter_mm <= 5000):
        raise BadInput(f"--diameter-mm {diameter_mm!r}; expected a number of mm, 10..5000")
    if not (math.isfinite(pin_diameter_mm) and 0 < pin_diameter_mm <= 20):
        raise BadInput(f"pin diameter {pin_diameter_mm!r} mm; expected a number > 0 and <= 20")
    pitch = math.pi * diameter_mm / pins
    if pitch <= pin_diameter_mm:
        raise BadInput(f"{pins} pins of {pin_diameter_mm:g} mm do not fit on a {diameter_mm:g} mm circle "
                       f"(pitch {pitch:.3f} mm); expected fewer pins or a larger diameter")


def _ruler(d, x0, y):
    """A 100 mm ruler from (x0, y): mm ticks, 5 mm and 10 mm marks with numbers."""
    d.line(x0, y, x0 + RULER_MM, y, width=0.2, tag="ruler")
    for mm in range(int(RULER_MM) + 1):
        length = 4.0 if mm % 10 == 0 else 2.5 if mm % 5 == 0 else 1.5
        d.line(x0 + mm, y, x0 + mm, y - length, width=0.12)
        if mm % 10 == 0:
            d.text(x0 + mm, y - 5.0, str(mm), size=2.2, anchor="middle")
    d.text(x0 + RULER_MM / 2, y + 4.5, "100 mm: measure it before drilling", size=2.6, anchor="middle")


def ring_template(*, pins, diameter_mm, pin_diameter_mm=1.5, name=""):
    """The template drawing (see the module notes).

    Parameters
    ----------
    pins : int
    diameter_mm : float
        Diameter of the circle through the pin centres.
    pin_diameter_mm : float
        Drawn as each pin's circle (the drill).
    name : str
        The machine's name, for the title.

    Returns
    -------
    (Drawing, (cx, cy))
        The drawing and the centre of the pin circle in it (mm).
    """
    _check(pins, diameter_mm, pin_diameter_mm)
    r = diameter_mm / 2.0
    pitch = math.pi * diameter_mm / pins
    font = max(0.6, min(3.0, 0.7 * pitch))
    pin_r = pin_diameter_mm / 2.0
    cross = max(pin_r + 0.6, 1.2)
    mark = pin_r + 1.6                      # the ring round pin 0
    label = mark + 0.8 + len(str(pins - 1)) * CHAR_EM * font
    margin = label + 8.0                    # round the pin circle: the numbers, "PIN 0", a border
    small = r < 75.0                        # the ruler does not fit inside: put it below
    head = 12.0                             # the title
    w = max(diameter_mm + 2 * margin, RULER_MM + 20.0)
    h = head + diameter_mm + 2 * margin + (20.0 if small else 0.0)
    cx, cy = w / 2.0, head + margin + r
    title = (f"stringbot drilling template{': ' + name if name else ''}, {pins} pins on a "
             f"{diameter_mm:g} mm circle, pins {pin_diameter_mm:g} mm")
    d = Drawing(w, h, title=title)
    lines = [title, "Print at 100 % (actual size) and check the 100 mm ruler.",
             "Seen from the front (the side the painting is looked at): pins count clockwise."]
    size = min(2.8, (w - 8.0) / (CHAR_EM * max(len(t) for t in lines)))
    for k, text in enumerate(lines):
        d.text(4.0, 4.0 + (k + 0.8) * 1.3 * size, text, size=size)
    for i, (x, y) in enumerate(pin_centres(pins, diameter_mm, centre=(cx, cy))):
        a = 360.0 * i / pins
        d.circle(x, y, pin_r, width=0.12, tag=f"pin {i}")
        d.line(x - cross, y, x + cross, y, width=0.08, tag=f"pin {i} cross")
        d.line(x, y - cross, x, y + cross, width=0.08)
        # the number, read along the radius outwards (turned on the left half so it is never upside down)
        t = math.radians(a)
        gap = (mark if i == 0 else cross) + 0.8
        lx, ly = x + gap * math.sin(t), y - gap * math.cos(t)
        if a <= 180.0:
            d.text(lx + 0.35 * font * math.cos(t), ly + 0.35 * font * math.sin(t), str(i), size=font,
                   angle=a - 90.0, anchor="start")
        else:
            d.text(lx - 0.35 * font * math.cos(t), ly - 0.35 * font * math.sin(t), str(i), size=font,
                   angle=a + 90.0, anchor="end")
    # pin 0: a second ring round it, and the counting direction as an arrow along the circle
    x0, y0 = cx, cy - r
    d.circle(x0, y0, mark, width=0.3, tag="pin 0 mark")
    d.text(x0, y0 - label - 1.5, "PIN 0", size=3.2, anchor="middle")
    if r >= 30.0:                           # the counting direction, inside the circle near pin 0
        arc_r = r - min(12.0, 0.25 * r)
        span = min(25.0, 3000.0 / r)
        pts = [(cx + arc_r * math.sin(math.radians(b)), cy - arc_r * math.cos(math.radians(b)))
               for b in [span * k / 20.0 for k in range(21)]]
        d.polyline(pts, width=0.35, tag="direction arrow")
        ex, ey = pts[-1]
        tb = math.radians(span)
        tx, ty = math.cos(tb), math.sin(tb)             # the way the pins count, at the arrow's end
        nx, ny = -math.sin(tb), math.cos(tb)            # towards the centre
        d.polyline([(ex + 2.5 * tx, ey + 2.5 * ty), (ex + 1.2 * nx, ey + 1.2 * ny),
                    (ex - 1.2 * nx, ey - 1.2 * ny)], width=0.2, fill=True)
        words = "pins count this way: 0, 1, 2 ..."
        d.text(cx, cy - arc_r + 8.0, words, size=min(2.6, 1.2 * arc_r / (CHAR_EM * len(words))),
               anchor="middle")
    # the centre
    c = min(6.0, 0.3 * r)
    d.line(cx - c, cy, cx + c, cy, width=0.15, tag="centre")
    d.line(cx, cy - c, cx, cy + c, width=0.15)
    d.circle(cx, cy, c / 3.0, width=0.15)
    if r >= 30.0:
        d.text(cx + 3.0, cy - 3.0, "centre", size=2.4)
    if small:
        _ruler(d, cx - RULER_MM / 2, h - 10.0)
    else:
        _ruler(d, cx - RULER_MM / 2, cy + min(25.0, 0.3 * r))
    return d, (cx, cy)


def template_svg(**kw):
    """:func:`ring_template` as SVG text."""
    d, _ = ring_template(**kw)
    return to_svg(d)


def template_pdf(*, paper="a4", **kw):
    """:func:`ring_template` as PDF bytes, tiled on ``paper`` with overlap and alignment marks."""
    from .drawing import tile_layout

    d, _ = ring_template(**kw)
    _, _, tiles = tile_layout(d.width, d.height, paper=paper)
    if len(tiles) > 1:
        _alignment_marks(d, tiles)

    return to_pdf(d, paper=paper, page_label=page_label)


def page_label(tile, rows, cols):
    """The line at the foot of each page of a tiled print: where it goes."""
    return (f"page {tile.row * cols + tile.col + 1} of {rows * cols}: row {tile.row + 1} of {rows}, "
            f"column {tile.col + 1} of {cols}. Overlap the pages so the + marks coincide. "
            "Print at 100 %.")


def _alignment_marks(d, tiles, keep=None):
    """Crosses in the middle of every strip two neighbouring pages share, with a circle round them
    (only where ``keep(x, y)`` is true, when given)."""
    xs = sorted({t.x0 for t in tiles})
    ys = sorted({t.y0 for t in tiles})
    w, h = tiles[0].w, tiles[0].h
    overlap_x = xs[0] + w - xs[1] if len(xs) > 1 else 0.0
    overlap_y = ys[0] + h - ys[1] if len(ys) > 1 else 0.0
    mark_x = [x + overlap_x / 2 for x in xs[1:]]
    mark_y = [y + overlap_y / 2 for y in ys[1:]]
    along_x = [y + h / 2 for y in ys]       # marks on vertical seams: halfway down each row
    along_y = [x + w / 2 for x in xs]
    spots = [(mx, my) for mx in mark_x for my in along_x + mark_y] + [(mx, my) for my in mark_y for mx in along_y]
    for mx, my in spots:
        if keep is None or keep(mx, my):
            _mark(d, mx, my)


def _mark(d, x, y):
    d.circle(x, y, 2.5, width=0.2, tag="alignment")
    d.line(x - 4, y, x + 4, y, width=0.2)
    d.line(x, y - 4, x, y + 4, width=0.2)
