"""Accuracy of ``turbinefit fit`` on the two kinds of pose measurements (issue #27):
GPS/IMU keyframes (``simulate --odometry gps``, no odometry.txt) and body-frame odometry
(``simulate --odometry vio``: noisy relative motions chained from the first pose, in
odometry.txt and keyframes.txt).

Each flight (200 keyframes, default preset, seeds 0-7; cached in ``benchmarks/data/``) is
fitted by the real command line ``turbinefit fit FLIGHT --out OUT --no-plots`` under:

* ``default``: no options (``--pair-frame auto``: estimated with odometry.txt, measured
  without);
* ``paper``: the paper's residual and configuration, ``--pair-frame estimated --preset
  paper-best``;
* ``measured``: ``--pair-frame measured``;
* ``corr-normal``: ``--preset corr-normal`` (pair frame auto).

Usage::

    python benchmarks/bench_odometry.py [--seeds 0 1 ...] [--keyframes 200]

Prints the mean position / orientation / model-point errors per configuration and flight
kind and writes ``benchmarks/results/bench_odometry.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

from common import DATA, RESULTS, run_command, simulate, write_json

#: configuration name -> extra command-line options of `turbinefit fit`
CONFIGS = {
    "default": [],
    "paper": ["--pair-frame", "estimated", "--preset", "paper-best"],
    "measured": ["--pair-frame", "measured"],
    "corr-normal": ["--preset", "corr-normal"],
}
KINDS = ("gps", "vio")
METRICS = ("position_error_m", "orientation_error_deg", "model_point_error_m")


def run_fit(flight: Path, extra: list[str]) -> dict:
    """`turbinefit fit` in a child process: the errors after the fit and the pair frame used."""
    with tempfile.TemporaryDirectory(dir=DATA) as tmp:
        out = Path(tmp) / "fit"
        run_command(["fit", str(flight), "--out", str(out), "--no-plots", "--quiet", *extra])
        summary = json.loads((out / "summary.json").read_text())
    after = summary["accuracy"]["after"]
    return {**{m: after[m] for m in METRICS}, "pair_frame": summary["config"]["pair_frame"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(8)))
    ap.add_argument("--keyframes", type=int, default=200)
    args = ap.parse_args()
    runs: dict[str, dict[str, list[dict]]] = {k: {c: [] for c in CONFIGS} for k in KINDS}
    for kind in KINDS:
        for seed in args.seeds:
            flight = simulate(args.keyframes, seed, kind)
            for name, extra in CONFIGS.items():
                r = run_fit(flight, extra)
                runs[kind][name].append({"seed": seed, **r})
                print(f"{kind} seed {seed} {name:12s} ({r['pair_frame']}): position "
                      f"{r['position_error_m']:.3f} m, orientation "
                      f"{r['orientation_error_deg']:.3f} deg, model points "
                      f"{r['model_point_error_m']:.3f} m", flush=True)
    means = {kind: {name: {m: statistics.fmean(r[m] for r in rs) for m in METRICS}
                    for name, rs in by.items()} for kind, by in runs.items()}
    print(f"\nmean errors, {args.keyframes} keyframes, seeds "
          f"{' '.join(map(str, args.seeds))}")
    print(f"{'flights':8s} {'configuration':14s} {'pair frame':10s} {'position m':>10s} "
          f"{'orient. deg':>11s} {'model pts m':>11s}")
    for kind in KINDS:
        for name in CONFIGS:
            m = means[kind][name]
            print(f"{kind:8s} {name:14s} {runs[kind][name][0]['pair_frame']:10s} "
                  f"{m['position_error_m']:10.3f} {m['orientation_error_deg']:11.3f} "
                  f"{m['model_point_error_m']:11.3f}")
    write_json(RESULTS / "bench_odometry.json", {
        "keyframes": args.keyframes, "seeds": args.seeds,
        "configs": {n: " ".join(e) for n, e in CONFIGS.items()},
        "mean": means, "runs": runs})


if __name__ == "__main__":
    main()
