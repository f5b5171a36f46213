"""The calibration sheet and the fit of a photo of it (stringbot/planner/calibration*.py).

Photos are synthetic (benchmarks/calibration_photos.py): the sheet seen through a perspective, its
threads sharp opaque bands of a known width drawn sample by sample, then lit unevenly, blurred, given
noise and written as 8-bit sRGB.  A small ring (120 pins on 200 mm) keeps them fast; full-size runs
are in benchmarks/bench_calibrate.py.
"""

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from stringbot.errors import BadInput
from stringbot.planner.calibration.sheet import cell_coverage, design_sheet, sheet_from_plan, sheet_plan
from stringbot.planner.calibration.photo import fit_photo, find_sheet, read_photo

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from calibration_photos import camera, render_photo  # noqa: E402

SMALL = dict(pins=120, diameter_mm=200.0, pin_diameter_mm=1.5)
SHAPE = (480, 640)


@pytest.fixture(scope="module")
def sheet():
    return design_sheet(thread_mm=0.25, **SMALL)


def photo(tmp_path, sheet, width, name="photo.png", **kw):
    tf = camera(sheet, SHAPE, tilt=kw.pop("tilt", (0.12, -0.08)), turn=kw.pop("turn", -15.0),
                shift=kw.pop("shift", (0.03, -0.02)), fill=0.72)
    path = tmp_path / name
    Image.fromarray(render_photo(sheet, tf, SHAPE, width_mm=width, k=3, **kw)).save(path)
    return path, tf


@pytest.mark.parametrize("pins, diameter, thread", [(60, 100.0, 0.3), (120, 200.0, 0.25), (300, 500.0, 0.25),
                                                     (300, 500.0, 0.15), (1000, 800.0, 0.4)])
def test_the_sheet_is_one_thread_through_every_patch_chord(pins, diameter, thread):
    s = design_sheet(pins=pins, diameter_mm=diameter, pin_diameter_mm=1.0, thread_mm=thread)
    seq = s.sequence
    assert all(0 <= p < pins for p in seq) and all(a != b for a, b in zip(seq[:-1], seq[1:]))
    wound = {frozenset(c) for c in zip(seq[:-1], seq[1:])}
    assert all(frozenset(c) in wound for strip in s.strips for c in strip.chords)
    densities = sorted(strip.lines_per_mm for strip in s.strips)
    assert len(densities) >= 3 and densities[-1] * thread > 0.6      # the densest patch is about half covered
    assert len(s.cells) >= 12 and set(s.cell_strip) == set(range(len(s.strips)))
    # the chords that join the patches stay in the rim band no measurement uses
    xy = s.pin_mm()
    patch = {frozenset(c) for strip in s.strips for c in strip.chords}
    for a, b in zip(seq[:-1], seq[1:]):
        if frozenset((a, b)) not in patch:
            mid = (xy[a] + xy[b]) / 2
            assert np.hypot(*mid) > s.radius_mm - s.rim_mm


def test_the_sheet_is_the_same_design_every_time_and_is_refused_for_another_ring(sheet):
    again = design_sheet(thread_mm=0.25, **SMALL)
    assert again.sequence == sheet.sequence and np.array_equal(again.cells, sheet.cells)
    plan = sheet_plan(sheet, machine="small", thread_mm=0.25)
    assert sheet_from_plan(plan, machine="small", where="sheet", **SMALL).sequence == sheet.sequence
    thick = design_sheet(thread_mm=0.4, **SMALL)             # densities for another thread: another sequence
    assert thick.sequence != sheet.sequence
    back = sheet_from_plan(sheet_plan(thick, machine="small", thread_mm=0.4), machine="small", where="sheet",
                           **SMALL)
    assert back.sequence == thick.sequence and back.thread_mm == 0.4
    edited = replace(plan, sequence=plan.sequence[:-1])
    with pytest.raises(BadInput, match="its pin sequence is not the calibration sheet"):
        sheet_from_plan(edited, machine="small", where="sheet", **SMALL)
    with pytest.raises(BadInput, match=r"for machine 'small' \(120 pins on 200\.0 mm\), not for machine 'big' "
                                       r"\(300 pins on 500 mm\)"):
        sheet_from_plan(plan, machine="big", where="sheet", pins=300, diameter_mm=500.0, pin_diameter_mm=1.5)
    with pytest.raises(BadInput, match="at least 60 pins"):
        design_sheet(pins=40, diameter_mm=200.0, pin_diameter_mm=1.0, thread_mm=0.25)


def test_cell_coverage_is_the_union_of_the_threads_measured_by_brute_force(sheet):
    """A slice of one cell per patch against a point-by-point count on a fine grid (a point is covered when it
    lies within half a width of some chord): an independent computation of the same union."""
    picked = [int(np.argmax(sheet.cell_strip == k)) for k in range(len(sheet.strips))]
    slices = np.array([[x0, x0 + 3.0, y0, y1] for x0, x1, y0, y1 in sheet.cells[picked]])
    ab = sheet.chord_mm()
    a, d = ab[:, 0], ab[:, 1] - ab[:, 0]
    n = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.hypot(d[:, 0], d[:, 1])[:, None]
    want = cell_coverage(replace(sheet, cells=slices), [0.1, 0.4])
    for (x0, x1, y0, y1), f in zip(slices, want):
        x, y = np.meshgrid(np.arange(x0 + 0.05, x1, 0.1), np.arange(y0 + 0.0015, y1, 0.003))
        p = np.stack([x.ravel(), y.ravel()], axis=1)
        centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
        near = np.abs(((centre - a) * n).sum(axis=1)) < math.hypot(x1 - x0, y1 - y0)
        nearest = np.full(len(p), np.inf)          # distance to the nearest chord's line
        for j in np.flatnonzero(near):
            nearest = np.minimum(nearest, np.abs((p - a[j]) @ n[j]))
        for width, fw in zip((0.1, 0.4), f):
            covered = (nearest < width / 2).mean()
            assert abs(covered - fw) < 0.002 + 0.01 * fw, (width, covered, fw)


@pytest.mark.parametrize("width", [0.15, 0.5])
def test_the_fitted_width_is_within_five_percent_through_perspective_uneven_light_blur_and_noise(
        tmp_path, sheet, width):
    path, _ = photo(tmp_path, sheet, width, board=0.70, thread=0.05, paper=0.9, gradient=(0.5, 35.0),
                    vignette=0.35, blur=1.0, noise=0.015)
    fit = fit_photo(path, sheet)
    assert abs(fit.effective_mm / width - 1) < 0.05
    assert abs(fit.board - 0.70 / 0.9) < 0.02                 # relative to the paper
    assert abs(fit.thread - 0.05 / 0.9) < 0.02
    assert fit.rms < 0.01


def test_the_marks_give_the_camera(tmp_path, sheet):
    path, tf = photo(tmp_path, sheet, 0.25, tilt=(-0.15, 0.1), turn=170.0)     # upside down, too
    found = find_sheet(read_photo(path), sheet)
    probe = np.array([[x, y] for x in (-90, 0, 90) for y in (-90, 0, 90)], float)
    assert np.abs(found(probe) - tf(probe)).max() < 0.5                       # pixels


def test_a_photo_without_the_marks_is_refused_saying_what_was_not_found(tmp_path, sheet):
    path, _ = photo(tmp_path, sheet, 0.25, marks=False)
    with pytest.raises(BadInput, match=r"marks were not found \(hollow ring marks: 0, disc marks: 0; .*"
                                       r"expected a photo of the whole wound sheet from `stringbot calibrate sheet`"):
        fit_photo(path, sheet)
    with pytest.raises(BadInput, match="marks were not found"):
        fit_photo(Path(__file__).resolve().parents[1] / "examples" / "camera.png", sheet)


def test_a_photo_of_the_sheet_not_wound_is_refused(tmp_path, sheet):
    path, _ = photo(tmp_path, sheet, 0.25, threads=False)
    with pytest.raises(BadInput, match="no darker than the bare board .* expected a photo of the sheet wound"):
        fit_photo(path, sheet)


def test_a_file_that_is_not_a_picture_is_refused(tmp_path, sheet):
    bad = tmp_path / "photo.jpg"
    bad.write_text("not a picture\n")
    with pytest.raises(BadInput, match=r"photo '.*photo.jpg' is not a picture PIL can read; expected PNG, JPEG"):
        fit_photo(bad, sheet, what="photo")


def test_the_template_prints_the_marks_where_the_fit_looks_and_nothing_inside_the_measured_disc(sheet):
    import re

    from stringbot.motion.calibration_sheet import sheet_pdf, sheet_svg

    svg = sheet_svg(sheet)
    h = sheet.half_mm
    for k, (x, y, r) in enumerate(sheet.marks):
        m = re.search(rf'<circle data-tag="mark {k}[^"]*" cx="([\d.]+)" cy="([\d.]+)" r="([\d.]+)" '
                      rf'stroke-width="([\d.]+)"', svg)
        cx, cy, rr, sw = map(float, m.groups())
        assert math.hypot(cx - h - x, cy - h - y) < 1e-3
        outer = rr + sw / 2 if k == 0 else rr
        assert abs(outer - r) < 1e-3
    inside = sheet.radius_mm - 0.5 * sheet.rim_mm
    for cx, cy, rr in re.findall(r'<circle data-tag="(?!cut)[^"]*" cx="([\d.]+)" cy="([\d.]+)" r="([\d.]+)"', svg):
        assert math.hypot(float(cx) - h, float(cy) - h) - float(rr) > inside - 1e-6
    pdf = design_sheet(pins=300, diameter_mm=500.0, pin_diameter_mm=1.5, thread_mm=0.25)
    data = sheet_pdf(pdf, paper="a4")
    assert data.startswith(b"%PDF-1.4") and data.count(b"/Type /Page ") > 1
