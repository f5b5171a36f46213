"""Does the planner's thread model predict the piece as it will hang?  Model against reference rendering.

For every plan (stringbot's default plan of each test picture, as
``stringbot plan IMG --machine grbl-ring`` makes it, and the peers' mono
plans in ``../shared/reference/peers``: ThreadTone, giunta, Prem-Dharshan),
the chords are drawn

* by the reference rendering (:mod:`stringbot.planner.model.reference`, converged)
  at 512 px: the truth;
* by each of the planner's models, as the planner would hold that plan:
  the chooser's canvas at the working size (401 px, :class:`Canvas
  <stringbot.planner.methods.canvas.Canvas>`), its coarse grid of the error as the
  eye sees it (``--lines auto`` stops by it), and the polish's canvas
  (:class:`WovenCanvas <stringbot.planner.methods.woven.WovenCanvas>`, 256 px, its
  fine canvas 2048 samples a side).

Printed per plan and model: ``mean`` the model's mean gray minus the
reference's (over the frame, 0..1; positive: the model believes the piece
lighter), ``rms`` the root-mean-square difference of the two drawings, both
at 512 px (a model's grid resized, bilinear) and blurred by sigma 2 px
(the as-woven error's blur), and ``err`` the model's own as-woven error of
the plan against the picture's luminance minus the reference's (``stringbot
score``'s ``woven``).  The targets: |mean| <= 0.01, rms <= 0.01, |err| <=
0.01.  For a model held on a grid coarser than 512 px (the eye's 128 px,
the polish's 256 px) ``grid`` is the same rms at that grid's own size: the
reference rendering box-filtered to it, both blurred by the same 2 px of
512 (what the model can hold, against what it holds).

Usage: python benchmarks/bench_model_agreement.py [--images DIR] [--peers DIR] [--only NAMES]
           [--plans DIR (our plans as NAME.json, made if missing)] [--json]
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = next((d / "shared" for d in ROOT.parents if (d / "shared" / "images").is_dir()), ROOT.parent / "shared")
PEERS = ("threadtone", "giunta", "premdharshan")
WORKING = 401


def _resized(img, size=512):
    from stringbot.planner.picture.resample import resize_square

    img = np.asarray(img, dtype=np.float64)
    return img if img.shape[0] == size else resize_square(img, size, anti_aliasing=img.shape[0] > size)


def compare(model_gray, ref_gray, target, mask):
    """``(mean, rms, err)`` of a model's drawing against the reference's (see the module notes)."""
    from scipy.ndimage import gaussian_filter

    a = gaussian_filter(_resized(model_gray), 2.0)
    b = gaussian_filter(ref_gray, 2.0)
    t = gaussian_filter(target, 2.0)
    mean = float(_resized(model_gray)[mask].mean() - ref_gray[mask].mean())
    rms = float(np.sqrt(np.mean((a - b)[mask] ** 2)))
    err = float(np.sqrt(np.mean((a - t)[mask] ** 2)) - np.sqrt(np.mean((b - t)[mask] ** 2)))
    return mean, rms, err


def grid_rms(model_gray, plan):
    """The rms of a model's drawing on its own grid against the reference rendering at that size, both
    blurred by sigma 2 px of 512 (None for a grid of 512 px or more)."""
    from scipy.ndimage import gaussian_filter

    from stringbot.planner.model.chords import frame_mask
    from stringbot.planner.model.reference import reference_gray
    from stringbot.planner.model.scoring import WOVEN_SIGMA, WOVEN_SIZE

    m = model_gray.shape[0]
    if m >= WOVEN_SIZE:
        return None
    ref = reference_gray(plan.chord_list(), plan.pin_xy, size=m, thread_fraction=plan.thread_model().fraction)
    sg = WOVEN_SIGMA * m / WOVEN_SIZE
    d = gaussian_filter(np.asarray(model_gray, dtype=np.float64), sg) - gaussian_filter(ref.astype(np.float64), sg)
    return float(np.sqrt(np.mean(d[frame_mask(m, plan.frame)] ** 2)))


def models(plan, image):
    """Each model's drawing of the plan (gray, 1 white) and its own as-woven error figure (or None)."""
    from stringbot.planner.methods.canvas import Canvas
    from stringbot.planner.methods.residual import woven_canvas
    from stringbot.planner.model.chords import chord_space, frame_mask
    from stringbot.planner.model.scoring import LUMINANCE
    from stringbot.planner.picture.read import read_picture

    chords = plan.chord_list()
    model = plan.thread_model()
    pic = read_picture(image, size=WORKING, crop=plan.crop, gray="luminance", weights=LUMINANCE)
    mask = frame_mask(WORKING, plan.frame)
    target = np.where(mask, 1.0 - pic.gray / 255.0, 0.0)
    w = mask.astype(np.float64)
    chooser = Canvas(target, w, plan.pin_xy, model.width_px(WORKING), eye=True)
    chooser.apply(chords_in=chords)
    out = {"chooser": (1.0 - chooser.D.reshape(WORKING, WORKING), None)}
    eye = chooser.eye
    me = eye.size
    area = float(np.sum(eye.s ** 2))
    out["eye"] = (1.0 - eye.D.reshape(me, me), float(np.sqrt(eye.error() / area)))
    space = chord_space(plan.pins, plan.frame)
    space.pin_xy = plan.pin_xy  # a peer's pins where it put them
    woven = woven_canvas(target, w, space, model)
    woven.build(chords)
    m = woven.size
    out["polish"] = (1.0 - woven.D.reshape(m, m), float(np.sqrt(woven.error() / float(np.sum(woven.s ** 2)))))
    # the polish's fine canvas box-filtered to 512 px: the model's own drawing at the scorer's size
    k = woven.F // 512
    if k >= 1 and woven.F % 512 == 0:
        fine = (woven.fine_counts() > 0).reshape(512, k, woven.F).sum(axis=1).reshape(512, 512, k).sum(axis=2) / (k * k)
        out["polish fine"] = (1.0 - fine, None)
    return out


def our_plans(names, images, folder):
    """stringbot's default plan of each picture, read from ``folder`` or made (and saved there)."""
    from stringbot.planner import read_plan, write_plan
    from stringbot.planner.build import plan_picture

    plans = {}
    for name in names:
        path = None if folder is None else Path(folder) / f"{name}.json"
        if path is not None and path.is_file():
            plans[name] = read_plan(path)
            continue
        p = plan_picture(images / f"{name}.png", pins=300, diameter_mm=500.0, thread_mm=0.25)
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_plan(p, path)
        plans[name] = p
    return plans


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", default=str(SHARED / "images"))
    ap.add_argument("--peers", default=str(SHARED / "reference" / "peers"))
    ap.add_argument("--only", default=None, help="comma-separated picture names (default: all)")
    ap.add_argument("--plans", default=None, help="folder of our plans (NAME.json), made and saved where missing")
    ap.add_argument("--json", action="store_true")
    opts = ap.parse_args()

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from quality_table import peer_plan

    from stringbot.planner.model.chords import frame_mask
    from stringbot.planner.model.reference import reference_gray
    from stringbot.planner.model.scoring import LUMINANCE, WOVEN_SIZE
    from stringbot.planner.picture.read import read_picture

    images = Path(opts.images)
    names = sorted(p.stem for p in images.iterdir() if p.suffix.lower() == ".png")
    if opts.only:
        names = [n for n in names if n in set(opts.only.split(","))]
    ours = our_plans(names, images, opts.plans)
    rows, worst = [], {}
    mask = frame_mask(WOVEN_SIZE, "circle")
    for name in names:
        plans = {"stringbot": ours[name]}
        plans.update({peer: peer_plan(Path(opts.peers) / f"{peer}_{name}.json") for peer in PEERS})
        for who, plan in plans.items():
            t = time.perf_counter()
            ref = reference_gray(plan.chord_list(), plan.pin_xy, size=WOVEN_SIZE,
                                 thread_fraction=plan.thread_model().fraction).astype(np.float64)
            t_ref = time.perf_counter() - t
            g = read_picture(images / f"{name}.png", size=WOVEN_SIZE, crop=plan.crop, gray="luminance",
                             weights=LUMINANCE).gray / 255.0
            target = np.where(mask, g, 1.0)
            row = {"image": name, "plan": who, "lines": len(plan.chord_list()), "reference_seconds": round(t_ref, 2)}
            for kind, (drawing, own) in models(plan, images / f"{name}.png").items():
                mean, rms, err = compare(drawing, ref, target, mask)
                row[kind] = {"mean": round(mean, 4), "rms": round(rms, 4), "err": round(err, 4)}
                grid = grid_rms(drawing, plan)
                if grid is not None:
                    row[kind]["grid"] = round(grid, 4)
                    wg = worst.setdefault(kind + " grid", {"rms": 0.0})
                    wg["rms"] = max(wg["rms"], grid)
                if own is not None:  # the model's own figure (its grid, its blur) against the reference's
                    from stringbot.planner.model.scoring import blurred_rms

                    row[kind]["own_err"] = round(own - blurred_rms(ref, target, frame="circle"), 4)
                w = worst.setdefault(kind, {"mean": 0.0, "rms": 0.0, "err": 0.0})
                for key in ("mean", "err"):
                    w[key] = max(w[key], abs(row[kind][key]))
                w["rms"] = max(w["rms"], row[kind]["rms"])
            rows.append(row)
            if not opts.json:
                print(f"{name:<10} {who:<13} {row['lines']:5d} lines  " + "  ".join(
                    f"{k}: {v['mean']:+.4f} / {v['rms']:.4f} / {v['err']:+.4f}"
                    + (f" (grid {v['grid']:.4f})" if "grid" in v else "")
                    + (f" (own {v['own_err']:+.4f})" if "own_err" in v else "")
                    for k, v in row.items() if isinstance(v, dict)), flush=True)
    if opts.json:
        print(json.dumps({"rows": rows, "worst": worst}, indent=1))
    else:
        print("worst |mean| / rms / |err| per model: " + "; ".join(
            f"{k} {v['mean']:.4f} / {v['rms']:.4f} / {v['err']:.4f}" if "mean" in v else f"{k} rms {v['rms']:.4f}"
            for k, v in worst.items()))


if __name__ == "__main__":
    main()
