"""How much of every blade side the inspection planner's photos cover, over many rotor
positions and turbines.

For each turbine type (``--types``: the NREL 5 MW, V80 and SWT-93 presets) and each seed
(``--seeds``), the turbine is :func:`~turbinefit.sim.turbines.preset_turbine` with the rng
a mission of that seed draws its turbine from (``SeedSequence(seed).spawn(6)[0]``: random
heading, blade rotation and base). :func:`~turbinefit.inspection.plan.plan_path` plans on
the true turbine at a 10 m stand-off and 2 mm/px for a 20 MP camera (5280 x 3956 px,
f = 7350 px: a 50 mm lens on a full-frame sensor), and photos taken exactly at the
planned poses are judged by :func:`~turbinefit.inspection.coverage.flight_coverage` (samples
every 0.5 m): per blade side the share of the span seen at <= 2 mm/px. Cases:

* ``flat``: the surface's flat blades in the rotor plane, the gimbal free (+90 deg);
* ``twisted``: the renderer's blades (twist 14 deg at the root, the pitch the renderer
  draws: -2 to 8 deg, feathered 70-90 deg one time in eight), planned for and judged on
  that surface, the gimbal free;
* ``flat_gimbal30``: flat blades, the gimbal limited to +30 deg up.

Per turbine type and case: the share of rotor positions whose every blade side reaches
95 %, the least and median side coverage (over all sides of all positions) and the median
of each position's least side, the photos, the views the planner added where its
straight views leave a side uncovered (``fill``), the path length and the planning time
(wall time on whatever machine runs it: a loaded 2-core machine here).

Usage::

    python benchmarks/bench_plan_coverage.py [--seeds 40] [--types nrel5mw,v80,swt93]
        [--cases flat,twisted,flat_gimbal30] [--jobs 1]

Prints a table and writes ``benchmarks/results/bench_plan_coverage.json``.
"""

from __future__ import annotations

import argparse
import math
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
from common import RESULTS, write_json

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.inspection.coverage import flight_coverage
from turbinefit.inspection.plan import PlanOptions, plan_path
from turbinefit.inspection.surface import BLADE_SIDES, PARTS, SurfaceShape, TurbineSurface
from turbinefit.jobs.plan import photo_poses
from turbinefit.sim.turbines import preset_turbine
from turbinefit.turbine.solid import ROOT_TWIST

CAMERA_20MP = PinholeCamera(5280, 3956, 7350.0, 7350.0, 2639.5, 1977.5)
STANDOFF, GSD = 10.0, 2.0
CASES = {"flat": (False, 90.0), "twisted": (True, 90.0), "flat_gimbal30": (False, 30.0)}
#: A blade side counts as covered from this share of its span on.
WELL = 0.95


def turbine_of(name: str, seed: int) -> Any:
    """The turbine a mission of ``seed`` flies round (its first random stream)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(6)[0])
    return preset_turbine(name, rng)


def renderer_pitch(seed: int) -> float:
    """A blade pitch [rad, this package's sense] drawn as the renderer draws its scenes'
    (``sim/images/scene.py``): -2 to 8 deg, one time in eight feathered (70-90 deg);
    the renderer's sense is the opposite of :class:`SurfaceShape`'s."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 7]))
    deg = rng.uniform(-2.0, 8.0) if rng.uniform() < 0.88 else rng.uniform(70.0, 90.0)
    return -math.radians(deg)


def one(name: str, seed: int, case: str) -> dict[str, Any]:
    twisted, up = CASES[case]
    pitch = renderer_pitch(seed) if twisted else 0.0
    shape = SurfaceShape(blade_pitch=pitch, blade_twist=-ROOT_TWIST) if twisted else None
    surface = TurbineSurface(turbine_of(name, seed), shape=shape)
    t0 = time.perf_counter()
    plan = plan_path(surface, CAMERA_20MP, PlanOptions(STANDOFF, GSD, max_gimbal_up_deg=up))
    seconds = time.perf_counter() - t0
    cov = flight_coverage(surface, CAMERA_20MP, photo_poses(plan))
    covered = np.array([g.covered(GSD) for g in cov.grids[:3]])  # (3 blades, 4 sides)
    predicted = getattr(plan, "covered", {})
    return {"type": name, "seed": seed, "case": case, "pitch_deg": math.degrees(pitch),
            "photos": len(plan.photos), "fill": int(sum(getattr(plan, "fill", {}).values())),
            "length_m": plan.length_m, "plan_s": seconds,
            "min_rotor_clearance_m": plan.min_rotor_clearance,
            "covered": {f"{PARTS[i]}/{BLADE_SIDES[k]}": float(covered[i, k])
                        for i in range(3) for k in range(4)},
            "predicted": {f"{PARTS[i]}/{BLADE_SIDES[k]}": v for (i, k), v in predicted.items()},
            "tower": [float(v) for v in cov.grids[3].covered(GSD)]}


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    sides = np.array([list(r["covered"].values()) for r in rows])  # (positions, 12)
    least = sides.min(axis=1)
    return {"positions": len(rows), "all_sides_95_share": float(np.mean(least >= WELL)),
            "least_side": float(sides.min()), "median_side": float(np.median(sides)),
            "median_least_side": float(np.median(least)),
            "photos_median": float(np.median([r["photos"] for r in rows])),
            "fill_median": float(np.median([r["fill"] for r in rows])),
            "length_median_m": float(np.median([r["length_m"] for r in rows])),
            "length_max_m": float(np.max([r["length_m"] for r in rows])),
            "plan_s_median": float(np.median([r["plan_s"] for r in rows])),
            "least_rotor_clearance_m": float(min(r["min_rotor_clearance_m"] for r in rows)),
            "worst": [{"seed": r["seed"], "side": min(r["covered"], key=r["covered"].get),
                       "covered": float(min(r["covered"].values()))}
                      for r in sorted(rows, key=lambda r: min(r["covered"].values()))[:3]]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--types", default="nrel5mw,v80,swt93")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args()
    types, cases = args.types.split(","), args.cases.split(",")
    for c in cases:
        if c not in CASES:
            ap.error(f"unknown case {c!r}; known: {', '.join(CASES)}")
    work = [(t, s, c) for c in cases for t in types for s in range(args.seeds)]
    t0 = time.perf_counter()
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            rows = list(pool.map(one, *zip(*work, strict=True)))
    else:
        rows = [one(*w) for w in work]
    out: dict[str, Any] = {"machine": platform.platform(), "seeds": args.seeds,
                           "standoff_m": STANDOFF, "gsd_mm_px": GSD,
                           "wall_s": time.perf_counter() - t0, "summary": {}, "rows": rows}
    print(f"plan at {STANDOFF:g} m, {GSD:g} mm/px, 20 MP camera, {args.seeds} rotor positions "
          "per type; coverage of the planned photos at <= 2 mm/px")
    print(f"{'case':<15}{'type':<9}{'all sides >= 95 %':>18}{'least':>8}{'median':>8}"
          f"{'median least':>14}{'photos':>8}{'fill':>6}{'path [m]':>10}{'max path':>10}"
          f"{'plan [s]':>10}")
    for c in cases:
        for t in types:
            s = summarise([r for r in rows if r["case"] == c and r["type"] == t])
            out["summary"][f"{c}/{t}"] = s
            print(f"{c:<15}{t:<9}{100 * s['all_sides_95_share']:17.1f}%"
                  f"{100 * s['least_side']:7.1f}%{100 * s['median_side']:7.1f}%"
                  f"{100 * s['median_least_side']:13.1f}%{s['photos_median']:8.0f}"
                  f"{s['fill_median']:6.0f}{s['length_median_m']:10.0f}"
                  f"{s['length_max_m']:10.0f}{s['plan_s_median']:10.2f}")
    write_json(RESULTS / "bench_plan_coverage.json", out)


if __name__ == "__main__":
    main()
