"""Latency and accuracy benchmark of ``turbinefit track`` (the figures of issue #4).

Runs the real command line ``turbinefit track FLIGHT --out OUT --no-plots --quiet`` (and
``turbinefit fit`` for the batch reference) in fresh processes on simulated flight folders
(320x240 heat-maps, default preset; cached in ``benchmarks/data/``):

* latency: a 1000-keyframe flight (seed 0) with the default window, and with windows of
  10 and 40; per-keyframe update time (median, 99th percentile, max) and the slope of a
  least-squares line through it against the keyframe index, over the whole flight and
  once the window is full; the accuracy of the same runs against the batch fit;
* accuracy: 200-keyframe flights, seeds 0-7: the tracker's final estimates (default
  window, no batch pass), its causal estimates (each keyframe on arrival) and its final
  estimates without back-substitution, against the batch fit of the same flight;
* the same with ``--marginal-terms same`` (keyframes leaving the window linearised with
  the configured cost instead of as correspondences);
* the unbounded window (``--window 0``) on the 200-keyframe flight of seed 0: its result
  against the batch fit, and how its latency grows.

Usage::

    python benchmarks/bench_track.py [--seeds 0 1 ...] [--windows 10 20 40]

Prints tables, writes ``benchmarks/results/bench_track.json`` and the latency plot
``benchmarks/results/track_latency.png``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from common import BIN, DATA, RAN, RESULTS, run_command, simulate, warm, write_json

#: the issue's latency budget [ms]: median and 99th percentile
BUDGET_MEDIAN_MS, BUDGET_P99_MS = 30.0, 100.0


def run(command: str, flight: Path, extra: list[str] | None = None) -> dict:
    """Run ``turbinefit COMMAND FLIGHT --out OUT`` in a child process; return its wall time,
    its summary and (for track) its latency column."""
    with tempfile.TemporaryDirectory(dir=DATA) as tmp:
        out = Path(tmp) / command
        cmd = [str(BIN), command, str(flight), "--out", str(out), "--no-plots", "--quiet",
               *(extra or [])]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode not in RAN:
            raise RuntimeError(f"{' '.join(cmd)} failed: {proc.stderr.strip()}")
        summary = json.loads((out / "summary.json").read_text())
        latency = None
        if command == "track":
            rows = (out / "latency.csv").read_text().splitlines()[1:]
            latency = [float(r.split(",")[1]) for r in rows]
    return {"wall_s": wall, "summary": summary, "latency_ms": latency}


def errors(summary: dict, key: str) -> dict:
    a = summary["accuracy"][key]
    return {"position_m": a["position_error_m"], "orientation_deg": a["orientation_error_deg"],
            "model_points_m": a["model_point_error_m"]}


def track_row(res: dict, batch: dict) -> dict:
    s = res["summary"]
    b = errors(batch["summary"], "after")
    row = {"wall_s": round(res["wall_s"], 2), "latency": s["latency"],
           "iterations_mean": s["iterations_mean"]}
    for key in ("final", "causal", "final_without_back_substitution"):
        e = errors(s, key)
        e["position_ratio_to_batch"] = e["position_m"] / b["position_m"]
        e["orientation_ratio_to_batch"] = e["orientation_deg"] / b["orientation_deg"]
        row[key] = e
    row["batch"] = b
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keyframes", type=int, default=1000, help="latency flight length")
    ap.add_argument("--windows", type=int, nargs="+", default=[10, 20, 40])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(8)))
    ap.add_argument("--accuracy-keyframes", type=int, default=200)
    ap.add_argument("--out", type=Path, default=RESULTS / "bench_track.json")
    args = ap.parse_args()
    DATA.mkdir(exist_ok=True)
    RESULTS.mkdir(exist_ok=True)
    from turbinefit.solver.tracker import TrackerConfig

    default_window = TrackerConfig().window
    result: dict = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                                "python": platform.python_version()},
                    "default_window": default_window}

    # ---- latency on the long flight -------------------------------------------------
    long_flight = simulate(args.keyframes, 0)
    warm(long_flight)
    batch_long = run("fit", long_flight)
    print(f"{args.keyframes} keyframes, batch fit: {batch_long['wall_s']:.2f} s, position "
          f"{errors(batch_long['summary'], 'after')['position_m']:.3f} m")
    lat_rows = {}
    default_latency = None
    print(f"\n{'window':>6} {'median':>8} {'p99':>8} {'max':>8} {'slope':>8} {'steady':>8}"
          f" {'final':>7} {'ratio':>6} {'causal':>7}   (ms; slopes in ms per 1000 keyframes;"
          f" position errors in m)")
    runs = [(str(w), ["--window", str(w)]) for w in args.windows]
    runs.append((f"{default_window}-same", ["--marginal-terms", "same"]))
    for name, extra in runs:
        res = run("track", long_flight, extra)
        row = track_row(res, batch_long)
        lat_rows[name] = row
        lat = row["latency"]
        print(f"{name:>6} {lat['median_ms']:8.1f} {lat['p99_ms']:8.1f} {lat['max_ms']:8.1f} "
              f"{lat['slope_ms_per_1000_keyframes']:+8.2f} "
              f"{lat.get('steady_slope_ms_per_1000_keyframes', 0.0):+8.2f} "
              f"{row['final']['position_m']:7.3f} {row['final']['position_ratio_to_batch']:6.2f} "
              f"{row['causal']['position_m']:7.3f}")
        if name == str(default_window):
            default_latency = res["latency_ms"]
    result["latency"] = {"keyframes": args.keyframes, "by_window": lat_rows,
                         "batch": {"wall_s": round(batch_long["wall_s"], 2),
                                   **errors(batch_long["summary"], "after")}}
    if default_latency is not None:
        from turbinefit.plots import plot_latency

        plot_latency(RESULTS / "track_latency.png", np.array(default_latency),
                     budget_ms=BUDGET_MEDIAN_MS)
        lat = lat_rows[str(default_window)]["latency"]
        ok = lat["median_ms"] < BUDGET_MEDIAN_MS and lat["p99_ms"] < BUDGET_P99_MS
        print(f"default window {default_window}: median {lat['median_ms']:.1f} ms "
              f"(< {BUDGET_MEDIAN_MS:g}), p99 {lat['p99_ms']:.1f} ms (< {BUDGET_P99_MS:g}): "
              f"{'met' if ok else 'NOT met'}")

    # ---- accuracy on 200-keyframe flights -------------------------------------------
    n = args.accuracy_keyframes
    print(f"\n{n} keyframes, default window {default_window}: position error [m] "
          f"(ratio to batch)")
    print(f"{'seed':>4} {'batch':>7} {'final':>14} {'causal':>14} {'no back-sub.':>14}"
          f" {'marg. same':>14} {'orient. batch/final [deg]':>26}")
    acc_rows = {}
    for seed in args.seeds:
        flight = simulate(n, seed)
        batch = run("fit", flight)
        row = track_row(run("track", flight), batch)
        same = track_row(run("track", flight, ["--marginal-terms", "same"]), batch)
        row["marginal_terms_same"] = same["final"]
        acc_rows[str(seed)] = row
        print(f"{seed:4d} {row['batch']['position_m']:7.3f} "
              + " ".join(f"{row[k]['position_m']:7.3f} ({row[k]['position_ratio_to_batch']:.2f})"
                         for k in ("final", "causal", "final_without_back_substitution",
                                   "marginal_terms_same"))
              + f" {row['batch']['orientation_deg']:12.3f} / {row['final']['orientation_deg']:.3f}")
    means = {k: statistics.mean(r[k]["position_m"] for r in acc_rows.values())
             for k in ("batch", "final", "causal", "final_without_back_substitution",
                       "marginal_terms_same")}
    ratios = [r["final"]["position_ratio_to_batch"] for r in acc_rows.values()]
    print(f"mean {means['batch']:7.3f} {means['final']:7.3f} ({means['final'] / means['batch']:.2f})"
          f" {means['causal']:7.3f} ({means['causal'] / means['batch']:.2f}) "
          f"{means['final_without_back_substitution']:7.3f} "
          f"({means['final_without_back_substitution'] / means['batch']:.2f}) "
          f"{means['marginal_terms_same']:7.3f} "
          f"({means['marginal_terms_same'] / means['batch']:.2f}); per-flight "
          f"ratio of final to batch: max {max(ratios):.2f}, {sum(r <= 1.1 for r in ratios)} of "
          f"{len(ratios)} within 1.10")
    result["accuracy"] = {"keyframes": n, "by_seed": acc_rows, "mean_position_m": means,
                          "mean_ratio_final_to_batch": means["final"] / means["batch"],
                          "max_flight_ratio_final_to_batch": max(ratios)}

    # ---- unbounded window -----------------------------------------------------------
    flight = simulate(n, args.seeds[0])
    batch = run("fit", flight)
    res = run("track", flight, ["--window", "0"])
    row = track_row(res, batch)
    with tempfile.TemporaryDirectory(dir=DATA) as tmp:
        from turbinefit.io import read_tum

        run_command(["track", str(flight), "--out", f"{tmp}/t", "--window", "0", "--no-prior",
                     "--no-plots", "--quiet"])
        run_command(["fit", str(flight), "--out", f"{tmp}/f", "--no-plots", "--quiet"])
        _, pt = read_tum(f"{tmp}/t/keyframes.txt")
        _, pb = read_tum(f"{tmp}/f/keyframes.txt")
        diff = np.linalg.norm(pt.translation - pb.translation, axis=-1)
    row["no_prior_position_difference_to_batch_m"] = {"mean": float(diff.mean()),
                                                      "max": float(diff.max())}
    result["unbounded"] = {"keyframes": n, "seed": args.seeds[0], **row}
    lat = row["latency"]
    print(f"\nunbounded window, {n} keyframes (seed {args.seeds[0]}): final "
          f"{row['final']['position_m']:.3f} m vs batch {row['batch']['position_m']:.3f} m; "
          f"without the start-up prior its poses differ from the batch fit's by "
          f"{diff.mean() * 100:.1f} cm on average (max {diff.max() * 100:.1f} cm); latency "
          f"median {lat['median_ms']:.1f} ms, growing {lat['slope_ms_per_1000_keyframes']:+.0f} "
          f"ms per 1000 keyframes")

    write_json(args.out, result)
    print(f"\nwrote {args.out} and {RESULTS / 'track_latency.png'}")


if __name__ == "__main__":
    main()
