"""The calibration sheet: a small windable plan of known thread densities, and its exact model.

``stringbot calibrate sheet`` winds this plan over a printed sheet;
``stringbot calibrate fit`` reads a photo of it (:mod:`.photo`).

Coordinates are millimetres in the plane of the ring, origin at its centre, x
right, y down, seen from the front; pin ``i`` sits at ``(r sin a, -r cos a)``
with ``a = 2 pi i / pins`` (pin 0 at the top, clockwise), as in a plan's
``pin_xy`` (``xy_mm = (pin_xy - 0.5) * diameter``).

The layout
----------
*Patches* are horizontal strips of chords.  A chord between pins ``i`` and
``j`` runs at right angles to the direction ``pi (i + j) / pins``, so the chords
of one sum ``i + j`` are exactly parallel, and each unit of sum turns a chord by
``pi / pins``.  Strip ``k`` pairs pins on the right with their mirror images on
the left: chord ``(R_a, L_b)`` with ``R_a = j0 + a`` and ``L_b = pins - j0 - b``
has *tilt* ``a - b`` (its sum) and *position* ``(a + b) / 2``; the strip holds
every chord of position ``0 .. m - 1`` and tilt ``-S .. S``.  Its middle is a
band :data:`BAND_FRACTION` of the diameter high (``m`` pin pitches) that
``2 S + 1`` nearly parallel chords cross per pitch; away from the middle the
tilts fan out (an hourglass).  ``S`` is chosen per strip for the thread's
nominal width ``w``: lines per mm times ``w`` near :data:`DENSITIES`, from lone
parallel threads a pitch apart to a patch the thread covers three quarters.
The strips lie one above the other with bare board between them; a few short
chords along the rim (within :data:`RIM_FRACTION` of the diameter of the pins)
join the patches into one thread.

The *cells* are rows across each strip, in four columns along its middle,
whose covered fraction changes by at most :data:`ROBUST` of it when the
threads lie :data:`SHIFT_FRACTION` of the diameter above or below where the
sheet says (a sheet laid a little off, threads seen a little aside of the
paper under them).  :func:`cell_coverage` gives each cell's covered fraction
for any thread width: the union of the threads (opaque bands of that width
with sharp edges, two threads over a spot cover it once), computed exactly
along vertical scanlines.

The *marks* are printed in the sheet's corners, outside the ring: a ring
(hollow) at the top left, discs at the other three corners.  The printed sheet
is a square of side ``diameter + 2 margin`` (:data:`MARGIN_FRACTION`); its
labels' boxes are listed so that the photo's paper can be told from its ink.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from ...errors import BadInput
from ..model.chords import pin_positions

__all__ = ["Sheet", "Strip", "design_sheet", "cell_coverage", "sheet_plan", "sheet_from_plan", "MIN_PINS",
           "SHEET_FORMAT", "SHEET_VERSION"]

SHEET_FORMAT = "stringbot-calibration-sheet"
SHEET_VERSION = 1
MIN_PINS = 60
#: the rim band left out of every measurement: pins, the chords that join the patches, the ring itself
RIM_FRACTION = 0.06
#: the margin of paper round the pin circle, as a fraction of the diameter
MARGIN_FRACTION = 0.14
#: the height of a strip's band, as a fraction of the diameter
BAND_FRACTION = 0.1
#: densities of the patches, as lines per mm times the thread's nominal width (the first: one tilt)
DENSITIES = (0.05, 0.15, 0.35, 0.7, 1.2)
#: a cell is kept if a sheet laid this fraction of the diameter off (up or down) changes its covered
#: fraction by at most ROBUST of it
SHIFT_FRACTION, ROBUST = 0.006, 0.03
#: cell height, fraction of the diameter (cells overlap by half)
ROW_FRACTION = 0.02


@dataclass(frozen=True)
class Strip:
    """One patch: chords of tilts ``-tilt .. tilt`` and positions ``0 .. m - 1``.

    ``lines_per_mm`` is the nominal density in its middle (threads crossing a mm
    across it); ``y_mm`` the height of its middle.
    """

    name: str
    tilt: int
    y_mm: float
    lines_per_mm: float
    chords: tuple


@dataclass(frozen=True)
class Sheet:
    """A calibration sheet's design (see the module notes)."""

    pins: int
    diameter_mm: float
    pin_diameter_mm: float
    thread_mm: float
    sequence: tuple
    strips: tuple
    #: (n, 4) cell rectangles ``x0, x1, y0, y1`` in mm; ``cell_strip[k]`` the strip of cell k
    cells: np.ndarray = field(repr=False)
    cell_strip: np.ndarray = field(repr=False)
    #: (4, 3) ``x, y, radius`` of the marks: top left (a ring), top right, bottom right, bottom left (discs)
    marks: np.ndarray = field(repr=False)
    #: the ring's hole: the inner radius of the ring mark is this times its radius
    ring_hole: float
    #: half the side of the printed square, mm
    half_mm: float
    #: ``(name, text, (x0, y0, x1, y1))``: what the template prints where, outside the pin circle
    labels: tuple

    @property
    def radius_mm(self):
        return self.diameter_mm / 2.0

    @property
    def rim_mm(self):
        """Width of the band inside the pin circle that no measurement uses."""
        return RIM_FRACTION * self.diameter_mm

    def pin_mm(self):
        """(pins, 2) pin centres in mm."""
        return (pin_positions(self.pins) - 0.5) * self.diameter_mm

    def chord_mm(self):
        """(chords, 2, 2) the sequence's chords, from pin centre to pin centre, in mm."""
        xy = self.pin_mm()
        seq = np.asarray(self.sequence)
        return np.stack([xy[seq[:-1]], xy[seq[1:]]], axis=1)


def _check_ring(pins, diameter_mm, pin_diameter_mm):
    if isinstance(pins, bool) or not isinstance(pins, int) or not MIN_PINS <= pins <= 5000:
        raise BadInput(f"a calibration sheet needs a ring of {MIN_PINS}..5000 pins, not {pins!r}; expected a "
                       f"machine with at least {MIN_PINS} pins")
    if not (math.isfinite(diameter_mm) and 10 <= diameter_mm <= 5000):
        raise BadInput(f"ring diameter {diameter_mm!r} mm; expected 10..5000 mm")
    if not (math.isfinite(pin_diameter_mm) and 0 < pin_diameter_mm < math.pi * diameter_mm / pins):
        raise BadInput(f"pin diameter {pin_diameter_mm!r} mm; expected a number > 0 that fits between the pins")


def _strip_chords(pins, j0, m, tilt):
    """Chords ``(R_a, L_b)`` of positions ``0 .. m-1`` and tilts ``-tilt .. tilt`` (module notes)."""
    out = []
    for u in range(2 * m - 1):               # u = a + b: twice the position
        for s in range(-tilt, tilt + 1):     # s = a - b: the tilt
            if (u + s) % 2:
                continue
            a, b = (u + s) // 2, (u - s) // 2
            out.append(((j0 + a) % pins, (pins - j0 - b) % pins))
    return out


def _euler(edges, start_near, pins):
    """A walk using every edge once, beginning at the pin nearest ``start_near`` along the rim.

    Odd pins are paired on each side of the ring by short rim chords (one end of the walk left on
    each side when there are odd ones); pieces that are still apart are joined by a rim chord wound
    there and back.
    """
    edges = list(edges)
    deg = {}
    for a, b in edges:
        deg[a] = deg.get(a, 0) + 1
        deg[b] = deg.get(b, 0) + 1
    odd = sorted(p for p, d in deg.items() if d % 2)
    ends = []
    for side in ([p for p in odd if p <= pins // 2], [p for p in odd if p > pins // 2]):
        if len(side) % 2:
            ends.append(side.pop(0))
        edges += [(side[k], side[k + 1]) for k in range(0, len(side), 2)]
    parent = {p: p for p in deg}

    def root(p):
        while parent[p] != p:
            parent[p] = parent[parent[p]]
            p = parent[p]
        return p

    for a, b in edges:
        parent[root(a)] = root(b)
    while len({root(p) for p in deg}) > 1:   # join the nearest two pieces, there and back
        a, b = min(((p, q) for p in deg for q in deg if root(p) != root(q)),
                   key=lambda pq: min((pq[0] - pq[1]) % pins, (pq[1] - pq[0]) % pins))
        edges += [(a, b), (b, a)]
        parent[root(a)] = root(b)
    adj = {}
    for k, (a, b) in enumerate(edges):
        adj.setdefault(a, []).append((b, k))
        adj.setdefault(b, []).append((a, k))

    def rim(p):
        return min((p - start_near) % pins, (start_near - p) % pins)

    first = min(ends, key=rim) if ends else min(adj, key=rim)
    used = [False] * len(edges)
    stack, walk = [first], []
    while stack:                             # Hierholzer
        p = stack[-1]
        while adj[p] and used[adj[p][-1][1]]:
            adj[p].pop()
        if adj[p]:
            q, k = adj[p].pop()
            used[k] = True
            stack.append(q)
        else:
            walk.append(stack.pop())
    return walk[::-1]


def _rim_walk(a, b, pins, step):
    """Pins from ``a`` to ``b`` (both excluded) the short way round, at most ``step`` pins apart."""
    d = (b - a) % pins
    sign = 1 if d <= pins - d else -1
    n = d if sign > 0 else pins - d
    hops = max(1, math.ceil(n / step))
    return [(a + sign * round(n * h / hops)) % pins for h in range(1, hops)]


def design_sheet(*, pins, diameter_mm, pin_diameter_mm=1.5, thread_mm=0.25):
    """The calibration sheet for a ring and the thread it will be wound with (see the module notes).

    Parameters
    ----------
    pins : int
        Pins on the ring, at least :data:`MIN_PINS`.
    diameter_mm : float
        Diameter of the pin circle.
    pin_diameter_mm : float
        For the template's pin marks.
    thread_mm : float
        The thread's nominal width: the patches' densities are chosen for it (:data:`DENSITIES`).

    Returns
    -------
    Sheet

    Raises
    ------
    BadInput
        A ring with too few pins, or sizes out of range.
    """
    _check_ring(pins, diameter_mm, pin_diameter_mm)
    if not (math.isfinite(thread_mm) and 0 < thread_mm <= 0.05 * diameter_mm):
        raise BadInput(f"thread {thread_mm!r} mm; expected a number > 0 and at most a 20th of the ring")
    r = diameter_mm / 2.0
    pitch = math.pi * diameter_mm / pins
    m = max(3, round(BAND_FRACTION * diameter_mm / pitch))
    tilts = sorted({max(0, round((rho_w * pitch / thread_mm - 1) / 2)) for rho_w in DENSITIES} | {0})
    low, high = tilts[:(len(tilts) + 1) // 2], tilts[(len(tilts) + 1) // 2:]
    tilts = [t for pair in zip(low, high + [None]) for t in pair if t is not None]   # sparse and dense, in turn
    levels = np.linspace(-0.6, 0.6, len(tilts)) * r
    rim_step = max(1, int(pins * math.acos(1 - 0.5 * RIM_FRACTION * diameter_mm / r) / math.pi))
    strips, sequence = [], []
    for k, (tilt, y) in enumerate(zip(tilts, levels)):
        centre = pins * math.acos(-y / r) / (2 * math.pi)      # the right-hand pin at height y
        j0 = int(round(centre - (m - 1) / 2))
        chords = _strip_chords(pins, j0, m, tilt)
        walk = _euler(chords, sequence[-1] if sequence else j0, pins)
        if sequence:
            sequence += _rim_walk(sequence[-1], walk[0], pins, rim_step)
            if walk[0] == sequence[-1]:
                walk = walk[1:]
        sequence += walk
        sine = math.sqrt(max(0.0, 1 - (y / r) ** 2))
        strips.append(Strip(name=chr(ord("A") + k), tilt=tilt, y_mm=float(y),
                            lines_per_mm=(2 * tilt + 1) / (pitch * sine), chords=tuple(chords)))
    margin = MARGIN_FRACTION * diameter_mm
    half = r + margin
    c = r + margin / 2.0
    mr = 0.3 * margin
    marks = np.array([[-c, -c, mr], [c, -c, mr], [c, c, mr], [-c, c, mr]])
    labels = []
    for s in strips:   # beside each strip on the right, between the pin circle's rim and the sheet's edge
        hc = math.sqrt(max(0.0, r * r - s.y_mm ** 2))
        x0 = hc + 0.35 * margin
        if x0 + 0.3 * margin < half - 0.1 * margin:
            labels.append((f"patch {s.name}", f"{s.name}", (x0, s.y_mm - 0.12 * margin, x0 + 0.25 * margin,
                                                             s.y_mm + 0.12 * margin)))
    labels.append(("title", "stringbot calibration sheet",
                   (-c + 1.2 * mr, -half + 0.15 * margin, c - 1.2 * mr, -half + 0.3 * margin)))
    labels.append(("how", "lay under the threads, pin 0 at the top; photograph from the front",
                   (-c + 1.2 * mr, half - 0.3 * margin, c - 1.2 * mr, half - 0.18 * margin)))
    sheet = Sheet(pins=pins, diameter_mm=float(diameter_mm), pin_diameter_mm=float(pin_diameter_mm),
                  thread_mm=float(thread_mm), sequence=tuple(int(p) for p in sequence), strips=tuple(strips),
                  cells=np.zeros((0, 4)), cell_strip=np.zeros(0, dtype=int), marks=marks, ring_hole=0.55,
                  half_mm=half, labels=tuple(labels))
    cells, owner = _cells(sheet)
    return Sheet(**{**sheet.__dict__, "cells": cells, "cell_strip": owner})


def _cells(sheet):
    """Rows across each strip whose coverage a sheet laid :data:`SHIFT_FRACTION` off hardly changes.

    Each strip is cut into four columns along x; a column's band (every chord of the strip, with
    room for the shift) is cut into ``k`` equal rows, ``k`` chosen so that most rows are robust: a
    shift up or down changes their covered fraction (at the nominal width) by at most
    :data:`ROBUST` of it.  The robust rows are the cells.
    """
    r, d = sheet.radius_mm, sheet.diameter_mm
    shift, row = SHIFT_FRACTION * d, ROW_FRACTION * d
    seg = _segments(sheet)
    xy = sheet.pin_mm()
    cells, owner = [], []
    for k, s in enumerate(sheet.strips):
        ch = np.asarray(s.chords)
        p, q = xy[ch[:, 0]], xy[ch[:, 1]]
        hc = math.sqrt(max(0.0, r * r - s.y_mm ** 2))
        xs = np.linspace(-0.45 * hc, 0.45 * hc, 5)
        for x0, x1 in zip(xs[:-1], xs[1:]):
            ys = [p[:, 1] + (x - p[:, 0]) * (q[:, 1] - p[:, 1]) / (q[:, 0] - p[:, 0]) for x in (x0, x1)]
            lo = min(y.min() for y in ys) - 1.5 * shift
            hi = max(y.max() for y in ys) + 1.5 * shift
            edges = np.arange(lo - shift, hi + shift + 0.1, 0.1)
            g = _covered_below(seg, x0, x1, edges, sheet.thread_mm, scanlines=32)[0]

            def cover(y0, y1):
                return (np.interp(y1, edges, g) - np.interp(y0, edges, g)) / (y1 - y0)

            best = []
            for n in range(1, max(1, int((hi - lo) / row)) + 1):
                bounds = np.linspace(lo, hi, n + 1)
                rows = [(y0, y1) for y0, y1 in zip(bounds[:-1], bounds[1:])
                        if cover(y0, y1) >= 0.01
                        and max(abs(cover(y0 + e, y1 + e) - cover(y0, y1)) for e in (shift, -shift))
                        <= ROBUST * cover(y0, y1)]
                if len(rows) > len(best):
                    best = rows
            cells += [(x0, x1, y0, y1) for y0, y1 in best]
            owner += [k] * len(best)
    return np.asarray(cells, dtype=float).reshape(-1, 4), np.asarray(owner, dtype=int)


def _segments(sheet):
    """The sheet's chords as ``(a, b, slope, half)``: ends ordered by x, slope dy/dx, and the vertical
    half-height of a band per mm of its width."""
    seg = sheet.chord_mm()
    a, b = seg[:, 0], seg[:, 1]
    swap = a[:, 0] > b[:, 0]
    a, b = np.where(swap[:, None], b, a), np.where(swap[:, None], a, b)
    slope = (b[:, 1] - a[:, 1]) / np.maximum(b[:, 0] - a[:, 0], 1e-9)
    return a, b, slope, 0.5 * np.sqrt(1.0 + slope ** 2)


def _covered_below(seg, x0, x1, edges, widths, *, scanlines):
    """Covered length below each of ``edges`` (sorted heights, mm) for bands of each of ``widths``,
    averaged over vertical scanlines across ``[x0, x1]``: the union of the bands, exactly along each
    scanline.  Returns shape ``(widths, edges)``."""
    a, b, slope, half = seg
    widths = np.atleast_1d(widths)
    lo, hi = edges[0], edges[-1]
    reach = widths.max() * half
    ya, yb = a[:, 1] + (x0 - a[:, 0]) * slope, a[:, 1] + (x1 - a[:, 0]) * slope
    near = (a[:, 0] < x1) & (b[:, 0] > x0) & (np.maximum(ya, yb) + reach > lo) & (np.minimum(ya, yb) - reach < hi)
    out = np.zeros((len(widths), len(edges)))
    if not near.any():
        return out
    xs = x0 + (np.arange(scanlines) + 0.5) / scanlines * (x1 - x0)
    yc = a[near, 1] + (xs[:, None] - a[near, 0]) * slope[near]            # (scanlines, chords)
    inside = (xs[:, None] >= a[near, 0]) & (xs[:, None] <= b[near, 0])
    order = np.argsort(np.where(inside, yc, -np.inf), axis=1)
    yc = np.take_along_axis(yc, order, axis=1)
    h = half[near][order]
    inside = np.take_along_axis(inside, order, axis=1)
    first = np.full((scanlines, 1), lo)
    for j, w in enumerate(widths):
        s = np.where(inside, np.clip(yc - w * h, lo, hi), lo)
        e = np.where(inside, np.clip(yc + w * h, lo, hi), lo)
        s = np.maximum(s, np.concatenate([first, np.maximum.accumulate(e, axis=1)[:, :-1]], axis=1))
        e = np.maximum(e, s)     # the part of each band not under those below it: disjoint, same union
        if len(edges) == 2:
            out[j, 1] = (e - s).sum() / scanlines
        else:
            out[j] = np.clip(edges[:, None, None] - s, 0.0, e - s).sum(axis=2).mean(axis=1)
    return out


def cell_coverage(sheet, widths, *, scanlines=96):
    """Covered fraction of each cell for each thread width: the exact union of sharp opaque bands.

    Each chord is a band of the given width centred on the line between its pins' centres.  Along
    ``scanlines`` vertical lines through each cell the bands' intervals are merged exactly (a spot
    under two threads counts once) and the covered length averaged.

    Parameters
    ----------
    sheet : Sheet
    widths : array_like of float, shape (w,)
        Thread widths in mm.

    Returns
    -------
    ndarray of float, shape (cells, w)
    """
    widths = np.atleast_1d(np.asarray(widths, dtype=np.float64))
    seg = _segments(sheet)
    out = np.zeros((len(sheet.cells), len(widths)))
    for k, (x0, x1, y0, y1) in enumerate(sheet.cells):
        out[k] = _covered_below(seg, x0, x1, np.array([y0, y1]), widths, scanlines=scanlines)[:, 1] / (y1 - y0)
    return out


def sheet_plan(sheet, *, machine, thread_mm, name=None):
    """The sheet as a plan (version 1) that ``stringbot wind`` winds; its design in ``calibration``.

    ``machine`` is recorded as ``plan --machine`` records it (the name or path as given: ``wind`` finds
    it there), ``name`` (default ``machine``) the machine's own name.  ``thread_mm`` is the plan's (the
    width the machine's plans are drawn at); the thread the densities were chosen for is
    ``calibration.thread_mm``.
    """
    from ..model.chords import thread_length
    from ..plan_file import Plan

    pin_xy = pin_positions(sheet.pins)
    chords = list(zip(sheet.sequence[:-1], sheet.sequence[1:]))
    info = {"format": SHEET_FORMAT, "version": SHEET_VERSION, "machine": name or machine,
            "ring": {"pins": sheet.pins, "diameter_mm": sheet.diameter_mm,
                     "pin_diameter_mm": sheet.pin_diameter_mm},
            "thread_mm": sheet.thread_mm, "sheet_mm": round(2 * sheet.half_mm, 3),
            "patches": [{"name": s.name, "tilt": s.tilt, "y_mm": round(s.y_mm, 3),
                         "lines_per_mm": round(s.lines_per_mm, 4), "chords": len(s.chords)} for s in sheet.strips],
            "marks": [[round(float(v), 3) for v in row] for row in sheet.marks]}
    return Plan(pins=sheet.pins, frame="circle", pin_xy=pin_xy, crop={"cx": 0.0, "cy": 0.0, "r": sheet.radius_mm},
                sequence=list(sheet.sequence), method="calibration", parameters={"machine": machine},
                source={}, stats={"lines": len(chords),
                                  "thread_diameters": round(thread_length(pin_xy, chords), 3)},
                diameter_mm=sheet.diameter_mm, thread_mm=float(thread_mm), extra={"calibration": info})


def sheet_from_plan(plan, *, pins, diameter_mm, pin_diameter_mm, machine, where):
    """The :class:`Sheet` a plan written by :func:`sheet_plan` was made from, checked against the ring.

    Raises
    ------
    BadInput
        The plan is not a calibration sheet, is for another ring, or its sequence is not the design's.
    """
    info = plan.extra.get("calibration")
    if not isinstance(info, dict) or info.get("format") != SHEET_FORMAT:
        raise BadInput(f"{where} is a plan but not a calibration sheet; expected the plan that "
                       "`stringbot calibrate sheet` wrote")
    if info.get("version") != SHEET_VERSION:
        raise BadInput(f"{where}: calibration sheet version {info.get('version')!r}; expected {SHEET_VERSION}")
    ring = info.get("ring") if isinstance(info.get("ring"), dict) else {}
    theirs = (ring.get("pins"), ring.get("diameter_mm"))
    if theirs != (pins, diameter_mm) or plan.pins != pins:
        raise BadInput(f"{where} is a calibration sheet for machine {info.get('machine')!r} ({theirs[0]} pins "
                       f"on {theirs[1]} mm), not for machine {machine!r} ({pins} pins on {diameter_mm:g} mm); "
                       "expected the sheet made with the same --machine")
    thread = info.get("thread_mm")
    if isinstance(thread, bool) or not isinstance(thread, (int, float)) or not thread > 0:
        raise BadInput(f"{where}: field 'calibration.thread_mm' is {thread!r}; expected the plan that "
                       "`stringbot calibrate sheet` wrote")
    sheet = design_sheet(pins=pins, diameter_mm=diameter_mm, pin_diameter_mm=pin_diameter_mm, thread_mm=float(thread))
    if tuple(plan.sequence) != sheet.sequence:
        raise BadInput(f"{where}: its pin sequence is not the calibration sheet this stringbot designs for "
                       f"{pins} pins; expected the plan that `stringbot calibrate sheet` wrote, unedited")
    return sheet
