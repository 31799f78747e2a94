"""Benchmark: the heat-map CNN on real drone photos of wind turbines, labelled with boxes.

The photos are not part of turbinefit (their original source's licence may not allow
redistribution: measure on them, never commit them or train a shipped model on them).
Get them from the MIT-licensed repository ``ertis-research/shm-wind-turbines``::

    git clone --depth 1 https://github.com/ertis-research/shm-wind-turbines
    python benchmarks/bench_real.py "shm-wind-turbines/datasets/Wind turbines and blades"

That folder holds ``images/turbine/`` (whole turbines) and ``images/blade/`` (blade
close-ups), 1024 x 1024 drone photos (half of them augmented copies, ``transformed*``,
left out here), and one box per photo in ``annotations/turbine.csv`` and
``annotations/blade.csv`` (``filename,width,height,class,xmin,ymin,xmax,ymax``).

**Held out.** The set may be trained on (``turbinefit train --boxes``), except for a
held-out part fixed before any training by :func:`turbinefit.eval.holdout.is_held_out`: a
photo is held out when the SHA-256 of its original's name (``transformedDJI_0049.jpg``
counts as ``DJI_0049.jpg``, so an augmented copy is always on its original's side) is
below 0.4 as a number in [0, 1): 110 of the 253 whole-turbine originals and 93 of the 282
blade originals. The figures are of the held-out part only (``--split held-out``, the
default; the script stops if it is under 30 % of a class); ``--split all`` measures every
original, as the figures before training on the set were (their first 80 of each class).

For the first ``--n`` original photos of each class of the split (all with ``--n 0``, the
default) it runs
``turbinefit evaluate --boxes`` (:func:`turbinefit.jobs.evaluate.evaluate_regions`, boxes
grown by 5 % of their size a side) and prints, per class: the share of the line
heat-maps' mass inside the grown box, the share of photos where a turbine is found, and
the point peaks outside the box; then the bottom-rows artefact: the mean of the line
channels' maximum over the maps' bottom rows (40 rows of the 1024-px photo) against that
over the whole map. Results: ``benchmarks/results/bench_real.json`` for the shipped net
(``bench_real_<stem>.json`` with ``--model <stem>.onnx``, ``bench_real_x<S>.json`` with
``--input-scale S``, or ``--out``); the contact sheet of
the worst photos goes to ``benchmarks/data/real_worst.png`` (it shows the photos: not
committed).

The data set's blade boxes hold one blade each, but half of its "blade" photos also show
the tower (looking down it), the other blades or a second turbine, which no box covers:
line mass the net puts on them counts as outside. ``--views`` (default
``benchmarks/real_blade_views.csv``, ``filename,view``) says for each of the first 80
blade photos what it shows, from looking at each photo: ``blade`` (the boxed blade, at
most the nacelle or hub at the frame's edge) or ``tower-too`` (the tower or another
turbine in view as well). The figures are then also given per view, with the share of the
line mass in the tower channel.

What the boxes cannot give, a figure of the line mass on the turbine wherever it is in
view, ``--parts`` (default ``benchmarks/real_blade_parts.csv``, ``filename,part,polygon``)
adds for the ``tower-too`` photos: an outline of each turbine part in view that the box
leaves out (``tower``, ``nacelle``, ``blade``, ``other-turbine``), a polygon ``x y x y ...``
in photo px (pixel edges) drawn by hand from looking at each photo on a 64-px grid (to
about 10-20 px). The line mass inside the grown box or any part (each part grown by 2 map
px, as the renders' true lines below) is then given per view, and over the photos of
``--views``, with the point peaks outside the box and parts.

**Real negatives.** ``--negatives DIR`` (repeatable) runs the net on the turbine-free
photos of DIR (not its subfolders; the same held-out rule picks the photos measured, so that
photos a net was trained on as negatives, ``turbinefit train --negatives``, are not
scored) and gives per folder: the share of photos whose maps a fit could take for a
turbine (:func:`turbinefit.eval.regions.could_be_evidence` at the fit's default
correspondence threshold, 0.3: an upper bound of the evidence share the verdict of a
flight of such photos would see; below 0.2 it is ``failed``, below 0.5 ``doubtful``),
the mean of the line channels' per-pixel maximum, the photos with any channel above the
model's threshold and the point peaks per photo; and a flight of them: up to 40 of the
photos, in name order, as the photos of a simulated 40-keyframe flight (seed 3, its
turbine.yaml and GPS/IMU poses), fitted from the images as ``turbinefit fit
--from-images`` does: its verdict and the share of keyframes with evidence (a turbine-free
flight must not be ``ok``). ``--untrained DIR`` measures a folder no net is trained on
(thermal photos) the same way, every photo of it.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from common import DATA, HERE, RESULTS, write_json

from turbinefit.detect import DetectOptions, DetectorPool, HeatmapDetector
from turbinefit.eval.holdout import is_held_out, original_name
from turbinefit.eval.regions import (
    LINE_CHANNELS,
    bottom_rows,
    box_region,
    could_be_evidence,
    grow_box,
    line_mass_inside,
    point_peaks,
    polygon_region,
)
from turbinefit.heatmaps.channels import CHANNEL_NAMES
from turbinefit.io.images import read_image
from turbinefit.jobs.evaluate import evaluate_regions
from turbinefit.solver.config import FitConfig

CLASSES = ("turbine", "blade")
#: What each blade photo shows (see the module docstring).
VIEWS = HERE / "real_blade_views.csv"
#: The turbine parts the blade photos' boxes leave out (see the module docstring).
PARTS = HERE / "real_blade_parts.csv"
#: Parts are grown by this many map px before scoring.
PART_GROW_PX = 2
TOWER_LINE = CHANNEL_NAMES.index("line_tower")
#: Photo rows [px of the photo] of the bottom-rows artefact.
BOTTOM_PX = 40
#: The held-out part must hold at least this share of each class.
MIN_HELD_OUT = 0.3
#: The fit's default correspondence threshold.
CORR_THRESHOLD = FitConfig().corr_threshold


def renders_of_each_shape(n: int, model: Path | None) -> None:
    """Held-out renders (seed 777) of each shape: line mass inside the true lines (targets
    above 0.05 grown by 2 map px), line IoU at the photo's size, and the bottom 4 % of the
    map's line mean against the whole map's."""
    from scipy import ndimage

    from turbinefit.detect import HeatmapDetector
    from turbinefit.eval.regions import line_mass_inside
    from turbinefit.sim.dataset import DatasetSpec, render_sample

    det = HeatmapDetector(model)
    for w, h in [(160, 120), (160, 160), (160, 106), (160, 90), (120, 160)]:
        spec = DatasetSpec(n, seed=777, width=w, height=h)
        inside, bottom, whole, inter, union = [], [], [], 0, 0
        for k in range(n):
            s = render_sample(spec, k)
            m = det.detect(s.image, (w, h))
            region = ndimage.binary_dilation(s.target[4:].max(axis=0) > 0.05, iterations=2)
            inside.append(line_mass_inside(m, region))
            b, a = bottom_rows(m, max(1, round(h / 25)))
            bottom.append(b)
            whole.append(a)
            p, g = m[4:] > 0.5, s.target[4:] > 0.5
            inter, union = inter + int((p & g).sum()), union + int((p | g).sum())
        print(f"renders {w}x{h}: line mass inside {np.nanmean(inside):.3f}, line IoU "
              f"{inter / union:.3f}, bottom rows {np.mean(bottom):.3f}, whole map "
              f"{np.mean(whole):.3f}")


def default_name(model: Path | None, input_scale: float) -> str:
    """The results file of a run of ``model`` (None: the shipped net) at ``input_scale``:
    the shipped net's figures are never overwritten by another net's."""
    name = "bench_real" if model is None else f"bench_real_{model.stem}"
    return name + (f"_x{input_scale:g}" if input_scale != 1.0 else "") + ".json"


def read_parts(path: Path) -> dict[str, list[list[float]]]:
    """``filename`` -> polygons (x y x y ... [photo px]) of ``path`` (``--parts``)."""
    parts: dict[str, list[list[float]]] = {}
    with open(path, newline="") as f:
        for line, r in enumerate(csv.DictReader(f), start=2):
            xy = [float(v) for v in r["polygon"].split()]
            if len(xy) < 6 or len(xy) % 2:
                sys.exit(f"{path}:{line}: polygon needs three or more x y pairs")
            parts.setdefault(r["filename"], []).append(xy)
    return parts


def on_turbine(maps: np.ndarray, row: list[str], photo_size: tuple[int, int],
               polygons: list[list[float]], grow: float, thresholds: tuple[float, float]
               ) -> tuple[float, int]:
    """(share of ``maps``' line mass, point peaks above ``thresholds`` (points, tips)
    outside) ``row``'s box (grown by ``grow``, as the ``evaluate`` run grew it) or any of
    ``polygons`` (as ``evaluate`` reads outlines, grown by :data:`PART_GROW_PX` map px)."""
    from scipy import ndimage

    (pw, ph), (h, w) = photo_size, maps.shape[1:]
    box = grow_box(tuple(float(v) for v in row[4:8]), grow, pw, ph)  # type: ignore[arg-type]
    region = box_region([box], photo_size, (w, h))
    if polygons:
        parts = polygon_region([tuple(xy) for xy in polygons], photo_size, (w, h))
        region |= ndimage.binary_dilation(parts, iterations=PART_GROW_PX)
    pk = point_peaks(maps, *thresholds).astype(int)
    return line_mass_inside(maps, region), int((~region[pk[:, 1], pk[:, 0]]).sum())


def negatives(pool: DetectorPool, folder: Path, split: str, model: Path | None
              ) -> dict[str, Any]:
    """Figures of the turbine-free photos of ``folder`` (its ``split`` part), printed."""
    from turbinefit.io.images import list_images

    photos = [p for p in list_images([folder]) if split == "all" or is_held_out(p.name)]
    if not photos:
        sys.exit(f"{folder}: no photos in the {split} part")
    info = pool.detector.info

    def run(det: HeatmapDetector, path: Path) -> tuple[bool, float, bool, int]:
        hm = det.detect_small(read_image(path, reduce_to=(640, 640)))
        return (could_be_evidence(hm, CORR_THRESHOLD),
                float(hm[list(LINE_CHANNELS)].max(axis=0).mean()),
                bool(hm.max() > info.threshold),
                len(point_peaks(hm, info.threshold, info.tip_threshold)))

    ev, line, found, peaks = zip(*pool.map(run, photos), strict=True)
    out = {"photos": len(photos), "could_be_evidence": float(np.mean(ev)),
           "line_mean": float(np.mean(line)), "found": float(np.mean(found)),
           "peaks_per_photo": float(np.mean(peaks))}
    out.update(negative_flight(photos[:40], model))
    share = out["flight_evidence_share"]
    print(f"negatives {folder} ({split}, {len(photos)} photos): could be evidence "
          f"{out['could_be_evidence']:.3f}, line mean {out['line_mean']:.4f}, found "
          f"{out['found']:.3f}, point peaks per photo {out['peaks_per_photo']:.2f}; a flight "
          f"of {out['flight_photos']}: {out['flight_verdict']}, evidence on "
          f"{'?' if share is None else f'{share:.0%}'} of keyframes")
    return out


def negative_flight(photos: list[Path], model: Path | None) -> dict[str, Any]:
    """The verdict of ``fit --from-images`` on a simulated flight whose photos are
    ``photos`` (resized to its camera): a turbine-free flight (module docstring)."""
    from PIL import Image

    from turbinefit.cli import main as turbinefit
    from turbinefit.io.images import list_images
    from turbinefit.jobs.fit import fit_folder

    with tempfile.TemporaryDirectory() as tmp:
        flight = Path(tmp) / "flight"
        if turbinefit(["simulate", str(flight), "--keyframes", str(len(photos)), "--seed",
                       "3", "--images", "--quiet"]) != 0:
            sys.exit("simulate failed")
        shutil.rmtree(flight / "heatmaps", ignore_errors=True)
        frames = sorted(list_images([flight / "images"]),
                        key=lambda p: float(p.stem))
        size = Image.open(frames[0]).size
        for src, dst in zip(photos, frames, strict=True):
            Image.open(src).convert("RGB").resize(size).save(dst)
        rep = fit_folder(flight, Path(tmp) / "fit", from_images=True, model=model,
                         plots=False)
    sig = rep.result.signals
    return {"flight_photos": len(photos), "flight_verdict": rep.result.verdict,
            "flight_evidence_share": None if sig is None else float(sig.evidence_share),
            "flight_reasons": list(rep.result.reasons)}


def per_view(views_csv: Path, rows: list[list[str]], inside: dict[str, float],
             tower_share: dict[str, float], turbine: dict[str, float],
             outside: dict[str, int]) -> dict[str, dict[str, float]]:
    """The blade photos' line mass inside the box, on the turbine (box or parts) and share
    in the tower channel, per view of ``views_csv`` and over all the photos it lists
    (photos it does not list are left out); printed."""
    with open(views_csv, newline="") as f:
        views = {r["filename"]: r["view"] for r in csv.DictReader(f)}
    out: dict[str, dict[str, float]] = {}
    for view in [*sorted(set(views.values())), "all listed"]:
        names = [r[0] for r in rows if r[3] == "blade"
                 and (views.get(r[0]) == view or (view == "all listed" and r[0] in views))]
        if not names:
            continue
        out[view] = {"photos": len(names),
                     "line_mass_inside": float(np.mean([inside[n] for n in names])),
                     "line_mass_on_turbine": float(np.mean([turbine[n] for n in names])),
                     "tower_channel_share": float(np.mean([tower_share[n] for n in names])),
                     "peaks_outside_turbine": int(sum(outside[n] for n in names))}
        print(f"blade photos showing {view:10s} {len(names):3d}: line mass inside the box "
              f"{out[view]['line_mass_inside']:.3f}, on the turbine (box or parts) "
              f"{out[view]['line_mass_on_turbine']:.3f}, in the tower channel "
              f"{out[view]['tower_channel_share']:.3f}, point peaks outside the turbine "
              f"{out[view]['peaks_outside_turbine']}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("photos_dir", type=Path,
                    help="the data set's 'Wind turbines and blades' folder (see below)")
    ap.add_argument("--n", type=int, default=0,
                    help="photos per class (0 = all originals of the split)")
    ap.add_argument("--split", choices=("held-out", "all"), default="held-out",
                    help="the held-out part (turbinefit.eval.holdout) or every original")
    ap.add_argument("--negatives", type=Path, action="append", default=[], metavar="DIR",
                    help="a folder of turbine-free photos (its held-out part is measured); "
                         "repeat for several")
    ap.add_argument("--untrained", type=Path, action="append", default=[], metavar="DIR",
                    help="a folder of photos no net is trained on (thermal photos, ...), "
                         "measured as --negatives, in full; repeat for several")
    ap.add_argument("--model", type=Path, default=None)
    ap.add_argument("--input-scale", type=float, default=1.0,
                    help="run the net at this multiple of its input size (test-time zoom off "
                         "unless 1)")
    ap.add_argument("--out", type=Path, default=None,
                    help="results JSON (default: benchmarks/results/bench_real.json for the "
                         "shipped net at its own size, bench_real_<stem>.json with --model, "
                         "bench_real_x<S>.json with --input-scale S)")
    ap.add_argument("--renders", type=int, default=0,
                    help="also N held-out renders of each shape (square, 3:2, 16:9, 3:4)")
    ap.add_argument("--views", type=Path, default=VIEWS,
                    help="CSV filename,view: what each blade photo shows (figures per view)")
    ap.add_argument("--parts", type=Path, default=PARTS,
                    help="CSV filename,part,polygon: the turbine parts in view that the "
                         "blade photos' boxes leave out (line mass on the turbine)")
    args = ap.parse_args()
    if args.renders > 0:
        renders_of_each_shape(args.renders, args.model)
    root = args.photos_dir
    if not (root / "annotations").is_dir():
        sys.exit(f"{root}: no annotations/ folder; see --help for how to get the photos")
    DATA.mkdir(exist_ok=True)
    RESULTS.mkdir(exist_ok=True)
    rows: list[list[str]] = []
    held_share: dict[str, float] = {}
    for cls in CLASSES:
        with open(root / "annotations" / f"{cls}.csv", newline="") as f:
            every = [r for r in csv.reader(f) if r and original_name(r[0]) == r[0]]
        held = [r for r in every if is_held_out(r[0])]
        held_share[cls] = len(held) / max(len(every), 1)
        if held_share[cls] < MIN_HELD_OUT:
            sys.exit(f"{root}: only {len(held)} of the {len(every)} {cls} originals are held "
                     f"out, under {MIN_HELD_OUT:.0%}")
        mine = held if args.split == "held-out" else every
        print(f"{cls}: {len(held)} of {len(every)} originals held out "
              f"({held_share[cls]:.1%}); measuring {args.split}")
        rows += mine[:args.n] if args.n > 0 else mine
    with tempfile.TemporaryDirectory() as tmp:
        boxes = Path(tmp) / "boxes.csv"
        boxes.write_text("".join(",".join(r) + "\n" for r in rows))
        scaled = args.input_scale != 1.0
        options = DetectOptions(zoom=False, input_scale=args.input_scale) if scaled else None
        rep = evaluate_regions(root / "images", boxes=boxes, model=args.model,
                               out=Path(tmp) / "report.json",
                               sheet=DATA / "real_worst.png", overwrite=True, progress=True,
                               detect_options=options)
        inside = {Path(p["photo"]).name: p["line_mass_inside"]
                  for p in json.loads((Path(tmp) / "report.json").read_text())["photos"]}
    model = Path(rep.model)
    result: dict[str, object] = {"photos_dir": root.name, "n_per_class": args.n,
                                 "split": args.split, "held_out_share": held_share,
                                 "input_scale": args.input_scale,
                                 "model": model.name, "grow": rep.grow,
                                 "metrics": rep.summary}
    for name, m in rep.summary.items():
        print(f"{name:8s} {int(m['photos']):4d} photos: line mass inside the box grown by "
              f"5 % {m['line_mass_inside']:.3f}, turbine found {m['found']:.1%}, point peaks "
              f"outside {int(m['peaks_outside'])} of {int(m['peaks'])}")

    pool = DetectorPool(args.model, options=options)
    parts = read_parts(args.parts) if args.parts.is_file() else {}

    def maps(det: HeatmapDetector, row: list[str]) -> tuple[tuple[int, int], np.ndarray]:
        img = read_image(root / "images" / row[3] / row[0])
        return (img.shape[0], img.shape[1]), det.detect_small(img)

    artefact = {}
    tower_share: dict[str, float] = {}
    turbine: dict[str, float] = {}
    outside: dict[str, int] = {}
    thresholds = (pool.detector.info.threshold, pool.detector.info.tip_threshold)
    for cls in CLASSES:
        mine = [r for r in rows if r[3] == cls]
        found = list(pool.map(maps, mine))
        pairs = [bottom_rows(hm, round(BOTTOM_PX * hm.shape[1] / hw[0])) for hw, hm in found]
        bottom, whole = (float(np.mean(x)) for x in zip(*pairs, strict=True))
        artefact[cls] = {"bottom_rows": bottom, "whole_map": whole}
        print(f"{cls:8s} bottom {BOTTOM_PX} rows' line mean {bottom:.3f}, whole map {whole:.3f}")
        for r, ((ph, pw), hm) in zip(mine, found, strict=True):
            total = float(hm[TOWER_LINE:].sum())
            tower_share[r[0]] = float(hm[TOWER_LINE].sum()) / total if total > 0 else 0.0
            turbine[r[0]], outside[r[0]] = on_turbine(hm, r, (pw, ph), parts.get(r[0], []),
                                                      rep.grow, thresholds)
    result["bottom_rows"] = artefact
    if args.views.is_file():
        result["views"] = per_view(args.views, rows, inside, tower_share, turbine, outside)
    if args.negatives:
        result["negatives"] = {str(d): negatives(pool, d, args.split, args.model)
                              for d in args.negatives}
    if args.untrained:
        result["untrained"] = {str(d): negatives(pool, d, "all", args.model)
                              for d in args.untrained}
    out = args.out or RESULTS / default_name(args.model, args.input_scale)
    write_json(out, result)
    print(f"wrote {out}; worst photos: {DATA / 'real_worst.png'}")


if __name__ == "__main__":
    main()
