"""How well the verdict of a fit (:mod:`turbinefit.solver.verdict`) separates good fits
from bad ones, and whether theta's covariance is honest.

* **studies**: the default simulated flights of every study
  (:func:`turbinefit.experiments.studies.study_config`, ``--flights`` flights of
  ``--keyframes`` keyframes each, every configuration of the study), plus a *hard* sweep
  (drift and turbine errors 4-10x the defaults, heat-map faults 2-4x) that produces
  flights the fit cannot recover. Reported: the share of flights with final position
  error under 0.5 m whose verdict is ``ok`` (target >= 99 %) and the share of those over
  2 m whose verdict is ``failed`` or ``doubtful`` (target >= 90 %), and the signals of
  the worst good and the best bad flights (what the thresholds were set from);
* **NEES**: on the joint fits of the studies' flights with error under 0.5 m, the
  normalised estimation error squared of theta, ``e^T Sigma^-1 e``: its mean (7 if the
  covariance is honest) and the share inside the chi-square(7) 95 % band [1.69, 16.01];
* **evidence-free heat-maps**: all zeros, all ones and a constant 0.3 on flights of the
  default simulation, with the command-line defaults and the paper's configuration:
  every fit must end ``failed``.

Usage::

    python benchmarks/bench_verdict.py [--flights 12] [--keyframes 60] [--workers 2]

Prints tables and writes ``benchmarks/results/bench_verdict.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
from common import RESULTS, write_json

from turbinefit.eval.metrics import accuracy
from turbinefit.experiments.studies import STUDIES, study_config
from turbinefit.experiments.sweep import SweepConfig, _sim_config, fit_config, flight_specs
from turbinefit.heatmaps import HeatmapStack
from turbinefit.sim.scenario import SimConfig, simulate_flight
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import fit
from turbinefit.turbine.model import param_errors

#: chi-square(7) 2.5 % and 97.5 % quantiles.
CHI2_7_BAND = (1.690, 16.013)
#: the command-line defaults for heat-map files (turbinefit.jobs.sources)
CLI_DEFAULTS = FitConfig(lines="corr", line_residual="normal", robust="cauchy")
GOOD_M = 0.5
BAD_M = 2.0


def hard_config(flights: int, keyframes: int) -> SweepConfig:
    """Flights beyond the fit's basin: large drift and turbine errors, poor heat-maps."""
    return SweepConfig(name="hard", flights=flights, keyframes=keyframes, seed=7,
                       pose_scale=(4.0, 10.0), theta_scale=(4.0, 10.0),
                       heatmap_scale=(2.0, 4.0),
                       configs={"paper-best": {"preset": "paper-best"},
                                "cli-defaults": {"lines": "corr", "line_residual": "normal",
                                                 "robust": "cauchy"}})


def run_one(task: tuple[str, SweepConfig, Any]) -> list[dict[str, Any]]:
    study, cfg, spec = task
    flight = simulate_flight(_sim_config(cfg, spec))
    if cfg.blade_rotation_offset_deg:
        v = flight.turbine.to_vector()
        v[5] += math.radians(cfg.blade_rotation_offset_deg)
        from turbinefit.turbine.model import TurbineParams
        flight = dataclasses.replace(flight, turbine=TurbineParams.from_vector(v))
    assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
    rows = []
    for name in cfg.configs:
        fc = fit_config(cfg.configs, name)
        res = fit(flight, fc)
        acc = accuracy(res.world_T_cam, res.turbine, flight.gt_world_T_cam, flight.gt_turbine,
                       fc.geometry)
        nees = None
        if res.theta_covariance is not None:
            e = param_errors(res.turbine, flight.gt_turbine)
            try:
                nees = float(e @ np.linalg.solve(res.theta_covariance, e))
            except np.linalg.LinAlgError:
                nees = None
        sig = res.signals.to_dict() if res.signals is not None else {}
        rows.append({"study": study, "config": name, "flight": spec.index,
                     "keyframes": spec.keyframes, "mode": fc.mode,
                     "position_m": acc.position_error_m, "verdict": res.verdict,
                     "reasons": res.reasons, "nees": nees, "signals": sig})
    return rows


def evidence_free(n: int, keyframes: int) -> list[dict[str, Any]]:
    rows = []
    for seed in range(n):
        flight = simulate_flight(SimConfig(n_keyframes=keyframes, seed=seed))
        shape = (flight.num_keyframes, 7, flight.camera.height, flight.camera.width)
        for value in (0.0, 1.0, 0.3):
            f2 = dataclasses.replace(flight, heatmaps=HeatmapStack(np.full(shape, value,
                                                                           np.float32)))
            for cname, fc in (("cli-defaults", CLI_DEFAULTS), ("paper-best", FitConfig())):
                res = fit(f2, fc)
                rows.append({"seed": seed, "value": value, "config": cname,
                             "verdict": res.verdict, "reasons": res.reasons})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flights", type=int, default=12, help="flights per study (default 12)")
    ap.add_argument("--keyframes", type=int, default=60, help="keyframes per flight")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--studies", nargs="*", default=list(STUDIES))
    ap.add_argument("--evidence-free-flights", type=int, default=2)
    args = ap.parse_args()
    t0 = time.perf_counter()
    tasks = []
    for study in args.studies:
        cfg = study_config(study, flights=args.flights, keyframes=args.keyframes)
        if cfg.keyframes_max is not None:  # the length study: keep it short
            cfg = dataclasses.replace(cfg, keyframes_max=min(cfg.keyframes_max, 200))
        tasks += [(study, cfg, s) for s in flight_specs(cfg)]
    hard = hard_config(args.flights * 2, args.keyframes)
    tasks += [("hard", hard, s) for s in flight_specs(hard)]
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(args.workers) as pool:
        for part in pool.map(run_one, tasks):
            rows += part
    free = evidence_free(args.evidence_free_flights, args.keyframes)

    good = [r for r in rows if r["position_m"] < GOOD_M]
    bad = [r for r in rows if r["position_m"] > BAD_M]
    good_ok = sum(r["verdict"] == "ok" for r in good)
    bad_flag = sum(r["verdict"] != "ok" for r in bad)
    nees = [r["nees"] for r in good if r["nees"] is not None and r["mode"] == "joint"]
    in_band = sum(CHI2_7_BAND[0] <= x <= CHI2_7_BAND[1] for x in nees)
    result = {
        "machine": platform.platform(), "flights_per_study": args.flights,
        "keyframes": args.keyframes, "fits": len(rows), "seconds": round(time.perf_counter() - t0, 1),
        "good_flights": len(good), "good_ok_share": good_ok / max(len(good), 1),
        "bad_flights": len(bad), "bad_flagged_share": bad_flag / max(len(bad), 1),
        "nees_flights": len(nees), "nees_mean": float(np.mean(nees)) if nees else None,
        "nees_median": float(np.median(nees)) if nees else None,
        "nees_in_chi2_95_band": in_band / max(len(nees), 1),
        "evidence_free_fits": len(free),
        "evidence_free_failed": sum(r["verdict"] == "failed" for r in free),
        "good_not_ok": [r for r in good if r["verdict"] != "ok"],
        "bad_ok": [r for r in bad if r["verdict"] == "ok"],
        "evidence_free_not_failed": [r for r in free if r["verdict"] != "failed"],
        "rows": rows,
    }
    print(f"{len(rows)} fits in {result['seconds']} s")
    print(f"error < {GOOD_M} m: {len(good)} fits, ok {100 * result['good_ok_share']:.1f} %")
    print(f"error > {BAD_M} m: {len(bad)} fits, failed or doubtful "
          f"{100 * result['bad_flagged_share']:.1f} %")
    print(f"NEES of theta over {len(nees)} joint fits under {GOOD_M} m: mean "
          f"{result['nees_mean']}, median {result['nees_median']}, in the chi-square(7) 95 % "
          f"band {100 * result['nees_in_chi2_95_band']:.1f} %")
    print(f"evidence-free heat-maps: {result['evidence_free_failed']} of {len(free)} failed")
    for r in result["good_not_ok"] + result["bad_ok"]:
        print(f"  {r['study']:9s} {r['config']:28s} flight {r['flight']:3d} "
              f"{r['position_m']:7.3f} m {r['verdict']:8s} {r['reasons']}")
    write_json(RESULTS / "bench_verdict.json", result)


if __name__ == "__main__":
    main()
