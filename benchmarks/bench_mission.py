"""Inspection missions in the loop (``turbinefit mission``): coverage, safety and where the
defects are, over many missions, closed loop against open loop, standard GNSS against RTK.

Each mission (:func:`turbinefit.mission.run_mission`, judged by
:func:`turbinefit.mission.mission_outcome`) flies round a turbine of the catalogue
(``--types``, cycled over the seeds) whose heading, blade rotation and base are drawn from
the seed, with 12 known defects on its blades, from an operator's turbine off by up to
+-5 deg in heading and blade rotation, 3 m at the base and 5 % in size; the 20 MP camera of
the benchmarks (f = 7350 px), a 10 m stand-off, 2 mm/px; photos rendered 320 px wide and
read by the shipped CNN (``--maps ideal``: the simulator's heat-maps). Per seed:

* ``closed``: the loop (approach orbit, init, tracker, replanning), standard GNSS;
* ``open``: the typed-in turbine's plan flown on GNSS alone, standard GNSS;
* ``rtk``: the loop with RTK.

Figures: the share of missions whose every blade side is covered at <= 2 mm/px to at
least 95 %; the closest true approach to any blade (least over the missions, and as a
fraction of the stand-off); the defects seen, pooled over the missions, on the right blade
and side, and their span errors (median, 95th percentile), from the fit of the mission's
photos and from the GNSS poses with the typed-in turbine (what an operator has without
turbinefit). ``--timing``: one more closed mission alone (nothing else running), for the
tracker's update time (detection included) and the time to fit its photos.

Results go to ``benchmarks/results/bench_mission.json`` (``--out``). Missions run in
``--workers`` processes (one solver and one detector thread each).

``--gps-sigma M`` weighs the standard GNSS fixes as M metres in the tracker and the fit
(``MissionConfig.gps_sigma``; default the GNSS model's 1.5 m), ``--fit-gps-sigma M`` in
the final fit alone: ``--missions 2 --kinds closed --maps ideal|photos --gps-sigma 1.5|5``,
``--kinds closed --gps-sigma 5`` and ``--kinds closed,open --fit-gps-sigma 5`` are the
comparison in ``docs/mission.md``.

``--width-term on|off`` puts the width term in the tracker and the final fit of every
mission, or of none (``MissionConfig.width_term``: the camera's distance from a blade
from how wide it looks; default ``auto``: with standard GNSS, not with RTK); ``--kinds
closed,rtk --width-term on`` and ``off`` are the comparison in ``docs/mission.md``.

Each mission's defects and located boxes go into the results too (``defect_truth``,
``defect_boxes``, ``baseline_boxes``), so that a rule for placing a defect can be scored again without
flying (:func:`turbinefit.eval.damage.score_damage`).

Run: ``python benchmarks/bench_mission.py`` (20 seeds x 3 kinds; about 25 min with 2
workers on 2 cores).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
KINDS = {"closed": {"closed_loop": True, "gnss": "standard"},
         "open": {"closed_loop": False, "gnss": "standard"},
         "rtk": {"closed_loop": True, "gnss": "rtk"}}


def one(seed: int, turbine: str, kind: str, maps: str, gps_sigma: float | None = None,
        fit_gps_sigma: float | None = None, width_term: bool | None = None) -> dict[str, Any]:
    """One mission's figures (run in a worker)."""
    from turbinefit.mission import MissionConfig, mission_outcome, run_mission

    standard = KINDS[kind]["gnss"] == "standard"
    cfg = MissionConfig(turbine=turbine, seed=seed, maps=maps,  # type: ignore[arg-type]
                        gps_sigma=gps_sigma if standard else None,
                        fit_gps_sigma=fit_gps_sigma if standard else None,
                        width_term=width_term,
                        **KINDS[kind])  # type: ignore[arg-type]
    t0 = time.perf_counter()
    m = run_mission(cfg)
    t_run = time.perf_counter() - t0
    o = mission_outcome(m)
    defects = [] if o.damage_score is None else [
        {"right_side": d.right_side, "right_part": d.right_part, "span_error_m": d.span_error_m}
        for d in o.damage_score.seen]
    baseline = [] if o.baseline_score is None else [
        {"right_side": d.right_side, "right_part": d.right_part, "span_error_m": d.span_error_m}
        for d in o.baseline_score.seen]
    keys = ("photo", "defect", "part", "side", "chord", "distance_m", "area_px")
    boxes = [] if o.damage_score is None else [
        {k: getattr(b, k) for k in keys} for b in o.damage_score.boxes]
    baseline_boxes = [] if o.baseline_score is None else [
        {k: getattr(b, k) for k in keys} for b in o.baseline_score.boxes]
    truth = [{k: getattr(d, k) for k in ("defect", "part", "side", "span_m", "chord", "size_m",
                                         "kind")} for d in m.defects]
    updates = [k.update_s for k in m.inspection if k.update_s is not None]
    return {"seed": seed, "turbine": turbine, "kind": kind,
            "photos": len(m.inspection), "replans": m.replans,
            "replans_refused": m.replan_failures,
            "least_side_coverage": o.least_side_coverage, "coverage": o.coverage,
            "clearance_rotor_m": o.clearance_rotor_m,
            "clearance_structure_m": o.clearance_structure_m,
            "estimate": o.estimate, "defects": defects, "baseline_defects": baseline,
            "defect_truth": truth, "defect_boxes": boxes, "baseline_boxes": baseline_boxes,
            "update_ms_median": float(1000 * np.median(updates)) if updates else None,
            "fit_s": o.timings["fit"], "mission_s": t_run}


def _pool(rows: list[dict[str, Any]], key: str) -> dict[str, Any]:
    seen = [d for r in rows for d in r[key]]
    span = [d["span_error_m"] for d in seen if d["span_error_m"] is not None]
    return {"defects_seen": len(seen),
            "right_part": float(np.mean([d["right_part"] for d in seen])) if seen else None,
            "right_part_and_side": float(np.mean([d["right_side"] for d in seen]))
            if seen else None,
            "span_error_median_m": float(np.median(span)) if span else None,
            "span_error_p95_m": float(np.percentile(span, 95)) if span else None}


def summarise(rows: list[dict[str, Any]], standoff: float) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for kind in KINDS:
        rs = [r for r in rows if r["kind"] == kind]
        if not rs:
            continue
        cov = np.array([r["least_side_coverage"] for r in rs], dtype=float)
        clear = np.array([r["clearance_rotor_m"] for r in rs])
        out[kind] = {
            "missions": len(rs),
            "every_side_covered_95": float(np.mean(np.nan_to_num(cov) >= 0.95)),
            "least_side_coverage_median": float(np.nanmedian(cov)),
            "closest_rotor_approach_m_min": float(clear.min()),
            "closest_rotor_approach_fraction_min": float(clear.min() / standoff),
            "missions_keeping_0.8_standoff": float(np.mean(clear >= 0.8 * standoff)),
            "closest_structure_approach_m_min": float(min(r["clearance_structure_m"]
                                                          for r in rs)),
            "turbine_frame_position_m_median": float(np.median(
                [r["estimate"]["fit"]["turbine_frame_position_m"] for r in rs])),
            "replans_median": float(np.median([r["replans"] for r in rs])),
            "defects_from_fit": _pool(rs, "defects"),
            "defects_without_turbinefit": _pool(rs, "baseline_defects"),
        }
    return out


def timing(maps: str, width_term: bool | None = None) -> dict[str, Any]:
    """One closed mission alone: the tracker's update time and the fit of its photos."""
    row = one(100, "nrel5mw", "closed", maps, width_term=width_term)
    return {"photos": row["photos"], "update_ms_median": row["update_ms_median"],
            "fit_s": row["fit_s"], "mission_s": row["mission_s"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=20, help="seeds (missions per kind)")
    ap.add_argument("--types", default="nrel5mw,v80,swt93")
    ap.add_argument("--kinds", default="closed,open,rtk")
    ap.add_argument("--maps", choices=("photos", "ideal"), default="photos")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--gps-sigma", type=float, default=None, metavar="M",
                    help="the weight of the standard GNSS fixes in the tracker and the fit, as "
                    "a standard deviation [m] (default: the GNSS model's 1.5 m)")
    ap.add_argument("--fit-gps-sigma", type=float, default=None, metavar="M",
                    help="the same for the final fit of each mission's photos alone")
    ap.add_argument("--width-term", choices=("auto", "on", "off"), default="auto",
                    help="the width term in the tracker and the final fit "
                    "(MissionConfig.width_term; auto: with standard GNSS, not with RTK)")
    ap.add_argument("--timing", action="store_true", help="also time one mission alone")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "bench_mission.json")
    ap.add_argument("--resume", action="store_true",
                    help="keep the missions of an interrupted run (OUT.partial.json)")
    args = ap.parse_args()
    types = args.types.split(",")
    width_term = None if args.width_term == "auto" else args.width_term == "on"
    jobs = [(s, types[s % len(types)], k, args.maps, args.gps_sigma, args.fit_gps_sigma,
             width_term) for s in range(args.missions) for k in args.kinds.split(",")]
    rows: list[dict[str, Any]] = []
    partial = args.out.with_suffix(".partial.json")
    if args.resume and partial.exists():
        wanted = {(s, t, k) for s, t, k, *_ in jobs}
        rows = [r for r in json.loads(partial.read_text())
                if (r["seed"], r["turbine"], r["kind"]) in wanted]
        done = {(r["seed"], r["turbine"], r["kind"]) for r in rows}
        jobs = [j for j in jobs if (j[0], j[1], j[2]) not in done]
        print(f"resuming: {len(rows)} missions kept, {len(jobs)} to fly", flush=True)
    total = len(rows) + len(jobs)
    os.environ["OMP_NUM_THREADS"] = "1"
    t0 = time.perf_counter()
    with cf.ProcessPoolExecutor(args.workers) as pool:
        futures = {pool.submit(one, *j): j for j in jobs}
        for f in cf.as_completed(futures):
            rows.append(f.result())
            r = rows[-1]
            print(f"[{len(rows)}/{total} {time.perf_counter() - t0:.0f} s] seed {r['seed']} "
                  f"{r['turbine']} {r['kind']}: least side {r['least_side_coverage']:.3f}, "
                  f"rotor {r['clearance_rotor_m']:.2f} m, fit "
                  f"{r['estimate']['fit']['turbine_frame_position_m']:.3f} m in the turbine's "
                  f"frame, {len(r['defects'])} defects", flush=True)
            partial.write_text(json.dumps(rows, default=float))
    rows.sort(key=lambda r: (r["seed"], r["kind"]))
    result: dict[str, Any] = {"machine": platform.platform(), "python": sys.version.split()[0],
                              "maps": args.maps, "gps_sigma_m": args.gps_sigma,
                              "fit_gps_sigma_m": args.fit_gps_sigma, "width_term": args.width_term,
                              "standoff_m": 10.0, "gsd_mm": 2.0,
                              "summary": summarise(rows, 10.0), "missions": rows}
    os.environ.pop("OMP_NUM_THREADS", None)
    if args.timing:
        result["timing"] = timing(args.maps, width_term)
    args.out.parent.mkdir(exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1, default=float) + "\n")
    partial.unlink(missing_ok=True)
    print(json.dumps(result["summary"], indent=1))
    if "timing" in result:
        print("timing:", result["timing"])


if __name__ == "__main__":
    main()
