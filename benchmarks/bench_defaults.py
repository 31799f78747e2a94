"""Which fit and track options to use by default, for each kind of heat-map source.

For each flight (``turbinefit simulate --images``, 200 keyframes, cached in
``benchmarks/data/``) the heat-maps are taken once from each source: the simulator's
(``heatmaps/``, "ideal") and the shipped CNN's on the photos ("photos"). Every candidate
configuration is then fitted in-process on the same maps (``turbinefit.solver.fit``), and
the tracker replays them (``turbinefit.solver.Tracker``, window 20); mean position /
orientation / model-point errors against the ground truth, per source and configuration,
and how often each configuration is the best. The defaults of ``fit`` and ``track`` are the
configurations this measures best for each source.

Usage::

    python benchmarks/bench_defaults.py [--seeds 0 1 ... 11] [--keyframes 200] [--no-track]
        [--model M.onnx]

Prints tables and writes ``benchmarks/results/bench_defaults.json``.
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

from turbinefit.eval.metrics import accuracy
from turbinefit.flight import Flight
from turbinefit.io.flight_folder import read_flight_folder
from turbinefit.jobs.sources import FileHeatmaps, PhotoHeatmaps
from turbinefit.solver import FitConfig, Tracker, TrackerConfig, fit

#: Candidate configurations per heat-map source: name -> FitConfig overrides. (A first
#: sweep of 3 flights also tried interp-cauchy with robust_scale 4 and heatmap_floor 0.1,
#: and paper-best with Cauchy, on both sources: none led on either.)
CANDIDATES: dict[str, dict[str, dict[str, Any]]] = {
    "ideal": {
        "paper-best": {},
        "corr-normal": {"lines": "corr", "line_residual": "normal"},
        "corr-normal-cauchy": {"lines": "corr", "line_residual": "normal", "robust": "cauchy"},
    },
    "photos": {
        "interp-cauchy": {"points": "interp", "robust": "cauchy"},
        "interp-cauchy-scale1": {"points": "interp", "robust": "cauchy", "robust_scale": 1.0},
        "corr-normal-cauchy-sigma2": {"lines": "corr", "line_residual": "normal",
                                      "robust": "cauchy", "pixel_sigma": 2.0},
        "corr-normal-cauchy-sigma2-scale1": {"lines": "corr", "line_residual": "normal",
                                             "robust": "cauchy", "pixel_sigma": 2.0,
                                             "robust_scale": 1.0},
        "corr-normal-cauchy-sigma3": {"lines": "corr", "line_residual": "normal",
                                      "robust": "cauchy", "pixel_sigma": 3.0},
        "corr-normal-cauchy-sigma2-scale0.5": {"lines": "corr", "line_residual": "normal",
                                               "robust": "cauchy", "pixel_sigma": 2.0,
                                               "robust_scale": 0.5},
    },
}


def simulate(seed: int, n: int) -> Path:
    """The flight with photos of ``seed`` (simulated once; shared with bench_detect)."""
    out = DATA / f"flight_images_n{n}_s{seed}"
    if not (out / "keyframes.txt").exists():
        DATA.mkdir(exist_ok=True)
        subprocess.run([str(BIN), "simulate", str(out), "--keyframes", str(n), "--seed",
                        str(seed), "--images", "--overwrite", "--quiet"], check=True)
    return out


def errors(flight: Flight, poses: Any, turbine: Any) -> dict[str, float]:
    assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
    a = accuracy(poses, turbine, flight.gt_world_T_cam, flight.gt_turbine)
    return {"position_m": a.position_error_m, "orientation_deg": a.orientation_error_deg,
            "model_point_m": a.model_point_error_m}


def track(flight: Flight, cfg: FitConfig) -> dict[str, Any]:
    tracker = Tracker(flight.camera, flight.turbine, TrackerConfig(fit=cfg))
    for k in range(flight.num_keyframes):
        tracker.update(float(flight.timestamps[k]), flight.world_T_cam[k], flight.heatmaps[k])
    final = errors(flight, tracker.world_T_cam(), tracker.turbine)
    causal = tracker.causal_world_T_cam()
    gt = flight.gt_world_T_cam
    assert gt is not None
    dc = np.linalg.norm(causal.translation - gt.translation, axis=-1)
    d0 = np.linalg.norm(flight.world_T_cam.translation - gt.translation, axis=-1)
    later = slice(20, None)
    return {**{f"final_{k}": v for k, v in final.items()},
            "causal_position_m": float(dc.mean()),
            "causal_better_than_initial_after_20": float(np.mean(dc[later] < d0[later]))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(12)))
    ap.add_argument("--keyframes", type=int, default=200)
    ap.add_argument("--sources", nargs="+", default=["ideal", "photos"],
                    choices=["ideal", "photos"])
    ap.add_argument("--no-track", action="store_true", help="fits only")
    ap.add_argument("--candidates", nargs="+", metavar="NAME",
                    help="only these configurations (names of CANDIDATES)")
    ap.add_argument("--model", type=Path, default=None,
                    help="the ONNX model the photos' heat-maps are detected with (default: "
                         "the shipped one)")
    ap.add_argument("--out", type=Path, default=RESULTS / "bench_defaults.json")
    args = ap.parse_args()
    chosen = {src: {n: c for n, c in CANDIDATES[src].items()
                    if args.candidates is None or n in args.candidates} for src in args.sources}
    unknown = set(args.candidates or ()) - {n for c in CANDIDATES.values() for n in c}
    if unknown:
        ap.error(f"unknown candidates: {', '.join(sorted(unknown))}")
    rows: list[dict[str, Any]] = []
    for seed in args.seeds:
        folder = read_flight_folder(simulate(seed, args.keyframes))
        for source_name in args.sources:
            source = (FileHeatmaps(folder, mmap=False) if source_name == "ideal"
                      else PhotoHeatmaps(folder, args.model))
            t0 = time.perf_counter()
            flight = folder.flight(source.stack(), source.camera)
            load_s = time.perf_counter() - t0
            initial = errors(flight, flight.world_T_cam, flight.turbine)
            for name, over in chosen[source_name].items():
                cfg = dataclasses.replace(FitConfig(), **over)
                t1 = time.perf_counter()
                res = fit(flight, cfg)
                row: dict[str, Any] = {
                    "seed": seed, "source": source_name, "config": name,
                    "initial_position_m": initial["position_m"], "load_s": load_s,
                    "fit_s": time.perf_counter() - t1,
                    **errors(flight, res.world_T_cam, res.turbine)}
                if not args.no_track:
                    row.update(track(flight, cfg))
                rows.append(row)
                print(f"seed {seed:2d} {source_name:6s} {name:32s} position "
                      f"{row['position_m']:.3f} m  orientation {row['orientation_deg']:.3f} deg  "
                      f"model points {row['model_point_m']:.3f} m"
                      + (f"  track final {row['final_position_m']:.3f} m causal "
                         f"{row['causal_position_m']:.3f} m better "
                         f"{row['causal_better_than_initial_after_20']:.2f}"
                         if "final_position_m" in row else ""), flush=True)
    summary: dict[str, Any] = {}
    for source_name in args.sources:
        print(f"\n{source_name}: mean over {len(args.seeds)} flights")
        table = {}
        for name in chosen[source_name]:
            sel = [r for r in rows if r["source"] == source_name and r["config"] == name]
            keys = [k for k in sel[0] if isinstance(sel[0][k], float) and not k.endswith("_s")]
            means = {k: statistics.fmean(r[k] for r in sel) for k in keys}
            table[name] = means
            print(f"  {name:32s} " + "  ".join(f"{k} {v:.3f}" for k, v in means.items()))
        best = min(table, key=lambda n: table[n]["position_m"])
        print(f"  best in position: {best}")
        summary[source_name] = {"means": table, "best_position": best}
    write_json(args.out, {"machine": {"platform": platform.platform()},
                          "seeds": args.seeds, "keyframes": args.keyframes,
                          "candidates": chosen,
                          "summary": summary, "rows": rows})
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
