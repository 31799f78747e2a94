"""Precision at the photo's resolution (issue 31): fits from ideal heat-maps at 320 x 240,
1280 x 960 and 5280 x 3956, and the CNN's detection figures on photos of those sizes.

* **Fit from ideal maps**: per seed, one simulated flight (default preset; the same
  turbine, path, drift and faults at every size) whose ideal heat-maps are rendered at
  each size (blobs, ridges and false streaks scaled with the width: the same picture at a
  higher resolution) into a memory map under ``benchmarks/data/``, and fitted in this
  process with the options ``fit`` uses for heat-map files: with the pixel settings
  following the maps' scale (``pixel_scale`` unset: width / 320) and, above 320 px, with
  the 320 px values used as the maps' pixels (``pixel_scale=1``, as before the settings
  followed the scale). Mean position, orientation and model-point errors, iterations and
  solve time per size; 5280 x 3956 maps take 585 MB per keyframe, so they are fitted
  on ``--large-keyframes`` keyframes (the other sizes are fitted on the same short
  flight too, for the comparison).
* **Detection at the photo's resolution** (``--detect``): held-out views drawn as the
  CNN's held-out renders are (:func:`turbinefit.sim.dataset.sample_view`, a seed never
  used in training), each photo rendered at each size (directly at that size, as the
  training renders are), run through the shipped model (which reads every photo at its
  320 x 240 input: :meth:`HeatmapDetector.detect_small`); :class:`~turbinefit.eval.detection.DetectionStats`
  on its 160 x 120 grid against the targets and true points, with distances in pixels of
  the photo and in pixels at 320 px (``px_scale``): median point errors, tip recall and
  precision (matched within 5 px at 320 px, whatever the photo), line IoU.
* **Fits from photos** (``--photos N``): N flights (seeds 20, 21, ...) with 1280 x 960
  photos (``turbinefit simulate --images``, cached under ``benchmarks/data/``), each
  fitted as ``fit`` does with no options from its ideal 320 x 240 maps and from its
  photos with the net at each ``--input-scales`` (1: the shipped detector; 2: the net
  run at 640 x 480, :class:`~turbinefit.detect.DetectOptions` ``input_scale``), the
  ratio of each to the ideal fit, and the tracker's causal estimates from the photos
  against the initial poses.
* **Coarse to fine** (``--refine``): the detection figures above 320 px and the photo
  fits again with :class:`~turbinefit.detect.DetectOptions` ``refine`` (the net run again
  on tiles of each photo at up to 4x the first pass's resolution).

Usage::

    python benchmarks/bench_resolution.py [--seeds 0 ... 11] [--keyframes 200]
        [--sizes 320 1280] [--large-keyframes 20] [--large-seeds 0]
        [--detect 100] [--detect-large 10] [--photos 12 [--input-scales 1 2]] [--refine]

Prints the figures and writes ``benchmarks/results/bench_resolution.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import statistics
import subprocess
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import BIN, DATA, RESULTS, write_json

from turbinefit.detect import DetectOptions
from turbinefit.eval.metrics import accuracy
from turbinefit.io.flight_folder import read_flight_folder
from turbinefit.jobs.sources import FILE_FIT_DEFAULTS, FileHeatmaps, PhotoHeatmaps, fit_config_for
from turbinefit.sim.scenario import SimConfig, simulate_flight
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import fit

#: Photo / heat-map sizes (4:3), by width.
SIZES = {320: 240, 1280: 960, 5280: 3956}
LARGE = 5280
HELDOUT_SEED = 777_777
#: First seed of the flights with 1280 x 960 photos.
PHOTO_SEED = 20


def fit_flight(seed: int, n: int, width: int, scales: list[float | None]) -> list[dict[str, Any]]:
    """Fit the ideal maps (``width`` wide) of flight ``seed`` once per pixel scale."""
    height = SIZES[width]
    cfg = SimConfig(n_keyframes=n, seed=seed, width=width, height=height,
                    heatmap_size=(width, height))
    path = DATA / f"resolution_maps_{width}.npy"
    DATA.mkdir(exist_ok=True)
    maps = np.lib.format.open_memmap(path, mode="w+", dtype=np.float32,
                                     shape=(n, 7, height, width))
    rows = []
    try:
        t0 = time.perf_counter()
        flight = simulate_flight(cfg, out=maps)
        render_s = time.perf_counter() - t0
        assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
        before = accuracy(flight.world_T_cam, flight.turbine, flight.gt_world_T_cam,
                          flight.gt_turbine)
        for scale in scales:
            res = fit(flight, FitConfig(**FILE_FIT_DEFAULTS, pixel_scale=scale))
            acc = accuracy(res.world_T_cam, res.turbine, flight.gt_world_T_cam,
                           flight.gt_turbine)
            rows.append({"seed": seed, "keyframes": n, "width": width,
                         "pixel_scale": "auto" if scale is None else scale,
                         "resolved_scale": res.config.pixel_scale,
                         "position_m": acc.position_error_m,
                         "orientation_deg": acc.orientation_error_deg,
                         "model_point_m": acc.model_point_error_m,
                         "position_before_m": before.position_error_m,
                         "model_point_before_m": before.model_point_error_m,
                         "iterations": res.iterations, "rounds": res.rounds,
                         "solve_s": res.time_s, "render_s": render_s, "verdict": res.verdict})
            r = rows[-1]
            print(f"  seed {seed:2d} {width}x{height} n={n} pixel_scale {r['pixel_scale']}: "
                  f"position {r['position_before_m']:.3f} -> {r['position_m']:.3f} m, "
                  f"orientation {r['orientation_deg']:.3f} deg, model points "
                  f"{r['model_point_before_m']:.3f} -> {r['model_point_m']:.3f} m, "
                  f"{r['iterations']} it, {r['solve_s']:.1f} s", flush=True)
        del flight
    finally:
        del maps
        path.unlink(missing_ok=True)
    return rows


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Means per (keyframes, width, pixel_scale)."""
    keys = sorted({(r["keyframes"], r["width"], str(r["pixel_scale"])) for r in rows},
                  key=lambda k: (-k[0], k[1], k[2]))
    out = []
    for n, w, s in keys:
        sel = [r for r in rows if (r["keyframes"], r["width"], str(r["pixel_scale"])) == (n, w, s)]
        out.append({"keyframes": n, "width": w, "pixel_scale": s, "flights": len(sel),
                    **{k: statistics.fmean(r[k] for r in sel)
                       for k in ("position_m", "orientation_deg", "model_point_m",
                                 "position_before_m", "model_point_before_m", "iterations",
                                 "solve_s")},
                    "worst_position_m": max(r["position_m"] for r in sel)})
    return out


def photo_flight(seed: int, n: int) -> Path:
    """The flight ``seed`` with 1280 x 960 photos (``turbinefit simulate --images``; maps
    at 320 x 240, the default), simulated once into ``benchmarks/data/``."""
    out = DATA / f"flight_images1280_n{n}_s{seed}"
    if not (out / "keyframes.txt").exists():
        DATA.mkdir(exist_ok=True)
        subprocess.run([str(BIN), "simulate", str(out), "--keyframes", str(n), "--seed",
                        str(seed), "--width", "1280", "--height", "960", "--images",
                        "--overwrite", "--quiet"], check=True)
    return out


def fit_photos(seed: int, n: int, input_scales: list[float], track_causal: bool,
               refine: bool = False) -> list[dict[str, Any]]:
    """Flight ``seed`` with 1280 x 960 photos fitted as ``fit`` does with no options: from
    its ideal 320 x 240 maps, and from its photos with the net run at each input scale
    without coarse to fine (1: the shipped detector's first pass, test-time zoom on; above
    1: zoom off, maps that many times larger); with ``track_causal``, the tracker's causal
    estimates from the photos at scale 1 (and coarse to fine) against the initial poses;
    with ``refine``, also
    from its photos coarse to fine (``DetectOptions(refine=True)``, what ``fit`` does)."""
    from bench_defaults import track

    folder = read_flight_folder(photo_flight(seed, n))
    sources: list[tuple[str, Any]] = [("ideal 320", FileHeatmaps(folder, mmap=False))]
    sources += [(f"photos x{s:g}", PhotoHeatmaps(folder, options=DetectOptions(
        zoom=None if s == 1 else False, input_scale=s, refine=False))) for s in input_scales]
    if refine:
        sources.append(("photos refined", PhotoHeatmaps(folder,
                                                        options=DetectOptions(refine=True))))
    rows = []
    for name, source in sources:
        t0 = time.perf_counter()
        flight = folder.flight(source.stack(), source.camera)
        load_s = time.perf_counter() - t0
        assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
        res = fit(flight, fit_config_for(source))
        acc = accuracy(res.world_T_cam, res.turbine, flight.gt_world_T_cam, flight.gt_turbine)
        row = {"seed": seed, "source": name, "position_m": acc.position_error_m,
               "orientation_deg": acc.orientation_error_deg,
               "model_point_m": acc.model_point_error_m, "load_s": load_s,
               "verdict": res.verdict}
        if track_causal and name in ("photos x1", "photos refined"):
            t = track(flight, fit_config_for(source))
            row["causal_better_than_initial_after_20"] = t["causal_better_than_initial_after_20"]
        rows.append(row)
        print(f"  seed {seed:2d} {name:11s} position {row['position_m']:.3f} m, orientation "
              f"{row['orientation_deg']:.3f} deg, model points {row['model_point_m']:.3f} m"
              + (f", causal better {row['causal_better_than_initial_after_20']:.2f}"
                 if "causal_better_than_initial_after_20" in row else "")
              + f" (load {load_s:.1f} s)", flush=True)
    return rows


def heldout_view_photo(index: int, width: int) -> tuple[Any, Any]:
    """Held-out view ``index``: its photo at ``width`` (RGB uint8) and the view."""
    from turbinefit.io.images import resize_image
    from turbinefit.sim.dataset import RENDER_SCALE, sample_view
    from turbinefit.sim.images import sample_scene
    from turbinefit.sim.images.render import render_image_and_depth

    rng = np.random.default_rng(np.random.SeedSequence([HELDOUT_SEED, index]))
    view = sample_view(rng)
    scene = sample_scene(rng, view.turbine)
    height = SIZES[width]
    render_w = max(width, view.camera.width * RENDER_SCALE)
    big = view.camera.resized(render_w, render_w * height // width)
    photo, _ = render_image_and_depth(big, view.world_T_cam, view.turbine.to_vector(), scene,
                                      rng, view.geometry)
    if render_w != width:
        photo = resize_image(photo, width, height)
    return photo, view


def detection(n: int, width: int, refine: bool = False) -> dict[str, dict[str, float]]:
    """Detection figures of the shipped model on ``n`` held-out photos ``width`` wide,
    coarse to fine if ``refine``."""
    from turbinefit.detect import HeatmapDetector
    from turbinefit.eval.detection import DetectionStats
    from turbinefit.heatmaps.targets import TARGET_SIGMA_PX
    from turbinefit.sim.render import RenderConfig, render_heatmaps
    from turbinefit.turbine.model import model_points

    det = HeatmapDetector(refine=refine)
    info = det.info
    grid_w = None
    stats: dict[str, DetectionStats] = {}
    t_render = t_detect = 0.0
    for i in range(n):
        t0 = time.perf_counter()
        photo, view = heldout_view_photo(i, width)
        t1 = time.perf_counter()
        pred = det.detect_small(photo)
        t_render += t1 - t0
        t_detect += time.perf_counter() - t1
        h, w = pred.shape[1:]
        if grid_w is None:
            grid_w = w
            # distances in photo pixels and in pixels at 320 px; match within 5 px at 320
            stats = {unit: DetectionStats(threshold=info.threshold,
                                          tip_threshold=info.tip_threshold,
                                          px_scale=k, match_px=5.0 * k / (320 / w),
                                          short_blade_px=40.0 * k / (320 / w))
                     for unit, k in (("photo_px", width / w), ("px_at_320", 320 / w))}
        cam = view.camera.resized(w, h)
        target = render_heatmaps(cam, view.world_T_cam, view.turbine.to_vector(),
                                 view.geometry, RenderConfig(sigma_px=TARGET_SIGMA_PX))
        world_p, _ = model_points(view.turbine.to_vector(), view.geometry)
        uv, ok, _ = cam.project_unbounded(view.world_T_cam.inverse().apply(world_p))
        visible = ok & cam.in_image(uv)
        for s in stats.values():
            s.add(pred, target, np.where(np.isfinite(uv), uv, 0.0), visible)
    out = {unit: s.summary() for unit, s in stats.items()}
    out["timing"] = {"render_s_per_photo": t_render / n, "detect_s_per_photo": t_detect / n}
    return out


DETECT_KEYS = ("hub_median_px", "tower_top_median_px", "base_median_px", "tips_recall",
               "tips_precision", "iou_tower", "iou_nacelle", "iou_blade")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="*", default=list(range(12)),
                    help="flights of the fits from ideal maps (none: skip them)")
    ap.add_argument("--keyframes", type=int, default=200)
    ap.add_argument("--sizes", type=int, nargs="+", default=[320, 1280], choices=[320, 1280])
    ap.add_argument("--large-keyframes", type=int, default=20,
                    help="keyframes of the 5280 x 3956 comparison (0: none)")
    ap.add_argument("--large-seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--detect", type=int, default=100,
                    help="held-out photos at 320 x 240 and 1280 x 960 (0: none)")
    ap.add_argument("--detect-large", type=int, default=10,
                    help="held-out photos at 5280 x 3956 (0: none)")
    ap.add_argument("--photos", type=int, default=0,
                    help="flights with 1280 x 960 photos (seeds 20, 21, ...) fitted from "
                         "ideal 320 x 240 maps and from their photos (0: none)")
    ap.add_argument("--input-scales", type=float, nargs="+", default=[1.0, 2.0],
                    help="net input scales of the photo fits")
    ap.add_argument("--no-track", action="store_true", help="photo fits without the tracker")
    ap.add_argument("--refine", action="store_true",
                    help="also detect coarse to fine (DetectOptions refine): detection "
                    "figures above 320 px and photo fits")
    ap.add_argument("--out", type=Path, default=RESULTS / "bench_resolution.json")
    args = ap.parse_args()

    rows: list[dict[str, Any]] = []
    print(f"fits from ideal heat-maps, {args.keyframes} keyframes, seeds {args.seeds}")
    for seed in args.seeds:
        for w in args.sizes:
            rows += fit_flight(seed, args.keyframes, w, [None] if w == 320 else [None, 1.0])
    if args.large_keyframes > 0:
        print(f"the same at 5280 x 3956 ({args.large_keyframes} keyframes, seeds "
              f"{args.large_seeds})")
        for seed in args.large_seeds:
            for w in (320, 1280, LARGE):
                rows += fit_flight(seed, args.large_keyframes, w,
                                   [None] if w == 320 else [None, 1.0])
    summary = summarise(rows)
    print("\nmeans: keyframes, width, pixel_scale: position, orientation, model points")
    for s in summary:
        print(f"  {s['keyframes']:4d} {s['width']:5d} {s['pixel_scale']:>5}: "
              f"{s['position_before_m']:.3f} -> {s['position_m']:.3f} m (worst "
              f"{s['worst_position_m']:.3f}), {s['orientation_deg']:.3f} deg, "
              f"{s['model_point_before_m']:.3f} -> {s['model_point_m']:.3f} m, "
              f"{s['iterations']:.1f} it, {s['solve_s']:.2f} s ({s['flights']} flights)")

    detect: dict[str, Any] = {}
    runs = [(str(w), w, n, False) for w, n in ((320, args.detect), (1280, args.detect),
                                               (LARGE, args.detect_large))]
    if args.refine:  # coarse to fine where a photo is at least twice the net's input
        runs += [(f"{w} refined", w, n, True) for w, n in ((1280, args.detect),
                                                           (LARGE, args.detect_large))]
    for key, width, n, refine in runs:
        if n <= 0:
            continue
        detect[key] = d = detection(n, width, refine)
        d["photos"] = n
        print(f"\ndetection on {n} held-out {width}x{SIZES[width]} photos"
              f"{', coarse to fine' if refine else ''} "
              f"(render {d['timing']['render_s_per_photo']:.1f} s, detect "
              f"{d['timing']['detect_s_per_photo']:.3f} s per photo)")
        for unit in ("photo_px", "px_at_320"):
            print(f"  {unit:9s} " + ", ".join(f"{k} {d[unit][k]:.3f}" for k in DETECT_KEYS))

    photo_rows: list[dict[str, Any]] = []
    photo_summary: dict[str, Any] = {}
    if args.photos > 0:
        print(f"\nfits with no options of {args.photos} flights with 1280x960 photos")
        for seed in range(PHOTO_SEED, PHOTO_SEED + args.photos):
            photo_rows += fit_photos(seed, args.keyframes, args.input_scales, not args.no_track,
                                     args.refine)
        ideal = {r["seed"]: r for r in photo_rows if r["source"] == "ideal 320"}
        for name in dict.fromkeys(r["source"] for r in photo_rows):
            sel = [r for r in photo_rows if r["source"] == name]
            means = {k: statistics.fmean(r[k] for r in sel)
                     for k in ("position_m", "orientation_deg", "model_point_m")}
            for k in ("position_m", "model_point_m"):  # ratio of means to the ideal fits'
                means[f"{k}_over_ideal"] = means[k] / statistics.fmean(
                    ideal[r["seed"]][k] for r in sel)
            causal = [r["causal_better_than_initial_after_20"] for r in sel
                      if "causal_better_than_initial_after_20" in r]
            if causal:
                means["causal_better_than_initial_after_20"] = statistics.fmean(causal)
            photo_summary[name] = means
            print(f"  {name:11s} " + ", ".join(f"{k} {v:.3f}" for k, v in means.items()))

    write_json(args.out, {
        "machine": platform.platform(), "args": {k: v for k, v in vars(args).items()
                                                 if k != "out"},
        "fit_rows": rows, "fit_summary": summary, "detection": detect,
        "photo_rows": photo_rows, "photo_summary": photo_summary,
        "config": dataclasses.asdict(FitConfig(**FILE_FIT_DEFAULTS))})
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
