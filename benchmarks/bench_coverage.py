"""``turbinefit coverage`` and the pixel-to-blade lookup on simulated flights.

* **Lookup**: each default 200-keyframe flight (``--flights`` seeds, cached in
  ``benchmarks/data/``) is fitted with ``turbinefit fit``; every ``--every``-th keyframe is
  rendered with per-pixel labels (``turbinefit.sim.images.render.render_labels``: ground-truth
  pose and turbine, the flight's scene, at the flight's 320 x 240 camera), and every
  pixel's ray is looked up on the *fitted* turbine from the *fitted* pose. Over the
  pixels the labels give to the turbine: the right part (blade A/B/C, tower, nacelle,
  hub), on blades the right blade and side, and span within 0.5 m (targets: >= 99 % and
  span within 0.5 m). Blade pitch: the scene's, given as known (``--blade-pitch``), and
  assumed 0 (a flat blade in the rotor plane). The same with the ground-truth poses and
  turbine separates the model's differences from the renderer (twist, tip, sub-pixel
  parts) from the fit's errors.
* **Plan**: ``turbinefit plan`` of each fit at a 10 m stand-off and 2 mm/px for a 20 MP
  camera (5280 x 3956, f = 7350 px: a 50 mm lens on a full-frame sensor), with the gimbal
  free (``--platform unlimited``), limited to 30 deg up and to the default platform's 20
  deg; then ``turbinefit coverage`` of photos at the planned
  poses of the *true* turbine (the flight flown exactly): per blade side the fraction of
  the span seen at <= 2 mm/px (target >= 95 %), the path's length.
* **Speed**: ``turbinefit coverage`` of the fit of a 1000-keyframe flight, process start
  to exit (target < 5 s), and the coverage computation alone.

Usage::

    python benchmarks/bench_coverage.py [--flights 2] [--every 2]

Prints a table and writes ``benchmarks/results/bench_coverage.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import RESULTS, run_command, simulate, warm, write_json

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.inspection.surface import (
    PARTS,
    SurfaceShape,
    TurbineSurface,
    blade_names,
    lookup_pixels,
    sector,
)
from turbinefit.io.camera_yaml import read_camera_yaml, write_camera_yaml
from turbinefit.io.flight_folder import read_flight_folder
from turbinefit.io.tum import read_tum
from turbinefit.io.turbine_yaml import read_turbine_yaml
from turbinefit.sim.images.render import render_labels
from turbinefit.sim.images.scene import flight_scene
from turbinefit.turbine.solid import ROOT_TWIST

#: The renderer's blade twist at the root [rad] (``sim/images/painter.py``).
#: Bins [m] of the blade span errors (the last one: 20 m and more).
SPAN_BINS = np.append(np.arange(0.0, 20.0 + 1e-9, 0.05), np.inf)
VARIANTS = ("fitted_flat", "fitted_pitch", "fitted_pitch_twist", "truth_pitch_twist")


def _counts(surface: TurbineSurface, poses: Any, gt: Any, gt_poses: Any, scene: Any,
            camera: Any, keyframes: list[int]) -> dict[str, int]:
    """Pixel counts of one flight: turbine pixels, part right; blade pixels, blade and
    side right, span within 0.5 m."""
    names = blade_names(gt)
    code_part = {1: PARTS.index("tower"), 2: PARTS.index("nacelle"), 3: PARTS.index("hub")}
    code_part |= {4 + i: PARTS.index(f"blade_{names[i]}") for i in range(3)}
    lut = np.full(8, -2)
    for c, p in code_part.items():
        lut[c] = p
    vv, uu = np.mgrid[0:camera.height, 0:camera.width]
    uv = np.stack([uu.ravel(), vv.ravel()], -1).astype(float)
    c: dict[str, Any] = dict.fromkeys(("turbine", "part", "blade", "blade_side", "span",
                                       "tower", "tower_span"), 0)
    hist = np.zeros(len(SPAN_BINS) - 1, dtype=np.int64)
    for k in keyframes:
        lab = render_labels(camera, gt_poses[k], gt.to_vector(), scene)
        hits, _ = lookup_pixels(surface, camera, poses[k], uv)
        code = lab.part.ravel().astype(np.int64)
        want = lut[code]
        turb = want >= 0
        c["turbine"] += int(turb.sum())
        c["part"] += int(np.sum(hits.part[turb] == want[turb]))
        bl = turb & (want <= 2)
        right = bl & (hits.part == want)
        c["blade"] += int(bl.sum())
        gside = sector(lab.side_angle.ravel()[right])
        c["blade_side"] += int(np.sum(hits.side[right] == gside))
        err = np.abs(hits.span[right] - lab.span.ravel()[right])
        c["span"] += int(np.sum(err < 0.5))
        hist += np.histogram(np.minimum(err, SPAN_BINS[-1] - 1e-9), SPAN_BINS)[0]
        tw = want == PARTS.index("tower")
        okt = tw & (hits.part == want)
        c["tower"] += int(tw.sum())
        c["tower_span"] += int(np.sum(np.abs(hits.span[okt] - lab.span.ravel()[okt]) < 0.5))
    c["span_error_hist"] = hist.tolist()
    return c


def span_percentile(hist: np.ndarray, q: float) -> float:
    """The ``q`` quantile [m] of the span errors counted in ``hist`` (bins
    :data:`SPAN_BINS`; the upper edge of the bin it falls in)."""
    cum = np.cumsum(hist)
    return float(SPAN_BINS[1 + int(np.searchsorted(cum, q * cum[-1]))])


def fit_of(seed: int, root: Path) -> tuple[Path, Path]:
    """The default 200-keyframe flight of ``seed`` and its fit (made once)."""
    flight = simulate(200, seed)
    fit_dir = root / f"fit{seed}"
    if not fit_dir.exists():
        run_command(["fit", str(flight), "--out", str(fit_dir), "--no-plots", "--quiet"])
    return flight, fit_dir


def lookup_flight(seed: int, every: int, root: Path) -> dict[str, Any]:
    flight, fit_dir = fit_of(seed, root)
    folder = read_flight_folder(flight)
    gt, gt_poses = folder.gt_turbine, folder.gt_world_T_cam
    assert gt is not None and gt_poses is not None
    _, poses = read_tum(fit_dir / "keyframes.txt")
    fitted = read_turbine_yaml(fit_dir / "turbine.yaml")
    camera = read_camera_yaml(flight / "camera.yaml")
    scene = flight_scene(gt.to_vector(), seed)
    keyframes = list(range(0, len(poses), every))
    # the renderer's pitch p and twist are -p and -14 deg in the inspection's convention
    pitch = SurfaceShape(blade_pitch=-scene.blade_pitch)
    shape = SurfaceShape(blade_pitch=-scene.blade_pitch, blade_twist=-ROOT_TWIST)
    row: dict[str, Any] = {"seed": seed, "scene_pitch_deg": math.degrees(scene.blade_pitch),
                           "keyframes": len(keyframes)}
    for name, surface, p in (
            ("fitted_flat", TurbineSurface(fitted), poses),
            ("fitted_pitch", TurbineSurface(fitted, shape=pitch), poses),
            ("fitted_pitch_twist", TurbineSurface(fitted, shape=shape), poses),
            ("truth_pitch_twist", TurbineSurface(gt, shape=shape), gt_poses)):
        row[name] = _counts(surface, p, gt, gt_poses, scene, camera, keyframes)
    return row


#: The next flight's camera: 20 MP, a 50 mm lens on a full-frame sensor (a P1-like camera).
CAMERA_20MP = PinholeCamera(5280, 3956, 7350.0, 7350.0, 2639.5, 1977.5)


def plan_flight(seed: int, root: Path, gimbal_up: float) -> dict[str, Any]:
    """``plan`` at 10 m and 2 mm/px from the fit, then ``coverage`` of photos taken at
    the planned poses of the true turbine (the flight flown exactly)."""
    flight, fit_dir = fit_of(seed, root)
    cam = root / "camera20mp.yaml"
    write_camera_yaml(cam, CAMERA_20MP)
    plan = root / f"plan{seed}_{gimbal_up:g}"
    t0 = time.perf_counter()
    run_command(["plan", str(fit_dir), "--standoff", "10", "--gsd", "2", "--camera", str(cam),
                 "--out", str(plan), "--platform", "unlimited", "--max-gimbal-up",
                 f"{gimbal_up:g}", "--quiet"])
    seconds = time.perf_counter() - t0
    sim = root / f"sim{seed}_{gimbal_up:g}"
    sim.mkdir()
    shutil.copy(plan / "keyframes.txt", sim / "keyframes.txt")
    shutil.copy(flight / "turbine_groundtruth.yaml", sim / "turbine.yaml")
    cov = root / f"cov{seed}_{gimbal_up:g}"
    run_command(["coverage", str(sim), "--camera", str(cam), "--gsd", "2", "--out", str(cov),
                 "--no-plots", "--quiet"])
    ps = json.loads((plan / "summary.json").read_text())
    cs = json.loads((cov / "summary.json").read_text())["coverage"]
    return {"seed": seed, "gimbal_up_deg": gimbal_up, "plan_s": seconds,
            "length_m": ps["length_m"], "photos": ps["photos"],
            "min_rotor_clearance_m": ps["min_rotor_clearance_m"],
            "covered": {part: {side: c["covered"] for side, c in sides.items()}
                        for part, sides in cs.items()}}


def speed(root: Path) -> dict[str, Any]:
    flight = simulate(1000, 0)
    fit_dir = root / "fit1000"
    run_command(["fit", str(flight), "--out", str(fit_dir), "--no-plots", "--quiet"])
    warm(flight)
    warm(fit_dir)
    out: dict[str, Any] = {}
    for plots in (False, True):
        t0 = time.perf_counter()
        run_command(["coverage", str(fit_dir), "--out", str(root / f"cov{plots}"), "--quiet",
                     *([] if plots else ["--no-plots"])])
        out["wall_s" if plots else "wall_no_plots_s"] = time.perf_counter() - t0
    summary = json.loads((root / "covTrue" / "summary.json").read_text())
    out["coverage_s"] = summary["timing_s"]["coverage"]
    out["rows"] = sum(1 for _ in (root / "covTrue" / "coverage.csv").open()) - 1
    return out


def pct(c: dict[str, int], num: str, den: str) -> float:
    return 100.0 * c[num] / max(c[den], 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flights", type=int, default=2)
    ap.add_argument("--every", type=int, default=2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        rows = [lookup_flight(s, args.every, root) for s in range(args.flights)]
        plans = [plan_flight(s, root, up) for up in (90.0, 30.0, 20.0)
                 for s in range(args.flights)]
        sp = speed(root)
    out: dict[str, Any] = {"machine": platform.platform(), "flights": rows, "speed": sp,
                           "plans": plans}
    print(f"lookup on {args.flights} default 200-keyframe flights, one keyframe in {args.every}, "
          "320x240 labelled renders")
    print(f"{'variant':<20}{'part':>8}{'blade+side':>12}{'span<0.5m':>11}{'tower span':>12}"
          f"{'span error [m] p50 / p90 / p99':>32}")
    totals: dict[str, Any] = {}
    for name in VARIANTS:
        c = {k: sum(r[name][k] for r in rows) for k in rows[0][name] if k != "span_error_hist"}
        hist = np.sum([r[name]["span_error_hist"] for r in rows], axis=0)
        totals[name] = {"part_pct": pct(c, "part", "turbine"),
                        "blade_side_pct": pct(c, "blade_side", "blade"),
                        "span_pct": pct(c, "span", "blade"),
                        "tower_span_pct": pct(c, "tower_span", "tower"), "pixels": c,
                        **{f"span_error_p{q}_m": span_percentile(hist, q / 100)
                           for q in (50, 90, 99)}}
        t = totals[name]
        print(f"{name:<20}{t['part_pct']:7.2f}%{t['blade_side_pct']:11.2f}%"
              f"{t['span_pct']:10.2f}%{t['tower_span_pct']:11.2f}%"
              f"{t['span_error_p50_m']:9.2f}{t['span_error_p90_m']:7.2f}"
              f"{t['span_error_p99_m']:7.2f}")
    out["totals"] = totals
    for r in rows:  # summed into the totals' percentiles
        for name in VARIANTS:
            del r[name]["span_error_hist"]
    print("plan at 10 m, 2 mm/px, 20 MP camera; coverage of its photos of the true turbine")
    for p in plans:
        blades = [v for part, sides in p["covered"].items() if part != "tower"
                  for v in sides.values()]
        tower = list(p["covered"]["tower"].values())
        print(f"seed {p['seed']} gimbal up to {p['gimbal_up_deg']:g} deg: {p['photos']} photos, "
              f"path {p['length_m']:.0f} m, rotor clearance {p['min_rotor_clearance_m']:.2f} m, "
              f"blade sides covered min {100 * min(blades):.1f} % mean "
              f"{100 * np.mean(blades):.1f} %, tower faces min {100 * min(tower):.1f} %, "
              f"planned in {p['plan_s']:.2f} s")
    print(f"coverage of 1000 keyframes: {sp['wall_s']:.2f} s wall with coverage.png "
          f"({sp['wall_no_plots_s']:.2f} s without), computing {sp['coverage_s']:.2f} s, "
          f"{sp['rows']} rows")
    write_json(RESULTS / "bench_coverage.json", out)


if __name__ == "__main__":
    main()
