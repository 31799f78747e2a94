"""The paper's three simulated studies (Section IV-A), the roll artefact (IV-B) and the
convergence basin, as sweeps with summaries, plots and a Markdown report.

Each study is a :class:`~turbinefit.experiments.sweep.SweepConfig` (:func:`study_config`);
:func:`run_study` runs or resumes it into a folder and writes the report;
:func:`write_report` rebuilds the figures and ``report.md`` from the stored rows alone.

Studies:

* ``unary`` (paper Fig. 4): the four unary configurations (points x lines, each corr or
  interp), initial against final mean position and orientation error, least-squares lines;
* ``joint`` (Fig. 5): joint against pose-only optimisation;
* ``turbine`` (Fig. 6): initial against final mean 3-D error of the six model points, and
  each parameter's error before and after;
* ``roll`` (Fig. 7): a wrong blade rotation (+10 deg) with exact GPS/IMU attitude; the
  camera roll error left by pose-only and by joint optimisation;
* ``basin``: success rate (final position and model-point errors under 0.5 m) against the
  size of the initial turbine and pose errors, up to 6x the defaults;
* ``quality``: heat-map quality: faults (pixel noise, missed parts, false responses, peak
  jitter) up to 4x the defaults, blob and ridge width 0.5-3x, a second turbine in view on
  half the flights; points corr and interp, lines interp;
* ``length``: flight length, 25 to 400 keyframes along the same inspection path;
* ``odometry``: the pairwise frame (measured, estimated, auto; and corr-normal with auto)
  on flights with GPS/IMU keyframes and on flights with body-frame odometry (half each).
* ``init``: ``turbinefit init`` then the fit (command-line defaults), from the images
  alone, ``near`` a position up to 15 m from the base, and with hub height and rotor
  diameter wrong by up to 15 %, against the flight's noisy turbine.yaml; headings and
  blade rotations uniform over their periods, both odometry kinds (the ``init_`` errors
  are then those of the estimate).
"""

from __future__ import annotations

import itertools
import json
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from turbinefit.errors import InputError
from turbinefit.eval.metrics import line_fit
from turbinefit.experiments.sweep import (
    PARAM_COLUMNS,
    ROWS_FILE,
    SweepConfig,
    SweepReport,
    read_rows,
    read_sweep_config,
    run_sweep,
)

#: Study names, in the order ``all`` runs them.
STUDIES = ("unary", "joint", "turbine", "roll", "basin", "quality", "length", "odometry",
           "init")
#: The paper's four unary configurations (points, lines).
UNARY = {
    "points corr, lines interp": {"points": "corr", "lines": "interp"},
    "points interp, lines interp": {"points": "interp", "lines": "interp"},
    "points corr, lines corr": {"points": "corr", "lines": "corr"},
    "points interp, lines corr": {"points": "interp", "lines": "corr"},
}
#: What counts as a converged flight in the basin study [m].
SUCCESS_POSITION_M = 0.5
SUCCESS_MODEL_POINTS_M = 0.5
RUNS_FILE = "runs.json"
REPORT_FILE = "report.md"


_JOINT = {"joint": {"preset": "paper-best"}}
#: The command-line defaults of a fit on heat-map files (turbinefit.jobs.sources).
_CLI = {"lines": "corr", "line_residual": "normal", "robust": "cauchy"}
_JOINT_POSE = {**_JOINT, "pose-only": {"preset": "pose-only"}}
#: The pairwise frames of the odometry study (the paper's best unary terms each).
_FRAMES = {"measured": {"preset": "paper-best", "pair_frame": "measured"},
           "estimated": {"preset": "paper-best", "pair_frame": "estimated"},
           "auto": {"preset": "paper-best"},
           "corr-normal, auto": {"preset": "corr-normal"}}
#: Each study: its default number of flights and the sweep fields it sets.
_STUDY_SWEEPS: dict[str, tuple[int, dict[str, Any]]] = {
    "unary": (200, {"configs": UNARY}),
    "joint": (200, {"configs": _JOINT_POSE}),
    "turbine": (200, {"pose_scale": (0.5, 2.0), "theta_scale": (0.5, 2.0), "configs": _JOINT}),
    "roll": (20, {"pose_scale": (0.0, 0.0), "theta_scale": (0.0, 0.0),
                  "blade_rotation_offset_deg": 10.0, "configs": _JOINT_POSE}),
    "basin": (120, {"pose_scale": (0.0, 6.0), "theta_scale": (0.0, 6.0), "configs": _JOINT}),
    "quality": (120, {"pose_scale": (0.5, 1.5), "theta_scale": (0.5, 1.5),
                      "heatmap_scale": (0.0, 4.0), "blur_scale": (0.5, 3.0),
                      "second_turbine": 0.5,
                      "configs": {k: UNARY[k] for k in ("points corr, lines interp",
                                                         "points interp, lines interp")}}),
    "length": (60, {"keyframes": 25, "keyframes_max": 400, "configs": _JOINT}),
    "odometry": (60, {"odometry": 0.5, "configs": _FRAMES}),
    # turbinefit init, then the fit (command-line defaults): headings and blade rotations
    # are uniform over their periods (the simulator's), both odometry kinds
    "init": (60, {"odometry": 0.5, "configs": {
        "init from nothing": {**_CLI, "init": "nothing"},
        "init near (<= 15 m)": {**_CLI, "init": "near"},
        "init with sizes (+-15 %)": {**_CLI, "init": "sizes"},
        "turbine.yaml": dict(_CLI)}}),
}


def study_config(study: str, flights: int | None = None, keyframes: int = 100,
                 seed: int = 0) -> SweepConfig:
    """The sweep of ``study`` (see the module docstring); the length study draws its own
    keyframe counts, so ``keyframes`` does not apply to it."""
    if study not in _STUDY_SWEEPS:
        raise InputError(f"unknown study {study!r} (choose from {', '.join(STUDIES)}, all)",
                         field="study")
    n, fields = _STUDY_SWEEPS[study]
    fields = {**fields, "configs": {k: dict(v) for k, v in fields["configs"].items()}}
    return SweepConfig(**{"name": study, "flights": flights or n, "keyframes": keyframes,
                          "seed": seed, **fields})


def run_study(cfg: SweepConfig, out_dir: str | os.PathLike[str], *, backend: str = "local",
              workers: int | None = None,
              progress: Callable[[int, int], None] | None = None) -> SweepReport:
    """Run or resume the sweep into ``out_dir``, record the run's timing in
    ``runs.json``, and write the figures and ``report.md``."""
    out = Path(out_dir)
    rep = run_sweep(cfg, out, backend=backend, workers=workers, progress=progress)
    runs = _read_runs(out)
    if rep.new_rows:  # a resumed sweep with nothing left to do is not a run
        runs.append({"date": time.strftime("%Y-%m-%dT%H:%M:%S"), "backend": backend,
                     "workers": workers or os.cpu_count(), "new_rows": rep.new_rows,
                     "seconds": round(rep.seconds, 2),
                     "rows_per_s": round(rep.new_rows / rep.seconds, 3) if rep.seconds > 0 else None})
    from turbinefit.io.atomic import write_text_atomic

    write_text_atomic(out / RUNS_FILE, json.dumps(runs, indent=2) + "\n")
    write_report(out)
    return rep


def _read_runs(folder: Path) -> list[dict[str, Any]]:
    """The timings of earlier runs of the study in ``folder`` (``runs.json``), or []."""
    path = folder / RUNS_FILE
    if not path.exists():
        return []
    from turbinefit.io.atomic import read_text

    try:
        runs = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"malformed JSON: {exc.msg}", path, exc.lineno) from None
    if not isinstance(runs, list):
        raise InputError("expected a list of runs", path)
    return runs


# ---------------------------------------------------------------------------------------
# summaries
# ---------------------------------------------------------------------------------------
def _ok(rows: list[dict[str, Any]], config: str | None = None) -> list[dict[str, Any]]:
    return [r for r in rows if r["status"] == "ok" and (config is None or r["config"] == config)]


def _col(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    return np.array([r[key] for r in rows], dtype=np.float64)


def reduction_stats(rows: list[dict[str, Any]], metric: str) -> dict[str, float]:
    """Median and 90th percentile of the final error and of the error reduction
    ``1 - final / initial`` [%] of ``metric`` over ``rows`` (flights whose initial error is
    zero are left out of the reduction)."""
    if not rows:
        return {}
    ini, fin = _col(rows, f"init_{metric}"), _col(rows, f"final_{metric}")
    keep = ini > 1e-9
    red = 100.0 * (1.0 - fin[keep] / ini[keep])
    out = {"final_median": float(np.median(fin)), "final_p90": float(np.percentile(fin, 90)),
           "initial_median": float(np.median(ini))}
    if red.size:
        out["reduction_median_pct"] = float(np.median(red))
        out["reduction_p10_pct"] = float(np.percentile(red, 10))
        out["reduction_p90_pct"] = float(np.percentile(red, 90))
    return out


def planned_rows(cfg: SweepConfig) -> int:
    """The rows the whole sweep has: one per flight and configuration."""
    return cfg.flights * len(cfg.configs)


def rows_text(cfg: SweepConfig, rows: list[dict[str, Any]]) -> str:
    """How many of the planned rows ``rows`` are, e.g. ``8 of 24 planned rows``."""
    return f"{len(rows)} of {planned_rows(cfg)} planned rows"


def summarize(cfg: SweepConfig, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The study's numbers: per configuration the reduction statistics of position,
    orientation and model-point error, least-squares lines of final against initial
    error, failures; plus the study's own figures (ordering, recovery, roll, basin)."""
    out: dict[str, Any] = {"study": cfg.name, "rows": len(rows),
                           "planned_rows": planned_rows(cfg),
                           "failed": sum(r["status"] != "ok" for r in rows), "configs": {}}
    for name in cfg.configs:
        ok = _ok(rows, name)
        c: dict[str, Any] = {"flights": len(ok)}
        for metric in ("position_m", "orientation_deg", "model_points_m", "roll_deg"):
            c[metric] = reduction_stats(ok, metric)
            if ok:
                c[metric]["line"] = line_fit(_col(ok, f"init_{metric}"), _col(ok, f"final_{metric}"))
        if ok:
            c["time_s_median"] = float(np.median(_col(ok, "time_s")))
            c["iterations_median"] = float(np.median(_col(ok, "iterations")))
        out["configs"][name] = c
    cs = out["configs"]
    ranked = sorted((n for n in cs if cs[n]["flights"]),
                    key=lambda n: cs[n]["position_m"]["final_median"])
    out["ranking_by_median_final_position"] = ranked
    if cfg.name == "turbine" or "joint" in cfg.configs:
        ok = _ok(rows, "joint" if "joint" in cfg.configs else next(iter(cfg.configs)))
        if ok:
            ini, fin = _col(ok, "init_model_points_m"), _col(ok, "final_model_points_m")
            keep = ini > 1e-9
            out["turbine_recovery_median_pct"] = float(np.median(100 * (1 - fin[keep] / ini[keep])))
            out["param_abs_error_median"] = {
                p: {"initial": float(np.median(np.abs(_col(ok, f"init_{p}")))),
                    "final": float(np.median(np.abs(_col(ok, f"final_{p}"))))}
                for p in PARAM_COLUMNS}
    if cfg.name == "roll":
        out["roll_deg_mean_abs"] = {
            "initial": float(np.mean(_col(_ok(rows), "init_roll_deg"))) if _ok(rows) else None,
            **{n: float(np.mean(_col(_ok(rows, n), "final_roll_deg")))
               for n in cfg.configs if _ok(rows, n)}}
    if cfg.name in FACTORS:
        out["factors"] = {
            key: {name: binned_medians([r for r in rows if r["config"] == name], key, edges)
                  for name in cfg.configs}
            for key, _, edges in FACTORS[cfg.name]}
    if cfg.odometry > 0:
        out["by_odometry"] = by_odometry(rows, list(cfg.configs))
    if cfg.name == "basin":
        ok = _ok(rows)
        out["success"] = basin_table(rows)
        out["success_rate"] = (float(np.mean([_success(r) for r in ok])) if ok else None)
    return out


def by_odometry(rows: list[dict[str, Any]], configs: list[str]) -> dict[str, Any]:
    """Per kind of pose measurements (``gps``, ``vio``) and configuration: fits, and the
    median final position, orientation and model-point errors."""
    out: dict[str, Any] = {}
    for kind in ("gps", "vio"):
        out[kind] = {}
        for name in configs:
            ok = [r for r in _ok(rows, name) if r.get("odometry", "gps") == kind]
            out[kind][name] = {"flights": len(ok), **{
                m: float(np.median(_col(ok, f"final_{m}"))) if ok else None
                for m in ("position_m", "orientation_deg", "model_points_m")}}
    return out


#: Bins of the quality and length studies: (row key, axis label, bin edges).
FACTORS: dict[str, list[tuple[str, str, tuple[float, ...]]]] = {
    "quality": [("heatmap_scale", "heat-map faults (x default)", (0, 1, 2, 3, 4.0001)),
                ("blur_scale", "heat-map blob width (x default)", (0.5, 1, 1.5, 2, 2.5, 3.0001)),
                ("second_turbine", "second turbine in view", (-0.5, 0.5, 1.5))],
    "length": [("keyframes", "keyframes per flight", (25, 50, 100, 200, 400.0001))],
}


def _bin_labels(key: str, edges: tuple[float, ...]) -> list[str]:
    if key == "second_turbine":
        return ["no", "yes"]
    return [f"{lo:g}-{round(hi, 2):g}" for lo, hi in itertools.pairwise(edges)]


def binned_medians(rows: list[dict[str, Any]], key: str, edges: tuple[float, ...],
                   metric: str = "final_position_m") -> list[dict[str, Any]]:
    """Per bin of ``key``: flight count, median and 90th percentile of ``metric`` (failed
    fits left out and counted)."""
    out = []
    for lo, hi in itertools.pairwise(edges):
        inbin = [r for r in rows if lo <= float(r[key]) < hi]
        ok = [r[metric] for r in inbin if r["status"] == "ok"]
        out.append({"low": lo, "high": hi, "flights": len(inbin),
                    "failed": len(inbin) - len(ok),
                    "median": float(np.median(ok)) if ok else None,
                    "p90": float(np.percentile(ok, 90)) if ok else None})
    return out


def _success(r: dict[str, Any]) -> bool:
    return (r["status"] == "ok" and r["final_position_m"] < SUCCESS_POSITION_M
            and r["final_model_points_m"] < SUCCESS_MODEL_POINTS_M)


def basin_table(rows: list[dict[str, Any]], edges: tuple[float, ...] = (0, 1, 2, 3, 4, 5, 6)
                ) -> dict[str, Any]:
    """Success rate in bins of the turbine-error and pose-error scales (failed fits count
    as failures)."""
    e = np.asarray(edges, dtype=np.float64)
    th = np.array([r["theta_scale"] for r in rows])
    po = np.array([r["pose_scale"] for r in rows])
    ok = np.array([_success(r) for r in rows], dtype=np.float64)
    rate = np.full((e.size - 1, e.size - 1), np.nan)
    count = np.zeros((e.size - 1, e.size - 1), dtype=int)
    for i in range(e.size - 1):
        for j in range(e.size - 1):
            m = (th >= e[i]) & (th < e[i + 1]) & (po >= e[j]) & (po < e[j + 1])
            count[i, j] = int(m.sum())
            if m.any():
                rate[i, j] = float(ok[m].mean())
    by_theta = [float(ok[(th >= e[i]) & (th < e[i + 1])].mean())
                if np.any((th >= e[i]) & (th < e[i + 1])) else None for i in range(e.size - 1)]
    by_pose = [float(ok[(po >= e[j]) & (po < e[j + 1])].mean())
               if np.any((po >= e[j]) & (po < e[j + 1])) else None for j in range(e.size - 1)]
    return {"edges": list(edges), "rate": [[None if math.isnan(v) else v for v in row]
                                           for row in rate.tolist()],
            "count": count.tolist(), "by_theta_scale": by_theta, "by_pose_scale": by_pose}


# ---------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------
def load_study(folder: str | os.PathLike[str]) -> tuple[SweepConfig, list[dict[str, Any]]]:
    """The sweep configuration and rows stored in ``folder`` (InputError if missing)."""
    root = Path(folder)
    sweep = root / "sweep.yaml"
    if not sweep.is_file():
        raise InputError("not a sweep folder (no sweep.yaml)", root)
    return read_sweep_config(sweep), read_rows(root / ROWS_FILE)


def _pct(v: float | None) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.0f} %"


def _num(v: float | None, digits: int = 3) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def write_report(folder: str | os.PathLike[str]) -> Path:
    """Figures (PNG) and ``report.md`` of the study in ``folder``, from its rows alone;
    also ``summary.json``. Returns the report's path."""
    from turbinefit import plots
    from turbinefit.io.atomic import write_text_atomic

    root = Path(folder)
    cfg, rows = load_study(root)
    summ = summarize(cfg, rows)
    names = list(cfg.configs)
    ok = _ok(rows)
    figures: list[tuple[str, str]] = []
    if ok:
        series = {n: _ok(rows, n) for n in names}
        if cfg.name in ("unary", "joint") or len(names) > 1:
            plots.plot_error_scatter(
                root / "errors.png",
                {n: (_col(s, "init_position_m"), _col(s, "final_position_m"))
                 for n, s in series.items() if s},
                {n: (_col(s, "init_orientation_deg"), _col(s, "final_orientation_deg"))
                 for n, s in series.items() if s},
                title=f"{cfg.name}: initial vs final mean error ({len(ok)} fits)")
            figures.append(("errors.png", "Initial against final mean error per flight, "
                            "least-squares lines"))
        j = series.get("joint") or series[names[0]]
        if j:
            plots.plot_turbine_recovery(
                root / "turbine.png", _col(j, "init_model_points_m"),
                _col(j, "final_model_points_m"),
                {p: (np.abs(_col(j, f"init_{p}")), np.abs(_col(j, f"final_{p}")))
                 for p in PARAM_COLUMNS})
            figures.append(("turbine.png", "Turbine recovery: model-point error and each "
                            "parameter's error before and after"))
        if cfg.name == "roll":
            plots.plot_roll(root / "roll.png", {
                "initial": _col(series[names[0]], "init_roll_deg"),
                **{n: _col(s, "final_roll_deg") for n, s in series.items() if s}})
            figures.append(("roll.png", "Mean camera roll error per flight"))
        if cfg.name in FACTORS:
            panels: list[tuple[str, Sequence[str], dict[str, Sequence[float | None]]]] = []
            for key, label, edges in FACTORS[cfg.name]:
                f = summ["factors"][key]
                ticks = _bin_labels(key, edges)
                panels.append((label, ticks, {n: [b["median"] for b in f[n]] for n in names}))
            plots.plot_binned(root / "factors.png", panels,
                              ylabel="median final position error [m]")
            figures.append(("factors.png", "Median final position error against "
                            + ", ".join(lab for _, lab, _ in FACTORS[cfg.name])))
        if cfg.name == "basin":
            b = summ["success"]
            plots.plot_basin(root / "basin.png", np.array(b["edges"]),
                             np.array([[np.nan if v is None else v for v in row]
                                       for row in b["rate"]], dtype=np.float64),
                             np.array(b["count"]))
            figures.append(("basin.png", "Success rate against the initial error sizes"))
    runs = _read_runs(root)
    lines = [f"# turbinefit experiment: {cfg.name}", ""]
    if len(rows) < planned_rows(cfg):
        lines += [f"**Incomplete: drawn from {rows_text(cfg, rows)}** (the run was stopped; "
                  "running the same `turbinefit experiment` command again completes it).", ""]
    lines += [f"{cfg.flights} simulated flights of {cfg.keyframes} keyframes ({cfg.width}x"
              f"{cfg.height} heat-maps, turbine {cfg.turbine}, sweep seed {cfg.seed}), "
              f"{len(names)} configuration(s): {rows_text(cfg, rows)}, {summ['failed']} failed. "
              f"Initial pose error scale {cfg.pose_scale[0]:g}-{cfg.pose_scale[1]:g}, turbine "
              f"error scale {cfg.theta_scale[0]:g}-{cfg.theta_scale[1]:g}, heat-map fault "
              f"scale {cfg.heatmap_scale[0]:g}-{cfg.heatmap_scale[1]:g} (1 = the simulator's "
              "defaults)" + (f", blade rotation offset {cfg.blade_rotation_offset_deg:g} deg"
                             if cfg.blade_rotation_offset_deg else "") + ".", ""]
    if runs:
        last = runs[-1]
        total_rows = sum(r["new_rows"] for r in runs)
        total_s = sum(r["seconds"] for r in runs)
        lines += [f"Run time: {total_s:.0f} s for {total_rows} rows in {len(runs)} run(s) "
                  f"({total_rows / total_s if total_s else 0:.2f} rows/s; last run: "
                  f"{last['backend']} backend, {last['workers']} worker(s)).", ""]
    lines += ["| configuration | fits | position: final median / p90 [m] | reduction median "
              "(p10 - p90) | orientation: final median / p90 [deg] | reduction median | "
              "model points: final median [m] | reduction median |",
              "|---|---|---|---|---|---|---|---|"]
    for n in names:
        c = summ["configs"][n]
        p, o, m = c.get("position_m", {}), c.get("orientation_deg", {}), c.get("model_points_m", {})
        lines.append(
            f"| {n} | {c['flights']} | {_num(p.get('final_median'))} / {_num(p.get('final_p90'))}"
            f" | {_pct(p.get('reduction_median_pct'))} ({_pct(p.get('reduction_p10_pct'))} - "
            f"{_pct(p.get('reduction_p90_pct'))}) | {_num(o.get('final_median'))} / "
            f"{_num(o.get('final_p90'))} | {_pct(o.get('reduction_median_pct'))} | "
            f"{_num(m.get('final_median'))} | {_pct(m.get('reduction_median_pct'))} |")
    lines.append("")
    lines += _study_text(cfg, summ)
    for fname, caption in figures:
        lines += [f"![{caption}]({fname})", "", f"*{caption}.*", ""]
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        lines += ["## Failed fits", "", "| flight | configuration | reason |", "|---|---|---|"]
        lines += [f"| {r['flight']} | {r['config']} | {r['reason']} |" for r in failed[:50]]
        lines.append("")
    write_text_atomic(root / "summary.json", json.dumps(summ, indent=2) + "\n")
    return write_text_atomic(root / REPORT_FILE, "\n".join(lines))


def _study_text(cfg: SweepConfig, s: dict[str, Any]) -> list[str]:
    out: list[str] = []
    ranked = s["ranking_by_median_final_position"]
    if cfg.name == "unary" and ranked:
        paper = "points corr, lines interp"
        out += [f"Ranking by median final position error: {' > '.join(ranked)}. The paper "
                f"found *{paper}* best; here it ranks {ranked.index(paper) + 1 if paper in ranked else '-'}"
                f" of {len(ranked)}.", ""]
    if cfg.name == "joint" and "joint" in s["configs"] and "pose-only" in s["configs"]:
        j, p = s["configs"]["joint"], s["configs"]["pose-only"]
        if j["flights"] and p["flights"]:
            out += [f"Median final position error: joint {j['position_m']['final_median']:.3f} "
                    f"m, pose-only {p['position_m']['final_median']:.3f} m.", ""]
    if "turbine_recovery_median_pct" in s and cfg.name in ("turbine", "joint"):
        out += [f"Median recovery of the introduced turbine error (1 - final / initial mean "
                f"model-point error): **{s['turbine_recovery_median_pct']:.1f} %**.", "",
                "| parameter | median abs. error before | after |", "|---|---|---|"]
        out += [f"| {p} | {v['initial']:.3f} | {v['final']:.3f} |"
                for p, v in s["param_abs_error_median"].items()]
        out.append("")
    if cfg.name == "roll" and s.get("roll_deg_mean_abs"):
        r = s["roll_deg_mean_abs"]
        out += ["Mean absolute camera roll error [deg]: " + ", ".join(
            f"{k} {_num(v)}" for k, v in r.items()) + ".", ""]
    if cfg.name in FACTORS and s.get("factors"):
        for key, label, edges in FACTORS[cfg.name]:
            f = s["factors"][key]
            cols = _bin_labels(key, edges)
            out += [f"Median (90th percentile) final position error [m] by {label}:", "",
                    "| configuration | " + " | ".join(cols) + " |",
                    "|---|" + "---|" * len(cols)]
            for n, bins in f.items():
                out.append(f"| {n} | " + " | ".join(
                    f"{_num(b['median'])} ({_num(b['p90'])}), n={b['flights']}" for b in bins)
                    + " |")
            out.append("")
    if s.get("by_odometry"):
        out += ["Median final errors by kind of pose measurements (gps: GPS/IMU keyframes; "
                "vio: body-frame odometry in odometry.txt):", "",
                "| measurements | configuration | fits | position [m] | orientation [deg] | "
                "model points [m] |", "|---|---|---|---|---|---|"]
        for kind, by in s["by_odometry"].items():
            for n, v in by.items():
                out.append(f"| {kind} | {n} | {v['flights']} | {_num(v['position_m'])} | "
                           f"{_num(v['orientation_deg'])} | {_num(v['model_points_m'])} |")
        out.append("")
    if cfg.name == "basin" and s.get("success"):
        b = s["success"]
        e = b["edges"]
        out += [f"Success: final position and model-point errors under {SUCCESS_POSITION_M} m "
                f"(overall {_pct(100 * s['success_rate'] if s['success_rate'] is not None else None)}).", "",
                "| scale | " + " | ".join(f"{e[i]:g}-{e[i + 1]:g}" for i in range(len(e) - 1)) + " |",
                "|---|" + "---|" * (len(e) - 1),
                "| turbine error | " + " | ".join(_pct(None if v is None else 100 * v)
                                                  for v in b["by_theta_scale"]) + " |",
                "| pose error | " + " | ".join(_pct(None if v is None else 100 * v)
                                               for v in b["by_pose_scale"]) + " |", ""]
    return out


def write_index(root: str | os.PathLike[str]) -> Path:
    """``root/report.md``: one line of headline figures per study folder below ``root``,
    linking each study's own report (what ``experiment all`` and ``report`` write)."""
    from turbinefit.io.atomic import write_text_atomic

    base = Path(root)
    lines = ["# turbinefit experiments", "", "| study | flights x configurations | headline | "
             "report |", "|---|---|---|---|"]
    for sub in sorted(p for p in base.iterdir() if (p / "sweep.yaml").is_file()):
        cfg, rows = load_study(sub)
        s = summarize(cfg, rows)
        head = ""
        if cfg.name == "unary":
            head = "best by median final position: " + (s["ranking_by_median_final_position"]
                                                        or ["-"])[0]
        elif cfg.name in ("joint", "turbine") and "turbine_recovery_median_pct" in s:
            head = f"median turbine-error recovery {s['turbine_recovery_median_pct']:.1f} %"
            if cfg.name == "joint" and s["configs"].get("pose-only", {}).get("flights"):
                head += (f"; median final position joint "
                         f"{s['configs']['joint']['position_m']['final_median']:.3f} m, "
                         f"pose-only {s['configs']['pose-only']['position_m']['final_median']:.3f} m")
        elif cfg.name == "roll" and s.get("roll_deg_mean_abs"):
            head = "mean roll error " + ", ".join(f"{k} {_num(v)} deg"
                                                  for k, v in s["roll_deg_mean_abs"].items())
        elif cfg.name in FACTORS and s.get("factors"):
            name = next(iter(cfg.configs))
            parts = []
            for key, label, edges in FACTORS[cfg.name]:
                bins = s["factors"][key][name]
                parts.append(f"{label} " + ", ".join(
                    f"{t} {_num(b['median'])}" for t, b in zip(_bin_labels(key, edges), bins,
                                                                strict=True)))
            head = f"median final position [m] ({name}): " + "; ".join(parts)
        elif cfg.name == "basin" and s.get("success_rate") is not None:
            head = f"success rate {100 * s['success_rate']:.0f} %"
        elif s.get("by_odometry"):
            head = "median final position [m]: " + "; ".join(
                f"{kind} " + ", ".join(f"{n} {_num(v['position_m'])}" for n, v in by.items())
                for kind, by in s["by_odometry"].items())
        elif s["ranking_by_median_final_position"]:  # a custom sweep
            head = "by median final position: " + " > ".join(
                f"{n} {s['configs'][n]['position_m']['final_median']:.3f} m"
                for n in s["ranking_by_median_final_position"])
        if len(rows) < planned_rows(cfg):
            head = f"**incomplete: {rows_text(cfg, rows)}**; {head}"
        lines.append(f"| {cfg.name} | {cfg.flights} x {len(cfg.configs)} | {head} | "
                     f"[{sub.name}/{REPORT_FILE}]({sub.name}/{REPORT_FILE}) |")
    lines.append("")
    return write_text_atomic(base / REPORT_FILE, "\n".join(lines))
