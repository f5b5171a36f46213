"""A 1:1 line drawing in millimetres, written as SVG or as a tiled vector PDF (stdlib only).

A :class:`Drawing` holds primitives in millimetres, x right and y down from its
top-left corner: circles, lines, polylines and text (a monospaced font, so that
text can be anchored exactly in both formats).  :func:`to_svg` writes it with
``width="...mm"`` and a viewBox in millimetres, so any viewer prints it at its
true size; :func:`to_pdf` writes PDF 1.4 by hand (objects, a cross-reference
table, Flate-compressed content streams) on A4 or Letter pages, tiled with an
overlap when the drawing is larger than the printable area of one page.  Every
page maps drawing millimetres to PDF points by one matrix,
``[k 0 0 -k e f]`` with ``k = 72 / 25.4``, so positions are exact.

Primitives may carry a ``tag`` (e.g. ``"pin 17"``): an SVG ``data-tag``
attribute, a ``% tag`` comment in the PDF content stream, so that tests (and
curious users) can find them again.
"""

import math
import zlib
from dataclasses import dataclass, field

__all__ = ["Drawing", "to_svg", "to_pdf", "PAPERS", "PT_PER_MM", "tile_layout"]

PT_PER_MM = 72.0 / 25.4
#: Paper sizes (width, height) in mm, portrait.
PAPERS = {"a4": (210.0, 297.0), "letter": (215.9, 279.4)}
#: Courier's advance width, in em (every glyph): text is anchored exactly.
CHAR_EM = 0.6


def _f(x):
    """A coordinate as short text: 4 decimals (0.1 micrometre), no trailing zeros."""
    text = f"{x:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


@dataclass
class Drawing:
    """Primitives in mm (x right, y down), on a sheet ``width`` x ``height`` mm."""

    width: float
    height: float
    items: list = field(default_factory=list)
    title: str = ""

    def circle(self, cx, cy, r, *, width=0.15, fill=False, tag=None):
        self.items.append(("circle", dict(cx=cx, cy=cy, r=r, width=width, fill=fill, tag=tag)))

    def line(self, x1, y1, x2, y2, *, width=0.15, tag=None):
        self.items.append(("line", dict(x1=x1, y1=y1, x2=x2, y2=y2, width=width, tag=tag)))

    def polyline(self, points, *, width=0.15, fill=False, tag=None):
        self.items.append(("polyline", dict(points=[tuple(p) for p in points], width=width, fill=fill,
                                            tag=tag)))

    def text(self, x, y, text, *, size=3.0, angle=0.0, anchor="start", tag=None):
        """``text`` with its baseline through (x, y), turned ``angle`` degrees clockwise."""
        if anchor not in ("start", "middle", "end"):
            raise ValueError(f"anchor {anchor!r}; expected start, middle or end")
        self.items.append(("text", dict(x=x, y=y, text=str(text), size=size, angle=angle, anchor=anchor,
                                         tag=tag)))


def _bbox(kind, a):
    """(x0, y0, x1, y1) of an item, a little generous."""
    if kind == "circle":
        return a["cx"] - a["r"], a["cy"] - a["r"], a["cx"] + a["r"], a["cy"] + a["r"]
    if kind == "line":
        return min(a["x1"], a["x2"]), min(a["y1"], a["y2"]), max(a["x1"], a["x2"]), max(a["y1"], a["y2"])
    if kind == "polyline":
        xs, ys = [p[0] for p in a["points"]], [p[1] for p in a["points"]]
        return min(xs), min(ys), max(xs), max(ys)
    length = len(a["text"]) * CHAR_EM * a["size"] + a["size"]
    return a["x"] - length, a["y"] - length, a["x"] + length, a["y"] + length


# ---- SVG ---------------------------------------------------------------------------------


def _esc(text):
    return (str(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace('"', "&quot;"))


def to_svg(drawing):
    """The drawing as SVG text, 1:1 (``width``/``height`` in mm, viewBox in mm)."""
    w, h = drawing.width, drawing.height
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<svg xmlns="http://www.w3.org/2000/svg" width="{_f(w)}mm" height="{_f(h)}mm" '
           f'viewBox="0 0 {_f(w)} {_f(h)}">']
    if drawing.title:
        out.append(f"<title>{_esc(drawing.title)}</title>")
    out.append('<g fill="none" stroke="black" stroke-linecap="round" '
               'font-family="Courier New, Courier, monospace">')
    for kind, a in drawing.items:
        tag = f' data-tag="{_esc(a["tag"])}"' if a.get("tag") else ""
        if kind == "circle":
            fill = ' fill="black"' if a["fill"] else ""
            out.append(f'<circle{tag} cx="{_f(a["cx"])}" cy="{_f(a["cy"])}" r="{_f(a["r"])}" '
                       f'stroke-width="{_f(a["width"])}"{fill}/>')
        elif kind == "line":
            out.append(f'<line{tag} x1="{_f(a["x1"])}" y1="{_f(a["y1"])}" x2="{_f(a["x2"])}" '
                       f'y2="{_f(a["y2"])}" stroke-width="{_f(a["width"])}"/>')
        elif kind == "polyline":
            pts = " ".join(f"{_f(x)},{_f(y)}" for x, y in a["points"])
            el = "polygon" if a["fill"] else "polyline"
            fill = ' fill="black"' if a["fill"] else ""
            out.append(f'<{el}{tag} points="{pts}" stroke-width="{_f(a["width"])}"{fill}/>')
        else:
            rot = f' transform="rotate({_f(a["angle"])} {_f(a["x"])} {_f(a["y"])})"' if a["angle"] else ""
            out.append(f'<text{tag} x="{_f(a["x"])}" y="{_f(a["y"])}" font-size="{_f(a["size"])}" '
                       f'text-anchor="{a["anchor"]}" fill="black" stroke="none"{rot}>{_esc(a["text"])}</text>')
    out += ["</g>", "</svg>", ""]
    return "\n".join(out)


# ---- PDF ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Tile:
    """One page of a tiled drawing: the part ``x0 .. x0 + w``, ``y0 .. y0 + h`` (mm) of it."""

    row: int
    col: int
    x0: float
    y0: float
    w: float
    h: float


def tile_layout(width, height, *, paper="a4", margin=10.0, overlap=10.0):
    """How a ``width`` x ``height`` mm drawing is laid on pages.

    Returns
    -------
    (page_w, page_h, tiles)
        The page size in mm (portrait, or landscape when that takes fewer
        pages) and the
        tiles, row by row.  Each tile shows a printable area of the page
        (page less ``margin`` on every side); neighbouring tiles overlap by
        ``overlap`` mm.
    """
    if paper not in PAPERS:
        raise ValueError(f"paper {paper!r}; expected one of {', '.join(PAPERS)}")
    best = None
    for pw, ph in (PAPERS[paper], PAPERS[paper][::-1]):     # portrait, then landscape
        aw, ah = pw - 2 * margin, ph - 2 * margin
        sx, sy = aw - overlap, ah - overlap
        nx = 1 if width <= aw + 1e-9 else math.ceil((width - aw) / sx - 1e-9) + 1
        ny = 1 if height <= ah + 1e-9 else math.ceil((height - ah) / sy - 1e-9) + 1
        if best is None or nx * ny < best[0]:
            best = (nx * ny, pw, ph, [Tile(r, c, c * sx, r * sy, aw, ah) for r in range(ny) for c in range(nx)])
    return best[1:]


def _pdf_text(text):
    return "(" + text.replace("\\", "\\\\").replace("(", "\\(").replace(")", "\\)") + ")"


_KAPPA = 0.5522847498


def _circle_ops(cx, cy, r):
    k = _KAPPA * r
    f = _f
    return [f"{f(cx + r)} {f(cy)} m",
            f"{f(cx + r)} {f(cy + k)} {f(cx + k)} {f(cy + r)} {f(cx)} {f(cy + r)} c",
            f"{f(cx - k)} {f(cy + r)} {f(cx - r)} {f(cy + k)} {f(cx - r)} {f(cy)} c",
            f"{f(cx - r)} {f(cy - k)} {f(cx - k)} {f(cy - r)} {f(cx)} {f(cy - r)} c",
            f"{f(cx + k)} {f(cy - r)} {f(cx + r)} {f(cy - k)} {f(cx + r)} {f(cy)} c"]


def _item_ops(kind, a):
    ops = [f"% {a['tag']}"] if a.get("tag") else []
    if kind == "text":
        t = math.radians(a["angle"])
        s = a["size"]
        shift = {"start": 0.0, "middle": 0.5, "end": 1.0}[a["anchor"]] * len(a["text"]) * CHAR_EM * s
        x = a["x"] - shift * math.cos(t)
        y = a["y"] - shift * math.sin(t)
        ops.append(f"BT /F1 1 Tf {_f(s * math.cos(t))} {_f(s * math.sin(t))} {_f(s * math.sin(t))} "
                   f"{_f(-s * math.cos(t))} {_f(x)} {_f(y)} Tm {_pdf_text(a['text'])} Tj ET")
        return ops
    ops.append(f"{_f(a['width'])} w")
    if kind == "circle":
        ops += _circle_ops(a["cx"], a["cy"], a["r"])
        ops.append("b" if a["fill"] else "S")
    elif kind == "line":
        ops += [f"{_f(a['x1'])} {_f(a['y1'])} m", f"{_f(a['x2'])} {_f(a['y2'])} l", "S"]
    else:
        pts = a["points"]
        ops.append(f"{_f(pts[0][0])} {_f(pts[0][1])} m")
        ops += [f"{_f(x)} {_f(y)} l" for x, y in pts[1:]]
        ops.append("b" if a["fill"] else "S")
    return ops


def _page_stream(drawing, tile, page_w, page_h, margin, label):
    k = PT_PER_MM
    # drawing mm (y down) -> page points (y up): X = k (x - x0 + margin), Y = k (page_h - margin - (y - y0))
    e = k * (margin - tile.x0)
    f = k * (page_h - margin + tile.y0)
    ops = ["1 J 1 j 0 G 0 g"]
    if label:
        ops.append("q")
        ops.append(f"BT /F1 8 Tf {_f(k * margin)} {_f(k * margin / 2 - 3)} Td {_pdf_text(label)} Tj ET")
        ops.append("Q")
    ops += ["q", f"{_f(k * margin)} {_f(k * margin)} {_f(k * tile.w)} {_f(k * tile.h)} re W n",
            f"% tile {tile.row} {tile.col} x0 {_f(tile.x0)} y0 {_f(tile.y0)}",
            f"{_f(k)} 0 0 {_f(-k)} {_f(e)} {_f(f)} cm"]
    x1, y1 = tile.x0 + tile.w, tile.y0 + tile.h
    for kind, a in drawing.items:
        bx0, by0, bx1, by1 = _bbox(kind, a)
        if bx1 < tile.x0 or bx0 > x1 or by1 < tile.y0 or by0 > y1:
            continue
        ops += _item_ops(kind, a)
    ops.append("Q")
    return ("\n".join(ops) + "\n").encode("latin-1", "replace")


def to_pdf(drawing, *, paper="a4", margin=10.0, overlap=10.0, page_label=None):
    """The drawing as PDF bytes at 1:1, tiled on ``paper`` pages when it does not fit one.

    Parameters
    ----------
    drawing : Drawing
    paper : {"a4", "letter"}
    margin : float
        Unprinted border of every page, mm (most printers cannot print the edge).
    overlap : float
        How much neighbouring tiles share, mm: glue or tape them so that their
        alignment marks coincide.
    page_label : callable(Tile, int rows, int cols) -> str, optional
        A line printed in each page's bottom margin.

    Returns
    -------
    bytes
    """
    page_w, page_h, tiles = tile_layout(drawing.width, drawing.height, paper=paper, margin=margin,
                                        overlap=overlap)
    rows = max(t.row for t in tiles) + 1
    cols = max(t.col for t in tiles) + 1
    objects = {1: b"<< /Type /Catalog /Pages 2 0 R >>",
               3: b"<< /Type /Font /Subtype /Type1 /BaseFont /Courier /Encoding /WinAnsiEncoding >>"}
    kids = []
    n = 4
    for tile in tiles:
        label = page_label(tile, rows, cols) if page_label else ""
        raw = _page_stream(drawing, tile, page_w, page_h, margin, label)
        data = zlib.compress(raw, 9)
        objects[n + 1] = (f"<< /Length {len(data)} /Filter /FlateDecode >>\nstream\n".encode()
                          + data + b"\nendstream")
        objects[n] = (f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {_f(page_w * PT_PER_MM)} "
                      f"{_f(page_h * PT_PER_MM)}] /Resources << /Font << /F1 3 0 R >> >> "
                      f"/Contents {n + 1} 0 R >>").encode()
        kids.append(f"{n} 0 R")
        n += 2
    objects[2] = f"<< /Type /Pages /Kids [{' '.join(kids)}] /Count {len(kids)} >>".encode()
    info = n
    objects[info] = (f"<< /Title {_pdf_text(drawing.title)} /Producer (stringbot) >>"
                     .encode("latin-1", "replace"))
    out = bytearray(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n")
    offsets = {}
    for num in sorted(objects):
        offsets[num] = len(out)
        out += f"{num} 0 obj\n".encode() + objects[num] + b"\nendobj\n"
    xref = len(out)
    count = max(objects) + 1
    out += f"xref\n0 {count}\n".encode() + b"0000000000 65535 f \n"
    for num in range(1, count):
        out += f"{offsets[num]:010d} 00000 n \n".encode()
    out += (f"trailer\n<< /Size {count} /Root 1 0 R /Info {info} 0 R >>\nstartxref\n{xref}\n%%EOF\n"
            .encode())
    return bytes(out)
