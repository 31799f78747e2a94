"""Accuracy and speed benchmark of ``turbinefit fit`` (the figures of issue #2).

Simulates flight folders (320x240 heat-maps, default preset; cached in
``benchmarks/data/``) and runs the real command line ``turbinefit fit FLIGHT --out OUT
--no-plots`` on each in a fresh process, as a new user would (bytecode caches as after
``pip install``: ``PYTHONDONTWRITEBYTECODE`` is dropped, and one run warms them and the
page cache first), measuring wall time from process start to exit and peak memory (max
RSS of the process: the pages of the heat-map files it maps count), with the load and
solve times the command reports.

* speed: 50, 200 and 1000 keyframes (seed 0), ``--repeat`` runs each (min and median),
  plus one run of the numpy reference implementation (``TURBINEFIT_NATIVE=0``); at 1000
  keyframes also the same flight with float32 heat-map files (as other tools write
  them: twice the bytes), on both cores, on one core (the figure a busy machine changes
  least) and with the figures (no ``--no-plots``);
* accuracy: 200 keyframes, seeds 0-7, in joint mode (the defaults), pose-only mode, and
  joint mode with the paper's pairwise frame (``--pair-frame estimated``).

Usage::

    python benchmarks/bench_fit.py [--sizes 50 200 1000] [--repeat 3] [--seeds 0 1 ...]

Prints tables and writes ``benchmarks/results/bench_fit.json``.
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

import numpy as np
from common import BIN, DATA, RAN, RESULTS, simulate, warm, write_json

#: accuracy configurations: name -> extra command-line options
MODES = {
    "joint": [],
    "pose-only": ["--mode", "pose"],
    "joint, paper's pairwise frame": ["--pair-frame", "estimated"],
}


def run_fit(flight: Path, extra: list[str] | None = None,
            env: dict[str, str] | None = None, plots: bool = False,
            cores: int | None = None) -> dict:
    """Run `turbinefit fit` in a child process (``cores``: on that many processors only);
    return wall time, peak RSS and the summary."""
    child_env = {**os.environ, **(env or {})}
    child_env.pop("PYTHONDONTWRITEBYTECODE", None)  # a new user's install has .pyc files
    with tempfile.TemporaryDirectory(dir=DATA) as tmp:
        out = Path(tmp) / "fit"
        cmd = [str(BIN), "fit", str(flight), "--out", str(out), "--quiet",
               *([] if plots else ["--no-plots"]), *(extra or [])]
        log = Path(tmp) / "stderr.txt"
        with open(log, "w") as err:
            t0 = time.perf_counter()
            proc = subprocess.Popen(
                cmd, stdout=subprocess.DEVNULL, stderr=err, env=child_env,
                preexec_fn=None if cores is None else (
                    lambda: os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:cores])))
            _, status, usage = os.wait4(proc.pid, 0)  # this child's own peak memory
            wall = time.perf_counter() - t0
        code = os.waitstatus_to_exitcode(status)
        if code not in RAN:
            raise RuntimeError(f"{' '.join(cmd)} failed: {log.read_text().strip()}")
        summary = json.loads((out / "summary.json").read_text())
    return {"wall_s": wall, "peak_rss_mb": usage.ru_maxrss / 1024.0, "summary": summary}


def float32_flight(flight: Path) -> Path:
    """``flight`` with its heat-map files written as float32 (as another tool would write
    them; cached beside it)."""
    out = flight.with_name(flight.name + "_float32")
    if not (out / "keyframes.txt").exists():
        tmp = out.with_name(out.name + ".tmp")
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.copytree(flight, tmp)
        for p in (tmp / "heatmaps").glob("*.npy"):
            np.save(p, np.load(p).astype(np.float32))
        shutil.rmtree(out, ignore_errors=True)
        tmp.rename(out)
    return out


def speed_runs(flight: Path, repeat: int, **kw: object) -> list[dict]:
    """``repeat`` runs of :func:`run_fit` after one that is not counted (bytecode caches,
    page cache)."""
    run_fit(flight, **kw)  # type: ignore[arg-type]
    return [run_fit(flight, **kw) for _ in range(repeat)]  # type: ignore[arg-type]


def speed_row(n: int, runs: list[dict], **what: object) -> dict:
    walls = [r["wall_s"] for r in runs]
    best = runs[walls.index(min(walls))]
    s = best["summary"]
    acc = s.get("accuracy", {})
    return {
        "keyframes": n, **what,
        "wall_s_min": round(min(walls), 3), "wall_s_median": round(statistics.median(walls), 3),
        "load_s": s["timing_s"]["load"], "solve_s": s["timing_s"]["solve"],
        "write_s": s["timing_s"]["write"],
        "iterations": s["solver"]["iterations"], "rounds": s["solver"]["rounds"],
        "num_residuals": s["solver"]["num_residuals"],
        "peak_rss_mb": round(max(r["peak_rss_mb"] for r in runs), 1),
        "position_m": acc.get("after", {}).get("position_error_m"),
        "orientation_deg": acc.get("after", {}).get("orientation_error_deg"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[50, 200, 1000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(8)))
    ap.add_argument("--out", type=Path, default=RESULTS / "bench_fit.json")
    args = ap.parse_args()
    DATA.mkdir(parents=True, exist_ok=True)
    RESULTS.mkdir(parents=True, exist_ok=True)
    if shutil.which(str(BIN)) is None:
        sys.exit(f"{BIN} not found: run inside the project's virtual environment")

    speed = []
    print("== speed: turbinefit fit FLIGHT --out OUT --no-plots (joint, defaults, seed 0) ==")
    head = (f"{'N':>6} {'wall min':>9} {'median':>7} {'load s':>7} {'solve s':>8} {'iters':>6} "
            f"{'residuals':>10} {'peak MB':>8} {'pos m':>6} {'rot deg':>7}")
    print(head)
    for n in args.sizes:
        flight = simulate(n, 0)
        warm(flight)
        variants: list[tuple[str, Path, dict]] = [("", flight, {})]
        if n == 1000:  # a flight made elsewhere: float32 maps; one core; with the figures
            f32 = float32_flight(flight)
            warm(f32)
            variants += [("float32 maps", f32, {}), ("float32 maps, one core", f32,
                                                     {"cores": 1}),
                         ("float32 maps, figures", f32, {"plots": True})]
        for name, path, kw in variants:
            row = speed_row(n, speed_runs(path, args.repeat, **kw),
                            maps="float32" if "float32" in name else "float16",
                            cores=kw.get("cores", os.cpu_count()), plots=bool(kw.get("plots")))
            speed.append(row)
            print(f"{n:>6} {row['wall_s_min']:>9.2f} {row['wall_s_median']:>7.2f} "
                  f"{row['load_s']:>7.2f} {row['solve_s']:>8.2f} {row['iterations']:>6} "
                  f"{row['num_residuals']:>10} {row['peak_rss_mb']:>8.0f} "
                  f"{row['position_m']:>6.3f} {row['orientation_deg']:>7.3f}  {name}")
    reference = []
    for n in [s for s in args.sizes if s <= 200]:
        row = speed_row(n, [run_fit(simulate(n, 0), env={"TURBINEFIT_NATIVE": "0"})])
        reference.append(row)
        print(f"{n:>6} {row['wall_s_min']:>9.2f} {'':>7} {row['load_s']:>7.2f} "
              f"{row['solve_s']:>8.2f} {row['iterations']:>6}   (numpy reference, no kernels)")

    print("\n== accuracy: 200 keyframes, mean over keyframes, per seed ==")
    acc: dict[str, list[dict]] = {}
    for name, extra in MODES.items():
        rows = []
        for seed in args.seeds:
            s = run_fit(simulate(200, seed), extra)["summary"]
            b, f = s["accuracy"]["before"], s["accuracy"]["after"]
            rows.append({
                "seed": seed,
                "position_m": [b["position_error_m"], f["position_error_m"]],
                "orientation_deg": [b["orientation_error_deg"], f["orientation_error_deg"]],
                "model_point_m": [b["model_point_error_m"], f["model_point_error_m"]],
                "model_point_ratio": f["model_point_error_m"] / max(b["model_point_error_m"],
                                                                    1e-12),
                "iterations": s["solver"]["iterations"],
            })
        acc[name] = rows
        pos = [r["position_m"][1] for r in rows]
        rot = [r["orientation_deg"][1] for r in rows]
        mpr = [100 * r["model_point_ratio"] for r in rows]
        print(f"{name}:")
        print("  position m      " + " ".join(f"{x:6.3f}" for x in pos)
              + f"   mean {statistics.mean(pos):.3f}  max {max(pos):.3f}")
        print("  orientation deg " + " ".join(f"{x:6.3f}" for x in rot)
              + f"   mean {statistics.mean(rot):.3f}  max {max(rot):.3f}")
        print("  model points %  " + " ".join(f"{x:6.1f}" for x in mpr)
              + f"   mean {statistics.mean(mpr):.1f}  max {max(mpr):.1f}")
    before = acc["joint"]
    print("  initial: position m " + " ".join(f"{r['position_m'][0]:.2f}" for r in before)
          + ", orientation deg " + " ".join(f"{r['orientation_deg'][0]:.2f}" for r in before)
          + ", model points m " + " ".join(f"{r['model_point_m'][0]:.2f}" for r in before))

    result = {
        "benchmark": "bench_fit",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "platform": platform.platform()},
        "speed": speed,
        "speed_numpy_reference": reference,
        "accuracy": acc,
    }
    write_json(args.out, result)
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
