"""Faces: SSIM inside the face box and over the frame, with and without ``--face``.

For each portrait the default plan (``stringbot plan IMG``: the default
method, auto lines, 300 pins, a 0.25 mm thread on 500 mm) is made with
``--face off`` and ``--face on``, and with ``--variants``: the face's
weights alone (the default centred crop), the face's crop alone (its weights
not raised), and the eyes, mouth and the face's edges weighed
:data:`FEATURES` more on top of the face; with ``--shapes`` the other weight
maps of :data:`SHAPES` (smooth bumps, larger and smaller ellipses, the face
weighed by its local contrast, the stop not weighed).  Each plan is scored as the user
gets it: drawn by the reference rendering at 512 px against the picture's
luminance read with the plan's own crop (white outside the frame),
scikit-image's ``structural_similarity`` (Gaussian window, sigma 1.5), its
map averaged over the face box (the one ``--face on`` found, in source
pixels, mapped into each plan's frame) and over the frame; plain and both
blurred by sigma 2 px.

Portraits: the astronaut (``../shared/images/astronaut.png``, NASA, public
domain) and three in ``benchmarks/data/`` (see its README.md for their
sources and licences): Grace Hopper, Barack Obama's 2012 official portrait,
Barack Obama speaking.

With ``--colors SPEC`` (e.g. ``auto:3``) the plans are colour plans (``stringbot plan IMG --colors SPEC``,
its defaults), scored by ``stringbot score``'s colour yardstick (``colour_score``): the luminance
SSIM inside the face box and over the frame, and the mean CIEDE2000 inside the box and over the frame.

With ``--starts own,37,151`` each plan is made from each of these start pins (``own``: the planner's
own), and the differences ``--face`` minus ``--face off`` (blurred, face box / frame) are printed for each
start and as their mean (a single plan's face figure scatters by about 0.025).

Usage: python benchmarks/bench_face.py [--json] [--variants] [--shapes] [--start-pin N] [--starts LIST] [--colors SPEC]
[--sheet docs/faces.png]
[IMAGE ...]
"""

import argparse
import contextlib
import json
import os
import sys
import time

# as the CLI: one BLAS thread, set before numpy loads (the polishes' long dot products stall among
# OpenBLAS's threads on a busy machine: a --face plan 80 s of CPU instead of 12)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = next((d / "shared" for d in ROOT.parents if (d / "shared" / "images").is_dir()), ROOT.parent / "shared")
sys.path.insert(0, str(ROOT))
PORTRAITS = [SHARED / "images" / "astronaut.png", ROOT / "benchmarks" / "data" / "grace_hopper.jpg",
             ROOT / "benchmarks" / "data" / "obama_portrait.jpg", ROOT / "benchmarks" / "data" / "obama_speech.jpg"]
#: side of a contact sheet's tile
SHEET_TILE = 240
KEYS = ("ssim_face", "ssim_frame", "ssim_face_blurred", "ssim_frame_blurred")


#: the "features" variant: the eyes, the mouth and the face's edges raised this much more than the face
FEATURES = (0.5, 0.3, 0.3)


@contextlib.contextmanager
def features(eyes, mouth, edges):
    """Plan with these extra weights on the eyes, the mouth and the face's edges (None: the defaults)."""
    from stringbot.planner.picture import face

    old = face.EYE_WEIGHT, face.MOUTH_WEIGHT, face.EDGE_WEIGHT
    if eyes is not None:
        face.EYE_WEIGHT, face.MOUTH_WEIGHT, face.EDGE_WEIGHT = eyes, mouth, edges
    try:
        yield
    finally:
        face.EYE_WEIGHT, face.MOUTH_WEIGHT, face.EDGE_WEIGHT = old


#: ``--shapes``: other weight maps over the face, each ``(name, kind, strength, a, b)``: ``ellipse`` the
#: default's soft-edged ellipse scaled ``a`` times; ``bump`` a Gaussian of sigma ``a`` x ``b`` of the box's
#: height x width; ``contrast`` the ellipse times ``a + (1 - a) c``, ``c`` the local contrast; ``flat stop``:
#: the default map, the eye's error (the stop of --lines auto) weighed by the frame alone
SHAPES = (("ellipse +2.02", "ellipse", 2.02, 1.0, 0), ("ellipse +2.5", "ellipse", 2.5, 1.0, 0),
          ("ellipse x1.3", "ellipse", 2.0, 1.3, 0), ("ellipse x0.8", "ellipse", 2.0, 0.8, 0),
          ("bump +2", "bump", 2.0, 0.55, 0.45), ("bump +3", "bump", 3.0, 0.55, 0.45),
          ("wide bump +2", "bump", 2.0, 0.8, 0.65), ("contrast +2", "contrast", 2.0, 0.3, 0),
          ("contrast +3", "contrast", 3.0, 0.3, 0), ("contrast +2.5", "contrast", 2.5, 0.6, 0),
          ("flat stop", "flat stop", 2.0, 1.0, 0))


def shape_weights(kind, strength, a, b):
    """A ``face_weights`` with another map over the face (see :data:`SHAPES`)."""
    import numpy as np
    from scipy.ndimage import gaussian_filter

    def weights(face, *, crop, size, gray, times=None, **_):
        k = size / (2.0 * crop["r"])
        rows, cols = np.mgrid[0:size, 0:size].astype(np.float64) + 0.5
        rows, cols = rows / k + crop["cy"] - crop["r"], cols / k + crop["cx"] - crop["r"]
        cy, cx = face.centre
        if kind == "bump":
            bump = np.exp(-0.5 * (((rows - cy) / (a * face.height)) ** 2 + ((cols - cx) / (b * face.width)) ** 2))
            out = 1.0 + strength * bump
        else:
            scale = a if kind == "ellipse" else 1.0
            d = np.hypot((rows - cy) / (0.62 * scale * face.height), (cols - cx) / (0.5 * scale * face.width))
            inside = np.clip((1.15 - d) / 0.3, 0.0, 1.0)
            if kind == "contrast":
                g, s = np.asarray(gray, np.float64), max(1.0, 0.05 * face.width * k)
                m = gaussian_filter(g, s)
                v = np.sqrt(np.maximum(gaussian_filter(g * g, s) - m * m, 0.0))
                top = float(np.percentile(v[inside > 0.5], 90)) if (inside > 0.5).any() else 1.0
                inside = inside * (a + (1.0 - a) * np.clip(v / max(top, 1e-6), 0.0, 1.0))
            out = 1.0 + strength * inside
        return (out if times is None else out * times).astype(np.float32)

    return weights


@contextlib.contextmanager
def shape(kind, strength, a, b):
    """Plan with another face weight map (:data:`SHAPES`)."""
    import numpy as np

    from stringbot.planner import build
    from stringbot.planner.methods import canvas

    old, grid = build.face_weights, canvas.Canvas._eye_grid
    if kind == "flat stop":
        canvas.Canvas._eye_grid = lambda self, t, w: grid(self, t, (np.asarray(w) > 0).astype(np.float64))
    else:
        build.face_weights = shape_weights(kind, strength, a, b)
    try:
        yield
    finally:
        build.face_weights, canvas.Canvas._eye_grid = old, grid


def measure(plan, image, box):
    """The plan's face and frame SSIM (``face_scores``) against the picture's luminance at 512 px."""
    from stringbot.planner.model.scoring import WOVEN_SIZE, face_scores
    from stringbot.planner.picture.read import read_picture

    pic = read_picture(image, size=WOVEN_SIZE, crop=plan.crop, gray="luminance")
    return face_scores(plan, pic.gray, box=box)


def tiles(plan, image, size=SHEET_TILE):
    """``[the picture's luminance with the plan's crop, the plan as woven]``, uint8 gray tiles."""
    import numpy as np

    from stringbot.planner.model.render import draw_woven
    from stringbot.planner.picture.read import read_picture

    pic = read_picture(image, size=size, crop=plan.crop, gray="luminance").gray
    return [np.clip(pic, 0, 255).astype(np.uint8), draw_woven(plan, size=size)]


def sheet(rows, path):
    """Write the contact sheet: a row a portrait, each plan beside the picture's luminance with its crop:
    luminance | --face off | luminance | --face on."""
    import numpy as np
    from PIL import Image

    grid = np.vstack([np.hstack([t for pair in r["tiles"] for t in pair]) for r in rows])
    Image.fromarray(grid).save(path, optimize=True)


def run(image, *, variants=False, shapes=False, start_pin=None):
    """Plan ``image`` without and with ``--face`` (and the variants, the other weight maps; from ``start_pin``,
    None: the planner's own); their figures."""
    from stringbot.planner.build import plan_picture
    from stringbot.planner.picture.face import crop_on_face, face_for_plan
    from stringbot.planner.picture.read import default_crop, fit_crop

    found = face_for_plan(image, face="on")
    crop = crop_on_face(image, found)
    whole = fit_crop(image, "square")
    plans = {"off": dict(face="off"), "on": dict(face="on")}
    if variants:
        plans["weights only"] = dict(face="on", crop=default_crop(2 * whole["cx"], 2 * whole["cy"]))
        plans["crop only"] = dict(face="off", crop=crop)
        plans["features"] = dict(face="on")
    if shapes:
        plans.update({name: dict(face="on", shape=spec) for name, *spec in SHAPES})
    out = {"image": Path(image).name, "box": [round(v, 1) for v in found.to_record()["box"]], "plans": {},
           "tiles": []}
    for name, kw in plans.items():
        t = time.perf_counter()
        spec = kw.pop("shape", None)
        with features(*(FEATURES if name == "features" else (None, None, None))), \
                (shape(*spec) if spec else contextlib.nullcontext()):
            p = plan_picture(image, start_pin=start_pin, **kw)
        s = measure(p, image, found.to_record()["box"])
        if name in ("off", "on"):
            out["tiles"].append(tiles(p, image))
        out["plans"][name] = {"lines": p.stats["lines"], "seconds": round(time.perf_counter() - t, 2),
                              "crop": {k: round(v, 1) for k, v in p.crop.items()},
                              **{k: round(s[k], 4) for k in KEYS}}
    return out


def run_colour(image, spec, *, start_pin=None):
    """Colour plans of ``image`` without and with ``--face`` (from ``start_pin``, None: the planner's own): their
    figures (as ``stringbot score``)."""
    from stringbot.planner.colour.build import plan_colour
    from stringbot.planner.colour.palette import parse_colors
    from stringbot.planner.colour.render import SCORE_SIZE, colour_score, plan_layers
    from stringbot.planner.picture.face import face_for_plan
    from stringbot.planner.picture.read import read_picture

    box = face_for_plan(image, face="on").to_record()["box"]
    out = {"image": Path(image).name, "box": [round(v, 1) for v in box], "plans": {}, "tiles": []}
    for name in ("off", "on"):
        t = time.perf_counter()
        p = plan_colour(image, colors=parse_colors(spec), face=name, start_pin=start_pin)
        pic = read_picture(image, size=SCORE_SIZE, crop=p.crop, gray="luminance")
        r = colour_score(plan_layers(p), p.pin_xy, pic.rgb, frame=p.frame, background=p.background,
                         thread_fraction=p.thread_model().fraction, face=box, crop=p.crop)
        f = r["face"]
        out["plans"][name] = {"lines": p.stats["lines"], "seconds": round(time.perf_counter() - t, 2),
                              "crop": {k: round(v, 1) for k, v in p.crop.items()},
                              "delta_e_face": round(f["delta_e_face"], 2), "delta_e": round(r["delta_e"], 2),
                              **{k: round(f[k], 4) for k in KEYS}}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("images", nargs="*", type=Path, default=PORTRAITS)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--variants", action="store_true", help="also the face's crop alone and its weights alone")
    ap.add_argument("--shapes", action="store_true", help="also the other face weight maps (SHAPES)")
    ap.add_argument("--start-pin", type=int, help="every plan from this pin (as plan --start-pin)")
    ap.add_argument("--starts", help="comma-separated start pins ('own': the planner's own), e.g. own,37,151: "
                    "each plan from each, and the differences --face on minus off averaged over them (not with "
                    "--colors, --sheet)")
    ap.add_argument("--colors", help="colour plans with these threads (as plan --colors, e.g. auto:3)")
    ap.add_argument("--sheet", type=Path, help="write a contact sheet: luminance | --face off | luminance | --face on")
    a = ap.parse_args(argv)
    if a.starts:
        starts = [None if x.strip() == "own" else int(x) for x in a.starts.split(",")]
        runs = {st: [run(im, variants=a.variants, shapes=a.shapes, start_pin=st) for im in a.images] for st in starts}
        for rows in runs.values():
            for r in rows:
                del r["tiles"]
        if a.json:
            print(json.dumps({str(k): v for k, v in runs.items()}, indent=1))
            return
        mean_table(runs)
        return
    rows = [run_colour(im, a.colors, start_pin=a.start_pin) if a.colors else
            run(im, variants=a.variants, shapes=a.shapes, start_pin=a.start_pin)
            for im in a.images]
    if a.sheet:
        sheet(rows, a.sheet)
    for r in rows:
        del r["tiles"]
    if a.json:
        print(json.dumps(rows, indent=1))
        return
    table(rows)


def mean_table(runs):
    """Print, for each start pin of :func:`main`'s ``--starts``, the blurred differences --face on minus off
    (face box / frame), then their mean over the starts, and the plans' mean lines and seconds."""
    starts = list(runs)
    first = runs[starts[0]]
    plans = [n for n in first[0]["plans"] if n != "off"]
    print("| picture | plan | " + " | ".join(f"start {'own' if s is None else s}: face / frame" for s in starts)
          + " | mean: face / frame | lines | seconds |")
    print("|---|---|" + "---|" * (len(starts) + 3))
    for i, r in enumerate(first):
        for name in plans:
            d = [(runs[s][i]["plans"][name]["ssim_face_blurred"] - runs[s][i]["plans"]["off"]["ssim_face_blurred"],
                  runs[s][i]["plans"][name]["ssim_frame_blurred"] - runs[s][i]["plans"]["off"]["ssim_frame_blurred"])
                 for s in starts]
            lines = sum(runs[s][i]["plans"][name]["lines"] for s in starts) / len(starts)
            secs = sum(runs[s][i]["plans"][name]["seconds"] for s in starts) / len(starts)
            mf, mr = sum(x[0] for x in d) / len(d), sum(x[1] for x in d) / len(d)
            print(f"| {r['image']} | {name} | " + " | ".join(f"{f:+.3f} / {g:+.3f}" for f, g in d)
                  + f" | **{mf:+.3f} / {mr:+.3f}** | {lines:.0f} | {secs:.1f} |")


def table(rows):
    """Print the figures of :func:`run` as a Markdown table and the differences --face on minus off."""
    print("| picture | plan | lines | SSIM face / frame | blurred: face / frame | crop (cx, cy, r) |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        for name, p in r["plans"].items():
            c = p["crop"]
            print(f"| {r['image']} | {name} | {p['lines']} | {p['ssim_face']:.3f} / {p['ssim_frame']:.3f} | "
                  f"{p['ssim_face_blurred']:.3f} / {p['ssim_frame_blurred']:.3f} | "
                  f"{c['cx']:g}, {c['cy']:g}, {c['r']:g} |")
    if "delta_e_face" in rows[0]["plans"]["off"]:
        for r in rows:
            print(f"{r['image']}: CIEDE2000 face / frame: off {r['plans']['off']['delta_e_face']:.2f} / "
                  f"{r['plans']['off']['delta_e']:.2f}, on {r['plans']['on']['delta_e_face']:.2f} / "
                  f"{r['plans']['on']['delta_e']:.2f}")
    for key in ("ssim_face", "ssim_frame", "ssim_face_blurred", "ssim_frame_blurred"):
        d = [r["plans"]["on"][key] - r["plans"]["off"][key] for r in rows]
        print(f"{key}: --face on minus off: " + ", ".join(f"{x:+.3f}" for x in d) + f" (mean {sum(d) / len(d):+.3f})")


if __name__ == "__main__":
    main()
