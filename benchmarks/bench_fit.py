"""Accuracy and speed benchmark of ``turbinefit fit`` (the figures of issue #2).

Simulates flight folders of 50, 200 and 1000 keyframes (320x240 heat-maps; cached in
``benchmarks/data/``), then runs the real command line ``turbinefit fit FLIGHT --out OUT
--no-plots`` on each in a fresh process, measuring wall time from process start to exit,
peak memory (max RSS), and the load and solve times the command reports. Accuracy: joint
vs pose-only on the 200-keyframe flights (several seeds).

Usage::

    python benchmarks/bench_fit.py [--sizes 50 200 1000] [--repeat 3] [--seeds 0 1 2]

Prints a table and writes ``benchmarks/results/bench_fit.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
RESULTS = HERE / "results"
BIN = Path(sys.executable).parent / "turbinefit"


def simulate(n: int, seed: int) -> Path:
    out = DATA / f"flight_n{n}_s{seed}"
    if not (out / "keyframes.txt").exists():
        subprocess.run([str(BIN), "simulate", str(out), "--keyframes", str(n), "--seed",
                        str(seed), "--overwrite", "--quiet"], check=True)
    return out


def run_fit(flight: Path, extra: list[str] | None = None) -> dict:
    """Run `turbinefit fit` in a child process; return wall time, peak RSS and the summary."""
    with tempfile.TemporaryDirectory(dir=DATA) as tmp:
        out = Path(tmp) / "fit"
        cmd = [str(BIN), "fit", str(flight), "--out", str(out), "--no-plots", *(extra or [])]
        log = Path(tmp) / "stderr.txt"
        with open(log, "w") as err:
            t0 = time.perf_counter()
            proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
            _, status, usage = os.wait4(proc.pid, 0)  # this child's own peak memory
            wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        peak_kb = usage.ru_maxrss
        if proc.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed: {log.read_text().strip()}")
        summary = json.loads((out / "summary.json").read_text())
    return {"wall_s": wall, "peak_rss_mb": peak_kb / 1024.0, "summary": summary}


def warm(flight: Path) -> None:
    """Read every file once so that all runs see the page cache (as after `simulate`)."""
    for p in flight.rglob("*"):
        if p.is_file():
            with open(p, "rb") as f:
                while f.read(1 << 24):
                    pass


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[50, 200, 1000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--out", type=Path, default=RESULTS / "bench_fit.json")
    args = ap.parse_args()
    DATA.mkdir(parents=True, exist_ok=True)
    RESULTS.mkdir(parents=True, exist_ok=True)
    if shutil.which(str(BIN)) is None:
        sys.exit(f"{BIN} not found: run inside the project's virtual environment")

    speed = []
    print("== speed: turbinefit fit FLIGHT --out OUT --no-plots (joint, defaults) ==")
    print(f"{'N':>6} {'wall s':>8} {'load s':>8} {'solve s':>8} {'iters':>6} "
          f"{'residuals':>10} {'peak MB':>8}")
    for n in args.sizes:
        flight = simulate(n, 0)
        warm(flight)
        runs = [run_fit(flight) for _ in range(args.repeat)]
        walls = [r["wall_s"] for r in runs]
        best = runs[walls.index(min(walls))]
        s = best["summary"]
        row = {
            "keyframes": n,
            "wall_s_min": min(walls), "wall_s_median": statistics.median(walls),
            "load_s": s["timing_s"]["load"], "solve_s": s["timing_s"]["solve"],
            "write_s": s["timing_s"]["write"],
            "iterations": s["solver"]["iterations"], "rounds": s["solver"]["rounds"],
            "num_residuals": s["solver"]["num_residuals"],
            "peak_rss_mb": max(r["peak_rss_mb"] for r in runs),
        }
        speed.append(row)
        print(f"{n:>6} {row['wall_s_min']:>8.2f} {row['load_s']:>8.2f} {row['solve_s']:>8.2f} "
              f"{row['iterations']:>6} {row['num_residuals']:>10} {row['peak_rss_mb']:>8.0f}")

    print("\n== accuracy: 200 keyframes, joint vs pose-only ==")
    acc = []
    for seed in args.seeds:
        flight = simulate(200, seed)
        for mode in ("joint", "pose"):
            r = run_fit(flight, ["--mode", mode])
            a = r["summary"]["accuracy"]
            b, f = a["before"], a["after"]
            row = {
                "seed": seed, "mode": mode,
                "position_m": [b["position_error_m"], f["position_error_m"]],
                "orientation_deg": [b["orientation_error_deg"], f["orientation_error_deg"]],
                "model_point_m": [b["model_point_error_m"], f["model_point_error_m"]],
                "model_point_ratio": f["model_point_error_m"] / max(b["model_point_error_m"], 1e-12),
            }
            acc.append(row)
            print(f"seed {seed} {mode:>5}: position {b['position_error_m']:.3f} -> "
                  f"{f['position_error_m']:.3f} m, orientation {b['orientation_error_deg']:.3f} -> "
                  f"{f['orientation_error_deg']:.3f} deg, model points "
                  f"{b['model_point_error_m']:.3f} -> {f['model_point_error_m']:.3f} m "
                  f"({100 * row['model_point_ratio']:.1f} %)")

    result = {
        "benchmark": "bench_fit",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "platform": platform.platform()},
        "speed": speed,
        "accuracy": acc,
    }
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(json.dumps(result, indent=2) + "\n")
    os.replace(tmp, args.out)
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
