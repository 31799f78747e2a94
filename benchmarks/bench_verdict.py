"""How well the verdict of a fit and of a track (:mod:`turbinefit.solver.verdict`)
separates good results from bad ones, and whether theta's covariance is honest.

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
  every fit must end ``failed``;
* ``--track``: the in-flight tracker (default window, the study's options) on the same
  flights (joint configurations) and evidence-free heat-maps: the same shares and NEES,
  with theta's covariance as the verdict takes it (the batch fit's rule,
  :meth:`~turbinefit.solver.tracker.Tracker.theta_covariance`) and, for comparison, as
  the last update's posterior with the start-up prior (what the verdict used before);
* ``--lengths 1 2 3 5 20 200``: ``turbinefit fit`` and ``turbinefit track`` (the job
  functions, heat-map files' defaults) on default simulated flights of those lengths
  (``--seeds``, cached in ``benchmarks/data/``): how often their verdicts agree, and the
  NEES of each (with the track's before-figures as above); ``--no-studies`` runs only
  this.

Usage::

    python benchmarks/bench_verdict.py [--flights 12] [--keyframes 60] [--workers 2]
    python benchmarks/bench_verdict.py --track --lengths 1 2 3 5 20 200 --seeds 10

Prints tables and writes ``benchmarks/results/bench_verdict.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import platform
import tempfile
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from common import DATA, RESULTS, simulate, write_json

from turbinefit.eval.metrics import accuracy
from turbinefit.experiments.studies import STUDIES, study_config
from turbinefit.experiments.sweep import SweepConfig, _sim_config, fit_config, flight_specs
from turbinefit.flight import Flight
from turbinefit.heatmaps import HeatmapStack
from turbinefit.io.flight_folder import read_flight_folder
from turbinefit.jobs.fit import fit_folder
from turbinefit.jobs.track import track_folder
from turbinefit.sim.scenario import SimConfig, simulate_flight
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import fit
from turbinefit.solver.tracker import Tracker, TrackerConfig
from turbinefit.solver.verdict import ImageEvidence, Signals, judge
from turbinefit.turbine.model import TurbineParams, param_errors

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


def nees(estimate: TurbineParams, truth: TurbineParams, cov: np.ndarray | None
         ) -> float | None:
    """``e^T cov^-1 e`` of theta's error ``e`` (None without a covariance)."""
    if cov is None:
        return None
    e = param_errors(estimate, truth)
    try:
        return float(e @ np.linalg.solve(cov, e))
    except np.linalg.LinAlgError:
        return None


def posterior_verdict(signals: Signals, posterior: np.ndarray | None) -> str:
    """The verdict the tracker got before its covariance followed the fit's rule: the same
    signals with the standard deviations of the last update's posterior (start-up prior
    included), without theta's distance from the optimum."""
    std = None if posterior is None else np.sqrt(np.maximum(np.diag(posterior), 0.0))
    return judge(dataclasses.replace(signals, theta_std=std, theta_step_sigmas=None))[0]


def track_flight(flight: Flight, fc: FitConfig) -> dict[str, Any]:
    """The tracker (default window) over ``flight`` with fit options ``fc``, judged as
    ``turbinefit track`` judges it."""
    tracker = Tracker(flight.camera, flight.turbine, TrackerConfig(fit=fc))
    odo = flight.odometry
    image: list[ImageEvidence] = []
    for k in range(flight.num_keyframes):
        tracker.update(float(flight.timestamps[k]), flight.world_T_cam[k], flight.heatmaps[k],
                       odometry=None if odo is None else odo[k])
        image.append(tracker.arrival_evidence())
    a = tracker.assess(ImageEvidence.concat(image), flight.world_T_cam,
                       flight.measurement_poses())
    post = tracker.estimates[-1].theta_covariance
    row: dict[str, Any] = {"verdict": a.verdict, "reasons": a.reasons,
                           "verdict_posterior": posterior_verdict(a.signals, post),
                           "prior_active_at_end": tracker.theta_prior_active,
                           "signals": a.signals.to_dict()}
    if flight.gt_world_T_cam is not None and flight.gt_turbine is not None:
        acc = accuracy(tracker.world_T_cam(), tracker.turbine, flight.gt_world_T_cam,
                       flight.gt_turbine, fc.geometry)
        row.update(position_m=acc.position_error_m,
                   nees=nees(tracker.turbine, flight.gt_turbine, a.theta_covariance),
                   nees_posterior=nees(tracker.turbine, flight.gt_turbine, post))
    return row


def run_one(task: tuple[str, SweepConfig, Any, bool]) -> list[dict[str, Any]]:
    study, cfg, spec, with_track = task
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
        sig = res.signals.to_dict() if res.signals is not None else {}
        row = {"study": study, "config": name, "flight": spec.index,
               "keyframes": spec.keyframes, "mode": fc.mode,
               "position_m": acc.position_error_m, "verdict": res.verdict,
               "reasons": res.reasons,
               "nees": nees(res.turbine, flight.gt_turbine, res.theta_covariance),
               "signals": sig}
        if with_track and fc.mode == "joint":
            row["track"] = track_flight(flight, fc)
        rows.append(row)
    return rows


def evidence_free(n: int, keyframes: int, with_track: bool = False) -> list[dict[str, Any]]:
    rows = []
    for seed in range(n):
        flight = simulate_flight(SimConfig(n_keyframes=keyframes, seed=seed))
        shape = (flight.num_keyframes, 7, flight.camera.height, flight.camera.width)
        for value in (0.0, 1.0, 0.3):
            f2 = dataclasses.replace(flight, heatmaps=HeatmapStack(np.full(shape, value,
                                                                           np.float32)))
            for cname, fc in (("cli-defaults", CLI_DEFAULTS), ("paper-best", FitConfig())):
                res = fit(f2, fc)
                row = {"seed": seed, "value": value, "config": cname,
                       "verdict": res.verdict, "reasons": res.reasons}
                if with_track:
                    row["track_verdict"] = track_flight(f2, fc)["verdict"]
                rows.append(row)
    return rows


def run_length(task: tuple[int, int]) -> dict[str, Any]:
    """``fit`` and ``track`` (the job functions, default options) on the default simulated
    flight of ``n`` keyframes and ``seed``."""
    n, seed = task
    folder = simulate(n, seed)
    gt = read_flight_folder(folder).gt_turbine
    assert gt is not None
    with tempfile.TemporaryDirectory(dir=DATA) as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fr = fit_folder(folder, Path(tmp) / "fit", plots=False)
        tr = track_folder(folder, Path(tmp) / "track", plots=False)
    assert fr.after is not None and tr.final is not None and tr.summary.signals is not None
    post = tr.estimates[-1].theta_covariance
    return {"keyframes": n, "seed": seed,
            "fit": {"verdict": fr.result.verdict, "reasons": fr.result.reasons,
                    "position_m": fr.after.position_error_m,
                    "nees": nees(fr.result.turbine, gt, fr.result.theta_covariance),
                    "theta_step_sigmas": fr.result.signals.theta_step_sigmas
                    if fr.result.signals is not None else None},
            "track": {"verdict": tr.summary.verdict, "reasons": tr.summary.reasons,
                      "verdict_posterior": posterior_verdict(tr.summary.signals, post),
                      "position_m": tr.final.position_error_m,
                      "nees": nees(tr.turbine, gt, tr.theta_covariance),
                      "nees_posterior": nees(tr.turbine, gt, post),
                      "theta_step_sigmas": tr.summary.signals.theta_step_sigmas}}


def nees_stats(values: list[float | None]) -> dict[str, Any]:
    """Count, mean, median and share inside the chi-square(7) 95 % band of NEES values
    (None: no covariance, left out and counted)."""
    v = [x for x in values if x is not None]
    return {"n": len(v), "without_covariance": len(values) - len(v),
            "mean": float(np.mean(v)) if v else None,
            "median": float(np.median(v)) if v else None,
            "in_chi2_95_band": (sum(CHI2_7_BAND[0] <= x <= CHI2_7_BAND[1] for x in v)
                                / len(v)) if v else None,
            "above_band": sum(x > CHI2_7_BAND[1] for x in v) / len(v) if v else None}


def lengths_table(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per flight length: verdict counts of fit and track, their agreement and NEES."""
    out: dict[str, Any] = {}
    for n in sorted({r["keyframes"] for r in rows}):
        part = [r for r in rows if r["keyframes"] == n]
        count = {who: {v: sum(r[who][k] == v for r in part) for v in ("ok", "doubtful", "failed")}
                 for who, k in (("fit", "verdict"), ("track", "verdict"))}
        count["track_posterior"] = {v: sum(r["track"]["verdict_posterior"] == v for r in part)
                                    for v in ("ok", "doubtful", "failed")}
        out[str(n)] = {
            "flights": len(part), "verdicts": count,
            "agree": sum(r["fit"]["verdict"] == r["track"]["verdict"] for r in part),
            "agree_posterior": sum(r["fit"]["verdict"] == r["track"]["verdict_posterior"]
                                   for r in part),
            "track_ok_where_fit_not": sum(r["track"]["verdict"] == "ok" != r["fit"]["verdict"]
                                          for r in part),
            "nees_fit": nees_stats([r["fit"]["nees"] for r in part]),
            "nees_track": nees_stats([r["track"]["nees"] for r in part]),
            "nees_track_posterior": nees_stats([r["track"]["nees_posterior"] for r in part])}
    return out


def print_lengths(table: dict[str, Any]) -> None:
    print("keyframes  fit ok/doubtful/failed  track ok/doubtful/failed  agree  "
          "(posterior)  NEES mean fit / track / (posterior)")

    def m(s: dict[str, Any]) -> str:
        return "-" if s["mean"] is None else f"{s['mean']:.3g}"

    for n, t in table.items():
        v = t["verdicts"]
        print(f"{n:>9s}  {v['fit']['ok']:2d} / {v['fit']['doubtful']:2d} / {v['fit']['failed']:2d}"
              f"            {v['track']['ok']:2d} / {v['track']['doubtful']:2d} / "
              f"{v['track']['failed']:2d}              {t['agree']:2d}/{t['flights']:2d}  "
              f"({t['agree_posterior']:2d})        {m(t['nees_fit'])} / {m(t['nees_track'])} "
              f"/ ({m(t['nees_track_posterior'])})")


def verdict_shares(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Of ``rows`` (position_m, verdict, nees, mode): the share of those under
    :data:`GOOD_M` that are ``ok``, of those over :data:`BAD_M` that are not, and the NEES
    of the joint ones under :data:`GOOD_M`."""
    good = [r for r in rows if r["position_m"] < GOOD_M]
    bad = [r for r in rows if r["position_m"] > BAD_M]
    steps = [r["signals"].get("theta_step_sigmas") for r in good if r.get("signals")]
    return {"good": len(good), "good_ok_share": sum(r["verdict"] == "ok" for r in good)
            / max(len(good), 1),
            "good_max_theta_step_sigmas": max((x for x in steps if x is not None),
                                              default=None),
            "bad": len(bad), "bad_flagged_share": sum(r["verdict"] != "ok" for r in bad)
            / max(len(bad), 1),
            "nees": nees_stats([r["nees"] for r in good if r.get("mode", "joint") == "joint"])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flights", type=int, default=12, help="flights per study (default 12)")
    ap.add_argument("--keyframes", type=int, default=60, help="keyframes per flight")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--studies", nargs="*", default=list(STUDIES))
    ap.add_argument("--evidence-free-flights", type=int, default=2)
    ap.add_argument("--track", action="store_true",
                    help="also run the tracker on the studies' flights (joint configurations)")
    ap.add_argument("--lengths", type=int, nargs="*", default=[],
                    help="fit and track default simulated flights of these many keyframes")
    ap.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 of --lengths")
    ap.add_argument("--no-studies", action="store_true", help="only --lengths")
    args = ap.parse_args()
    t0 = time.perf_counter()
    result: dict[str, Any] = {"machine": platform.platform()}
    if args.lengths:
        tasks_n = [(n, s) for n in args.lengths for s in range(args.seeds)]
        for n in args.lengths:  # simulate each folder once, before the workers share them
            for s in range(args.seeds):
                simulate(n, s)
        with ProcessPoolExecutor(args.workers) as pool:
            lrows = list(pool.map(run_length, tasks_n))
        table = lengths_table(lrows)
        result["lengths"] = {"seeds": args.seeds, "table": table, "rows": lrows}
        print_lengths(table)
    if not args.no_studies:
        result.update(studies(args))
    result["seconds"] = round(time.perf_counter() - t0, 1)
    write_json(RESULTS / "bench_verdict.json", result)


def studies(args: argparse.Namespace) -> dict[str, Any]:
    """The studies' flights and the evidence-free heat-maps (see the module docstring)."""
    t0 = time.perf_counter()
    tasks = []
    for study in args.studies:
        cfg = study_config(study, flights=args.flights, keyframes=args.keyframes)
        if cfg.keyframes_max is not None:  # the length study: keep it short
            cfg = dataclasses.replace(cfg, keyframes_max=min(cfg.keyframes_max, 200))
        tasks += [(study, cfg, s, args.track) for s in flight_specs(cfg)]
    hard = hard_config(args.flights * 2, args.keyframes)
    tasks += [("hard", hard, s, args.track) for s in flight_specs(hard)]
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(args.workers) as pool:
        for part in pool.map(run_one, tasks):
            rows += part
    free = evidence_free(args.evidence_free_flights, args.keyframes, args.track)

    good = [r for r in rows if r["position_m"] < GOOD_M]
    bad = [r for r in rows if r["position_m"] > BAD_M]
    fits = verdict_shares(rows)
    result = {
        "flights_per_study": args.flights,
        "keyframes": args.keyframes, "fits": len(rows),
        "studies_seconds": round(time.perf_counter() - t0, 1),
        "good_flights": fits["good"], "good_ok_share": fits["good_ok_share"],
        "bad_flights": fits["bad"], "bad_flagged_share": fits["bad_flagged_share"],
        "nees_flights": fits["nees"]["n"], "nees_mean": fits["nees"]["mean"],
        "nees_median": fits["nees"]["median"],
        "nees_in_chi2_95_band": fits["nees"]["in_chi2_95_band"],
        "good_max_theta_step_sigmas": fits["good_max_theta_step_sigmas"],
        "evidence_free_fits": len(free),
        "evidence_free_failed": sum(r["verdict"] == "failed" for r in free),
        "good_not_ok": [r for r in good if r["verdict"] != "ok"],
        "bad_ok": [r for r in bad if r["verdict"] == "ok"],
        "evidence_free_not_failed": [r for r in free if r["verdict"] != "failed"],
        "rows": rows,
    }
    print(f"{len(rows)} fits in {result['studies_seconds']} s")
    print(f"error < {GOOD_M} m: {len(good)} fits, ok {100 * result['good_ok_share']:.1f} %")
    print(f"error > {BAD_M} m: {len(bad)} fits, failed or doubtful "
          f"{100 * result['bad_flagged_share']:.1f} %")
    print(f"NEES of theta over {result['nees_flights']} joint fits under {GOOD_M} m: mean "
          f"{result['nees_mean']}, median {result['nees_median']}, in the chi-square(7) 95 % "
          f"band {100 * (result['nees_in_chi2_95_band'] or 0.0):.1f} %")
    print(f"evidence-free heat-maps: {result['evidence_free_failed']} of {len(free)} failed")
    print(f"theta's distance from the optimum, fits under {GOOD_M} m: at most "
          f"{result['good_max_theta_step_sigmas']} sigma")
    for r in result["good_not_ok"] + result["bad_ok"]:
        print(f"  {r['study']:9s} {r['config']:28s} flight {r['flight']:3d} "
              f"{r['position_m']:7.3f} m {r['verdict']:8s} {r['reasons']}")
    if args.track:
        tracked = [r for r in rows if "track" in r]
        trows = [{**r["track"], "mode": "joint"} for r in tracked]
        post = [{**t, "verdict": t["verdict_posterior"], "nees": t["nees_posterior"]}
                for t in trows]
        result["track"] = {
            "tracks": len(trows), "rule": verdict_shares(trows),
            "posterior": verdict_shares(post),
            "agree_with_fit": sum(r["track"]["verdict"] == r["verdict"] for r in tracked)
            / max(len(tracked), 1),
            "ok_where_fit_not": sum(r["track"]["verdict"] == "ok" != r["verdict"]
                                    for r in tracked),
            "evidence_free_failed": sum(r["track_verdict"] == "failed" for r in free),
        }
        t = result["track"]
        for key, what in (("rule", "the fit's rule"), ("posterior", "last update's posterior")):
            s = t[key]
            print(f"track ({what}): error < {GOOD_M} m: {s['good']}, ok "
                  f"{100 * s['good_ok_share']:.1f} %; > {BAD_M} m: {s['bad']}, flagged "
                  f"{100 * s['bad_flagged_share']:.1f} %; NEES over {s['nees']['n']}: mean "
                  f"{s['nees']['mean']}, median {s['nees']['median']}, in band "
                  f"{100 * (s['nees']['in_chi2_95_band'] or 0.0):.1f} %; distance from the "
                  f"optimum at most {s['good_max_theta_step_sigmas']} sigma")
        print(f"track verdict = fit verdict on {100 * t['agree_with_fit']:.1f} % of "
              f"{len(tracked)} flights; track ok where fit not: {t['ok_where_fit_not']}; "
              f"evidence-free: {t['evidence_free_failed']} of {len(free)} tracks failed")
    return result


if __name__ == "__main__":
    main()
