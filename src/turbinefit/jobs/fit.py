"""The ``fit`` job: a flight folder in, the fitted poses, turbine, summary and figures out.

:func:`fit_folder` reads the flight (heat-maps from ``heatmaps/`` or detected from the
photos, :mod:`turbinefit.jobs.sources`), runs :func:`turbinefit.solver.fit` and writes the
output folder atomically (:mod:`turbinefit.jobs.outputs`). Nothing is written into the
flight folder.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.eval.metrics import Accuracy, accuracy
from turbinefit.flight import Flight
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import NonFiniteHeatmapError
from turbinefit.io.atomic import write_text_atomic
from turbinefit.io.fit_config import format_fit_config
from turbinefit.io.flight_folder import read_flight_folder
from turbinefit.io.georef import location_text, read_flight_georef, write_georef_outputs
from turbinefit.io.mesh import write_turbine_glb
from turbinefit.io.tum import write_tum
from turbinefit.io.turbine_yaml import write_turbine_yaml
from turbinefit.jobs.init import InitSummary, estimate_turbine
from turbinefit.jobs.outputs import (
    FIT_OUTPUTS,
    flight_inputs,
    plot_error,
    recorded_path,
    summary_json,
)
from turbinefit.jobs.sources import fit_config_for, open_heatmaps, photo_stack, source_photos
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import FitResult, fit
from turbinefit.solver.lm import IterationRecord
from turbinefit.turbine.model import TurbineParams

if TYPE_CHECKING:
    from turbinefit.detect import DetectOptions

#: The comment line of the ``turbine.yaml`` that ``fit`` and ``track`` write.
FITTED_TURBINE_COMMENT = "turbinefit: fitted turbine parameters (metres, radians)"


@dataclass
class FitSummary:
    """What ``summary.json`` of a fit holds (:meth:`to_dict` is its layout).

    Attributes:
        flight: the flight folder.
        num_keyframes: keyframes fitted.
        heatmap_size: (width, height) of the heat-maps fitted [px].
        heatmaps: where the heat-maps came from.
        defaults: which defaults the options started from (None: a --config file or preset).
        result: the solver's result (costs, iterations, rounds, history, config).
        initial_turbine: the flight's initial turbine.
        before, after: accuracy of the initial and fitted estimates (None without ground
            truth).
        timings: seconds spent loading, solving, writing, plotting and in all.
        init: without ``turbine.yaml``: how the initial turbine was estimated
            (``turbinefit init``), else None.
    """

    flight: str
    num_keyframes: int
    heatmap_size: tuple[int, int]
    heatmaps: str
    result: FitResult
    initial_turbine: TurbineParams
    before: Accuracy | None = None
    after: Accuracy | None = None
    timings: dict[str, float] = field(default_factory=dict)
    defaults: str | None = None
    init: InitSummary | None = None

    def to_dict(self) -> dict[str, Any]:
        r = self.result
        out: dict[str, Any] = {
            "turbinefit_version": __version__,
            "flight": self.flight,
            "num_keyframes": self.num_keyframes,
            "heatmap_size": list(self.heatmap_size),
            "config": r.config.to_dict(),
            "solver": {
                "initial_cost": r.initial_cost,
                "final_cost": r.final_cost,
                "initial_terms": r.initial_terms,
                "final_terms": r.final_terms,
                "iterations": r.iterations,
                "rounds": r.rounds,
                "termination": r.termination,
                "num_residuals": r.num_residuals,
                "history": [
                    {"stage": h.stage, "round": h.round, "iteration": h.iteration,
                     "cost": h.cost, "step_norm": h.step_norm, "mu": h.mu,
                     "accepted": h.accepted, "time_s": round(h.time_s, 5)}
                    for h in r.history
                ],
            },
            "turbine": {"initial": self.initial_turbine.to_dict(),
                        "optimised": r.turbine.to_dict(),
                        "std": None if r.signals is None else r.signals.theta_std_dict()},
            "verdict": r.verdict,
            "reasons": list(r.reasons),
            "signals": None if r.signals is None else r.signals.to_dict(),
            "timing_s": {k: round(v, 4) for k, v in self.timings.items()},
        }
        if self.before is not None and self.after is not None:
            out["accuracy"] = {"before": self.before.to_dict(), "after": self.after.to_dict()}
        out["heatmaps"] = self.heatmaps
        out["turbine_init"] = None if self.init is None else self.init.to_dict()
        if self.defaults is not None:
            out["defaults"] = self.defaults
        return out


@dataclass
class FitReport:
    """What :func:`fit_folder` did.

    Attributes:
        result: the solver's result.
        out_dir: where the outputs were written.
        summary: what ``summary.json`` holds (accuracy before and after with ground truth,
            timings).
    """

    result: FitResult
    out_dir: Path
    summary: FitSummary

    @property
    def before(self) -> Accuracy | None:
        return self.summary.before

    @property
    def after(self) -> Accuracy | None:
        return self.summary.after

    @property
    def timings(self) -> dict[str, float]:
        return self.summary.timings


def fit_folder(
    flight_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: FitConfig | None = None,
    *,
    options: Mapping[str, Any] | None = None,
    plots: bool = True,
    overwrite: bool = False,
    progress: Callable[[IterationRecord], None] | None = None,
    config_path: str | os.PathLike[str] | None = None,
    from_images: bool | None = None,
    model: str | os.PathLike[str] | None = None,
    detect_progress: bool = False,
    detect_options: DetectOptions | None = None,
    initial_poses: SE3 | None = None,
    initial_turbine: TurbineParams | None = None,
) -> FitReport:
    """Fit the flight in ``flight_dir`` and write the results to ``out_dir``.

    Writes ``keyframes.txt`` (optimised ``world_T_cam``, TUM), ``turbine.yaml`` (fitted
    theta and its standard deviations), ``turbine.glb`` (the fitted turbine as a 3-D model,
    :mod:`turbinefit.io.mesh`), ``summary.json`` (:class:`FitSummary`, with the verdict,
    its reasons and signals), ``config.yaml`` (the resolved options) and, unless
    ``plots=False``, ``scene.png``, ``reprojections.png``, ``errors.png`` (with ground truth)
    and ``cost.png``. The outputs are written whatever the verdict
    (``report.result.verdict``): a failed fit is kept for inspection.

    ``out_dir`` is checked before anything is read (:mod:`turbinefit.jobs.outputs`): not
    ``flight_dir`` or ``config_path`` (the file ``config`` was read from), nor inside or
    around them; an existing non-empty folder only with ``overwrite`` and only if it holds
    nothing but the files above.

    Heat-maps come from ``flight_dir/heatmaps/``, or are detected from the photos in
    ``flight_dir/images/`` (ONNX ``model`` or the shipped one, with ``detect_options``)
    when ``from_images`` is True, or when it is None and the flight has photos but no
    ``heatmaps/`` (:func:`turbinefit.jobs.sources.open_heatmaps`).

    Without ``turbine.yaml`` the initial turbine is estimated from the heat-maps first
    (:func:`turbinefit.jobs.init.estimate_turbine`; ``summary.init``).

    Options: ``config`` (None = the defaults for the kind of heat-maps,
    :func:`turbinefit.jobs.sources.fit_config_for`), with the FitConfig fields of
    ``options`` set on top; the options used are written to ``config.yaml``.

    ``initial_poses``, ``initial_turbine``: start from these instead of the flight's
    ``keyframes.txt`` and ``turbine.yaml`` (e.g. a tracker's final estimates); the flight's
    poses remain the measurements.
    """
    flight_dir = Path(flight_dir)
    out_dir = Path(out_dir)
    FIT_OUTPUTS.check(out_dir, flight_inputs(flight_dir, None if config_path is None
                                              else Path(config_path)), overwrite)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    folder = read_flight_folder(flight_dir)
    georef = read_flight_georef(flight_dir)
    # heat-map files are checked as the solver first reads them (its first search reads
    # every keyframe: the check then costs no pass over the files of its own)
    source = open_heatmaps(folder, from_images, model, detect_options, check="first read")
    cfg = fit_config_for(source, config, options)
    with source.checking():  # a value out of range: the InputError naming its file
        stack = source.stack(progress=detect_progress)
        init = None
        if folder.turbine is None:  # no turbine.yaml: estimate it from the images
            init = estimate_turbine(stack, source.camera, folder.keyframes.poses,
                                    where=flight_dir, gt_turbine=folder.gt_turbine)
        flight = folder.flight(stack, source.camera, None if init is None else init.turbine)
        if cfg.uses_photos:
            flight = dataclasses.replace(flight, photos=photo_stack(
                flight_dir, flight.timestamps, flight.camera))
        timings["load"] = time.perf_counter() - t0

        t1 = time.perf_counter()
        try:
            # absurd inputs overflow inside the solver: the verdict reports it (non-finite
            # numbers, no step), not numpy's warnings
            with np.errstate(over="ignore", invalid="ignore"):
                result = fit(flight, cfg, callback=progress, initial_poses=initial_poses,
                             initial_turbine=initial_turbine)
        except NonFiniteHeatmapError as exc:
            raise InputError("heat-map contains NaN or inf",
                             source.where(exc.keyframe)) from None
        timings["solve"] = time.perf_counter() - t1

    summary = FitSummary(recorded_path(flight_dir, out_dir), flight.num_keyframes,
                         (flight.camera.width, flight.camera.height), source.description,
                         result, flight.turbine, timings=timings,
                         defaults=None if config is not None else source.defaults_name,
                         init=init)
    if flight.gt_world_T_cam is not None and flight.gt_turbine is not None:
        with np.errstate(over="ignore", invalid="ignore"):  # errors of absurd inputs: inf
            summary.before = accuracy(flight.world_T_cam, flight.turbine,
                                      flight.gt_world_T_cam, flight.gt_turbine, cfg.geometry)
            summary.after = accuracy(result.world_T_cam, result.turbine,
                                     flight.gt_world_T_cam, flight.gt_turbine, cfg.geometry)
    t2 = time.perf_counter()
    with FIT_OUTPUTS.writing(out_dir, overwrite) as tmp:
        write_tum(tmp / "keyframes.txt", flight.timestamps, result.world_T_cam)
        write_turbine_yaml(tmp / "turbine.yaml", result.turbine, comment=FITTED_TURBINE_COMMENT,
                           std=None if result.signals is None
                           else result.signals.theta_std_dict(),
                           extra=location_text(georef, result.turbine))
        write_georef_outputs(tmp, georef, flight.timestamps, result.world_T_cam)
        write_turbine_glb(tmp / "turbine.glb", result.turbine, result.config.geometry,
                          georef)
        write_text_atomic(tmp / "config.yaml", format_fit_config(result.config), fsync=False)
        if plots:
            t3 = time.perf_counter()
            try:
                write_plots(tmp, flight, result, source_photos(source))
            except OSError as exc:  # e.g. no space left on the device
                raise plot_error(exc, out_dir) from exc
            timings["plots"] = time.perf_counter() - t3
        timings["write"] = time.perf_counter() - t2 - timings.get("plots", 0.0)
        timings["total"] = time.perf_counter() - t0
        write_text_atomic(tmp / "summary.json", summary_json(summary), fsync=False)
    return FitReport(result, out_dir, summary)


def write_plots(out: Path, flight: Flight, result: FitResult,
                photo: Callable[[int], NDArray[np.uint8]] | None = None) -> None:
    """The figures of a fit (imports matplotlib only when called); ``photo`` (keyframe
    index -> its photo, :func:`turbinefit.jobs.sources.source_photos`): the reprojections
    are drawn over the photos, the heat-maps faint on top."""
    from turbinefit import plots

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
        geometry=geometry, timestamps=flight.timestamps, photo=photo)
    if flight.gt_world_T_cam is not None:
        plots.plot_pose_errors(out / "errors.png", flight.timestamps, flight.gt_world_T_cam,
                               initial=flight.world_T_cam, optimised=result.world_T_cam)
    if result.history:
        plots.plot_cost_history(out / "cost.png", [h.cost for h in result.history],
                                [h.stage for h in result.history])
