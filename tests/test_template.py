"""`stringbot template`: the drilling template, read back from the files and measured.

The SVG is parsed as XML (its user unit must be the millimetre: width="Wmm" and a
viewBox W wide), the PDF by its own structure (the cross-reference table, each
page's Flate stream, the one matrix that maps millimetres to points); each pin's
centre is measured from the centre mark and compared with the machine file's
geometry: the pin circle's diameter, pin i at 360 i / pins degrees clockwise from
the top.
"""

import math
import re
import xml.etree.ElementTree as ET
import zlib

import pytest

from firmware_protocol.machine import load_machine
from test_cli_plan import one_error_line, run

SVG = "{http://www.w3.org/2000/svg}"
PT = 72 / 25.4


def expected(pins, diameter):
    r = diameter / 2
    return [(r * math.sin(2 * math.pi * i / pins), -r * math.cos(2 * math.pi * i / pins)) for i in range(pins)]


def svg_points(path):
    root = ET.parse(path).getroot()
    w = root.get("width")
    assert w.endswith("mm") and root.get("height").endswith("mm")
    vb = [float(v) for v in root.get("viewBox").split()]
    assert vb[0] == 0 and vb[1] == 0 and abs(vb[2] - float(w[:-2])) < 1e-9, "the user unit is not 1 mm"
    pins, centre = {}, None
    for el in root.iter():
        tag = el.get("data-tag") or ""
        m = re.fullmatch(r"pin (\d+) cross", tag)
        if m:       # the horizontal stroke of the pin's cross: its midpoint is the centre
            x = (float(el.get("x1")) + float(el.get("x2"))) / 2
            pins[int(m.group(1))] = (x, float(el.get("y1")))
        elif tag == "centre":
            centre = ((float(el.get("x1")) + float(el.get("x2"))) / 2, float(el.get("y1")))
        elif re.fullmatch(r"pin (\d+)", tag):
            assert el.tag == SVG + "circle"
    return pins, centre


def pdf_pages(data):
    """[(media_box, content text)] by the file's own cross-reference table."""
    assert data.startswith(b"%PDF-1.4")
    start = int(re.search(rb"startxref\s+(\d+)", data).group(1))
    table = data[start:].split(b"trailer")[0].split(b"\n")
    count = int(table[1].split()[1])
    offsets = [int(row[:10]) for row in table[2:2 + count]]
    objs = {}
    for num, off in enumerate(offsets):
        if num == 0:
            continue
        head = data[off:off + 20]
        assert head.startswith(f"{num} 0 obj".encode()), (num, head)
        objs[num] = data[off:data.index(b"endobj", off)]
    pages = []
    kids = re.search(rb"/Kids \[([^\]]*)\]", objs[2]).group(1).split(b" 0 R")
    for kid in [int(k) for k in kids if k.strip()]:
        page = objs[kid]
        box = [float(v) for v in re.search(rb"/MediaBox \[([^\]]*)\]", page).group(1).split()]
        content = int(re.search(rb"/Contents (\d+) 0 R", page).group(1))
        body = objs[content]
        length = int(re.search(rb"/Length (\d+)", body).group(1))
        raw = body[body.index(b"stream\n") + 7:][:length]
        pages.append((box, zlib.decompress(raw).decode("latin-1")))
    return pages


def pdf_points(data):
    """Pin centres and the centre mark, in mm, each page's drawing put back where its matrix says;
    every page must map 1 mm to exactly 72/25.4 pt (printed at 100 %)."""
    pins, centres, tiles = {}, [], []
    for box, text in pdf_pages(data):
        lines = text.splitlines()
        m = next(re.fullmatch(r"(\S+) 0 0 (\S+) (\S+) (\S+) cm", ln) for ln in lines if ln.endswith(" cm"))
        a, d, e, f = (float(v) for v in m.groups())
        assert abs(a - PT) < 1e-4 and abs(d + PT) < 1e-4, "a page is not at 1:1"
        tiles.append((box, e, f))
        for k, ln in enumerate(lines):
            tag = ln[2:] if ln.startswith("% ") else None
            if tag is None or not (re.fullmatch(r"pin \d+ cross", tag) or tag == "centre"):
                continue
            x1, y1 = (float(v) for v in lines[k + 2].split()[:2])     # "w", then "x y m", "x y l"
            x2, _ = (float(v) for v in lines[k + 3].split()[:2])
            # page points, as the printer puts them on paper, then back to the sheet's mm by the matrix
            px, py = a * (x1 + x2) / 2 + e, d * y1 + f
            sheet = ((px - e) / a, (py - f) / d)
            if tag == "centre":
                centres.append(sheet)
            else:
                pins.setdefault(int(tag.split()[1]), []).append(sheet)
    return pins, centres, tiles


def max_error(points, centre, pins, diameter):
    want = expected(pins, diameter)
    return max(math.hypot(points[i][0] - centre[0] - want[i][0], points[i][1] - centre[1] - want[i][1])
               for i in range(pins))


def test_svg_pins_equal_the_machine_file(tmp_path):
    m = load_machine("grbl-ring")
    out = tmp_path / "ring.svg"
    code, stdout, err = run("template", "--machine", "grbl-ring", "-o", out)
    assert code == 0, err
    assert "300 pins on a 500 mm circle" in stdout
    points, centre = svg_points(out)
    assert sorted(points) == list(range(m.pins))
    assert max_error(points, centre, m.pins, m["ring.diameter_mm"]) < 0.01
    text = out.read_text()
    assert "PIN 0" in text and "pins count this way" in text and "100 mm" in text
    # the ruler: a line exactly 100 mm long
    ruler = next(el for el in ET.parse(out).getroot().iter() if el.get("data-tag") == "ruler")
    assert abs(float(ruler.get("x2")) - float(ruler.get("x1")) - 100.0) < 1e-9


@pytest.mark.parametrize("paper, size", [("a4", (210, 297)), ("letter", (215.9, 279.4))])
def test_pdf_tiles_a_large_ring_and_every_pin_is_where_the_machine_says(tmp_path, paper, size):
    m = load_machine("grbl-ring")
    out = tmp_path / "ring.pdf"
    code, stdout, err = run("template", "--machine", "grbl-ring", "-o", out, "--paper", paper)
    assert code == 0, err
    data = out.read_bytes()
    points, centres, tiles = pdf_points(data)
    assert len(tiles) > 1, "a 500 mm ring does not fit one page"
    for box, _, _ in tiles:
        w, h = sorted(box[2:])
        assert abs(w - min(size) * PT) < 0.01 and abs(h - max(size) * PT) < 0.01
    assert sorted(points) == list(range(m.pins))
    centre = centres[0]
    assert all(abs(c[0] - centre[0]) < 1e-6 and abs(c[1] - centre[1]) < 1e-6 for c in centres)
    # a pin on two pages (in the overlap) is at the same place on both
    merged = {}
    for i, places in points.items():
        for p in places:
            assert abs(p[0] - places[0][0]) < 1e-6 and abs(p[1] - places[0][1]) < 1e-6
        merged[i] = places[0]
    assert max_error(merged, centre, m.pins, m["ring.diameter_mm"]) < 0.01
    assert sum(len(v) for v in points.values()) > m.pins, "no pin lies in an overlap"
    pages = pdf_pages(data)
    assert all("Overlap the pages" in text for _, text in pages)
    assert sum(text.count("% alignment") for _, text in pages) >= 2 * (len(pages) - 1)


def test_pdf_tiles_overlap_by_10_mm_and_alignment_marks_agree(tmp_path):
    out = tmp_path / "ring.pdf"
    code, _, err = run("template", "--pins", "200", "--diameter-mm", "600", "-o", out)
    assert code == 0, err
    pages = pdf_pages(out.read_bytes())
    origins = []
    for box, text in pages:
        tile = re.search(r"% tile (\d+) (\d+) x0 (\S+) y0 (\S+)", text)
        origins.append((int(tile.group(1)), int(tile.group(2)), float(tile.group(3)), float(tile.group(4))))
    cols = sorted({o[2] for o in origins})
    printable = (min(pages[0][0][2:]) / PT) - 20
    assert abs((cols[1] - cols[0]) - (printable - 10)) < 1e-3, "neighbouring pages do not overlap by 10 mm"
    # every alignment mark is printed on at least two pages, at the same place on the sheet
    seen = {}
    for page, (_, text) in enumerate(pages):
        lines = text.splitlines()
        for k, ln in enumerate(lines):
            if ln == "% alignment":
                x, y = (round(float(v), 6) for v in lines[k + 2].split()[:2])
                seen.setdefault((x, y), set()).add(page)
    assert seen and all(len(p) >= 2 for p in seen.values()), seen


def test_pins_and_diameter_without_a_machine_and_a_small_ring_on_one_page(tmp_path):
    out = tmp_path / "small.pdf"
    code, _, err = run("template", "--pins", "24", "--diameter-mm", "100", "-o", out, "--pin-diameter-mm", "2")
    assert code == 0, err
    points, centres, tiles = pdf_points(out.read_bytes())
    assert len(tiles) == 1
    assert max_error({i: p[0] for i, p in points.items()}, centres[0], 24, 100.0) < 0.01
    svg = tmp_path / "small.svg"
    assert run("template", "--pins", "24", "--diameter-mm", "100", "-o", svg, "--pin-diameter-mm", "2")[0] == 0
    pts, centre = svg_points(svg)
    assert max_error(pts, centre, 24, 100.0) < 0.01
    circles = [el for el in ET.parse(svg).getroot().iter(SVG + "circle")
               if re.fullmatch(r"pin \d+", el.get("data-tag") or "")]
    assert len(circles) == 24 and all(float(c.get("r")) == 1.0 for c in circles)


@pytest.mark.parametrize("args, words", [
    (["--pins", "24", "-o", "x.svg"], "expected --machine NAME, or both --pins N and --diameter-mm D"),
    (["--machine", "grbl-ring", "--pins", "24", "-o", "x.svg"], "leave out --pins"),
    (["--pins", "24", "--diameter-mm", "100", "-o", "x.png"], "expected a file name ending in .svg or .pdf"),
    (["--pins", "24", "--diameter-mm", "100", "-o", "-"], "expected a file name ending in .svg or .pdf"),
    (["--pins", "2", "--diameter-mm", "100", "-o", "x.svg"], "--pins 2"),
    (["--pins", "400", "--diameter-mm", "100", "-o", "x.svg"], "do not fit"),
    (["--machine", "nosuch", "-o", "x.svg"], "unknown machine"),
])
def test_bad_template_input_is_one_line(tmp_path, args, words):
    code, _, err = run("template", *args, cwd=tmp_path)
    one_error_line(code, err, words)
    assert not (tmp_path / "x.svg").exists()
