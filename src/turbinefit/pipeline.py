"""End-to-end jobs over flight folders: what the CLI commands run.

Each job is one typed function returning a result dataclass; the CLI only parses
arguments, calls it and prints. Outputs are written atomically: everything goes into a
temporary folder next to ``out_dir`` that is renamed into place at the end, so a failure
(bad input, an interrupted run) leaves nothing half-written, and inputs are never
overwritten.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.eval.metrics import Accuracy, accuracy
from turbinefit.flight import Flight
from turbinefit.heatmaps import NonFiniteHeatmapError
from turbinefit.io.atomic import atomic_output_dir
from turbinefit.io.flight_folder import read_flight
from turbinefit.io.tum import write_tum
from turbinefit.io.turbine_yaml import write_turbine_yaml
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import FitResult, fit
from turbinefit.solver.lm import IterationRecord


@dataclass
class FitReport:
    """What :func:`fit_folder` did.

    Attributes:
        result: the solver's result.
        out_dir: where the outputs were written.
        before, after: accuracy of the initial and optimised estimates (None without
            ground truth).
        timings: seconds spent loading, solving, writing and plotting.
        summary: the dictionary written to ``summary.json``.
    """

    result: FitResult
    out_dir: Path
    before: Accuracy | None
    after: Accuracy | None
    timings: dict[str, float]
    summary: dict[str, Any] = field(default_factory=dict)


def load_fit_config(path: str | os.PathLike[str]) -> FitConfig:
    """Read fit options from a YAML mapping (the ``config.yaml`` that ``fit`` writes)."""
    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text())
    except FileNotFoundError:
        raise InputError("file not found", p) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise InputError(f"malformed YAML: {getattr(exc, 'problem', exc)}", p,
                         None if mark is None else mark.line + 1) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError("expected a mapping of fit options", p)
    data.pop("turbinefit_version", None)
    try:
        return FitConfig.from_dict(data)
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), p) from None


def _check_out_dir(out_dir: Path, inputs: list[Path]) -> None:
    out = out_dir.resolve()
    for src in inputs:
        s = src.resolve()
        if out == s or s.is_relative_to(out) or out.is_relative_to(s):
            raise InputError(f"output folder would overwrite or nest inside the input {src}",
                             out_dir)


def fit_folder(
    flight_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: FitConfig | None = None,
    *,
    plots: bool = True,
    overwrite: bool = False,
    progress: Callable[[IterationRecord], None] | None = None,
) -> FitReport:
    """Fit the flight in ``flight_dir`` and write the results to ``out_dir``.

    Writes ``keyframes.txt`` (optimised ``world_T_cam``, TUM), ``turbine.yaml`` (fitted
    theta), ``summary.json``, ``config.yaml`` (the resolved options) and, unless
    ``plots=False``, ``scene.png``, ``reprojections.png``, ``errors.png`` (with ground
    truth) and ``cost.png``.
    """
    cfg = config or FitConfig()
    flight_dir = Path(flight_dir)
    out_dir = Path(out_dir)
    _check_out_dir(out_dir, [flight_dir])
    if out_dir.exists() and not overwrite and any(out_dir.iterdir()):
        raise InputError("output folder exists and is not empty (use --overwrite)", out_dir)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    flight = read_flight(flight_dir)
    timings["load"] = time.perf_counter() - t0

    t1 = time.perf_counter()
    try:
        result = fit(flight, cfg, callback=progress)
    except NonFiniteHeatmapError as exc:
        stamp = flight.timestamps[exc.keyframe]
        raise InputError("heat-map contains NaN or inf",
                         flight_dir / "heatmaps" / f"{stamp:.6f}.npy") from None
    timings["solve"] = time.perf_counter() - t1

    before = after = None
    if flight.gt_world_T_cam is not None and flight.gt_turbine is not None:
        before = accuracy(flight.world_T_cam, flight.turbine, flight.gt_world_T_cam,
                          flight.gt_turbine, cfg.geometry)
        after = accuracy(result.world_T_cam, result.turbine, flight.gt_world_T_cam,
                         flight.gt_turbine, cfg.geometry)

    summary = make_summary(flight_dir, flight, result, before, after, timings)
    t2 = time.perf_counter()
    with atomic_output_dir(out_dir, overwrite=overwrite) as tmp:
        write_tum(tmp / "keyframes.txt", flight.timestamps, result.world_T_cam)
        write_turbine_yaml(tmp / "turbine.yaml", result.turbine,
                           comment="turbinefit: fitted turbine parameters (metres, radians)")
        cfg_dict = {"turbinefit_version": __version__, **result.config.to_dict()}
        (tmp / "config.yaml").write_text(yaml.safe_dump(cfg_dict, sort_keys=False))
        if plots:
            t3 = time.perf_counter()
            write_plots(tmp, flight, result)
            timings["plots"] = time.perf_counter() - t3
        timings["write"] = time.perf_counter() - t2 - timings.get("plots", 0.0)
        timings["total"] = time.perf_counter() - t0
        summary["timing_s"] = {k: round(v, 4) for k, v in timings.items()}
        (tmp / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return FitReport(result, out_dir, before, after, timings, summary)


def make_summary(flight_dir: Path, flight: Flight, result: FitResult, before: Accuracy | None,
                 after: Accuracy | None, timings: dict[str, float]) -> dict[str, Any]:
    """The content of ``summary.json``."""
    summary: dict[str, Any] = {
        "turbinefit_version": __version__,
        "flight": str(flight_dir),
        "num_keyframes": flight.num_keyframes,
        "heatmap_size": [flight.camera.width, flight.camera.height],
        "config": result.config.to_dict(),
        "solver": {
            "initial_cost": result.initial_cost,
            "final_cost": result.final_cost,
            "initial_terms": result.initial_terms,
            "final_terms": result.final_terms,
            "iterations": result.iterations,
            "rounds": result.rounds,
            "termination": result.termination,
            "num_residuals": result.num_residuals,
            "history": [
                {"round": h.round, "iteration": h.iteration, "cost": h.cost,
                 "step_norm": h.step_norm, "mu": h.mu, "accepted": h.accepted,
                 "time_s": round(h.time_s, 5)}
                for h in result.history
            ],
        },
        "turbine": {"initial": flight.turbine.to_dict(), "optimised": result.turbine.to_dict()},
        "timing_s": {k: round(v, 4) for k, v in timings.items()},
    }
    if before is not None and after is not None:
        summary["accuracy"] = {"before": before.to_dict(), "after": after.to_dict()}
    return summary


def write_plots(out: Path, flight: Flight, result: FitResult) -> None:
    """The figures of a fit (imports matplotlib only when called)."""
    from turbinefit import plots
    from turbinefit.geometry.se3 import pose_errors

    geometry = result.config.geometry
    plots.plot_scene(
        out / "scene.png", initial_poses=flight.world_T_cam, optimised_poses=result.world_T_cam,
        initial_turbine=flight.turbine, optimised_turbine=result.turbine,
        gt_poses=flight.gt_world_T_cam, gt_turbine=flight.gt_turbine, geometry=geometry)
    plots.plot_reprojections(
        out / "reprojections.png", camera=flight.camera, heatmaps=flight.heatmaps,
        keyframes=plots.choose_keyframes(flight.num_keyframes, 6),
        initial_poses=flight.world_T_cam, initial_turbine=flight.turbine,
        optimised_poses=result.world_T_cam, optimised_turbine=result.turbine,
        geometry=geometry, timestamps=flight.timestamps)
    if flight.gt_world_T_cam is not None:
        p0, r0 = pose_errors(flight.world_T_cam, flight.gt_world_T_cam)
        p1, r1 = pose_errors(result.world_T_cam, flight.gt_world_T_cam)
        plots.plot_errors(out / "errors.png", timestamps=flight.timestamps,
                          initial_pos_err=p0, optimised_pos_err=p1,
                          initial_rot_err_deg=np.degrees(r0), optimised_rot_err_deg=np.degrees(r1))
    if result.history:
        plots.plot_cost_history(out / "cost.png",
                                [result.initial_cost] + [h.cost for h in result.history])


def simulate_folder(
    out_dir: str | os.PathLike[str],
    config: Any = None,
    *,
    overwrite: bool = False,
    progress: bool = False,
) -> Path:
    """Simulate a flight (:func:`turbinefit.sim.simulate_flight`) and write it as a flight
    folder with ground truth; the resolved simulation settings go to ``simulation.yaml``."""
    import dataclasses

    from turbinefit.io.flight_folder import write_flight
    from turbinefit.sim.scenario import SimConfig, simulate_flight

    cfg = config or SimConfig()
    out = Path(out_dir)
    if out.exists() and not overwrite and any(out.iterdir()):
        raise InputError("output folder exists and is not empty (use --overwrite)", out)
    flight = simulate_flight(cfg, progress=progress)
    write_flight(flight, out, overwrite=overwrite)
    settings = {"turbinefit_version": __version__, **_plain(dataclasses.asdict(cfg))}
    from turbinefit.io.atomic import write_text_atomic

    write_text_atomic(out / "simulation.yaml", yaml.safe_dump(settings, sort_keys=False))
    return out


def _plain(obj: Any) -> Any:
    """Tuples to lists, recursively (for YAML)."""
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    return obj
