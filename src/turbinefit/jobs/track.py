"""The ``track`` job: a flight folder replayed keyframe by keyframe through the in-flight
:class:`~turbinefit.solver.tracker.Tracker`, as a drone would feed it.

Each keyframe's heat-maps come from the flight's :class:`~turbinefit.jobs.sources.
HeatmapSource` as it arrives (read from ``heatmaps/`` or detected from its photo); the
tracker only ever sees heat-maps. A keyframe's latency is the wall time of getting its
heat-maps and of the tracker's update.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.eval.metrics import Accuracy, accuracy
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.io.atomic import write_text_atomic
from turbinefit.io.fit_config import format_tracker_config, tracker_config_dict
from turbinefit.io.flight_folder import FlightFolder, read_flight_folder
from turbinefit.io.georef import location_text, read_flight_georef, write_georef_outputs
from turbinefit.io.mesh import write_turbine_glb
from turbinefit.io.tum import write_tum
from turbinefit.io.turbine_yaml import write_turbine_yaml
from turbinefit.jobs.fit import FITTED_TURBINE_COMMENT
from turbinefit.jobs.init import InitSummary, estimate_turbine
from turbinefit.jobs.outputs import (
    TRACK_OUTPUTS,
    flight_inputs,
    plot_error,
    recorded_path,
    summary_json,
)
from turbinefit.jobs.sources import fit_config_for, grey_photos, open_heatmaps
from turbinefit.solver.tracker import KeyframeError, Tracker, TrackerConfig, TrackEstimate
from turbinefit.solver.verdict import ImageEvidence, Signals
from turbinefit.turbine.model import TurbineGeometry, TurbineParams, model_point_error

if TYPE_CHECKING:
    from turbinefit.detect import DetectOptions


@dataclass(frozen=True)
class LatencyStats:
    """Per-keyframe latency [ms]: median, 90th / 99th percentile, max, mean, and the slope
    of a least-squares line through latency against keyframe index [ms per 1000
    keyframes]; ``steady_slope`` is that slope after the window has filled (any growth
    left would come from the flight's length), None for a flight no longer than it."""

    median_ms: float
    p90_ms: float
    p99_ms: float
    max_ms: float
    mean_ms: float
    slope_ms_per_1000_keyframes: float
    steady_slope_ms_per_1000_keyframes: float | None = None

    @staticmethod
    def of(latency_ms: np.ndarray, window: int | None = None) -> LatencyStats | None:
        """The statistics of ``latency_ms`` (None if empty) with a sliding ``window``."""
        lat = np.asarray(latency_ms, dtype=np.float64)
        if lat.size == 0:
            return None

        def slope(v: np.ndarray) -> float:
            if v.size < 2:
                return 0.0
            return float(np.polyfit(np.arange(v.size, dtype=np.float64), v, 1)[0]) * 1000.0

        steady = (slope(lat[window:]) if window is not None and lat.size > window + 1
                  else None)
        return LatencyStats(float(np.median(lat)), float(np.percentile(lat, 90)),
                            float(np.percentile(lat, 99)), float(lat.max()), float(lat.mean()),
                            slope(lat), steady)

    def to_dict(self) -> dict[str, float]:
        d = {"median_ms": self.median_ms, "p90_ms": self.p90_ms, "p99_ms": self.p99_ms,
             "max_ms": self.max_ms, "mean_ms": self.mean_ms,
             "slope_ms_per_1000_keyframes": self.slope_ms_per_1000_keyframes}
        if self.steady_slope_ms_per_1000_keyframes is not None:
            d["steady_slope_ms_per_1000_keyframes"] = self.steady_slope_ms_per_1000_keyframes
        return d


@dataclass
class TrackSummary:
    """What ``summary.json`` of a track holds (:meth:`to_dict` is its layout).

    Attributes:
        flight, num_keyframes, heatmap_size, heatmaps: as for
            :class:`~turbinefit.jobs.fit.FitSummary`.
        config: the tracker's options.
        latency: statistics of the per-keyframe latency (None for no keyframes).
        iterations_mean: mean LM iterations per update.
        theta_prior_active_at_end: whether the start-up prior on theta still acted.
        initial_turbine, final_turbine: the turbine before and after.
        final_sigma: standard deviation of each turbine parameter at the end, by the
            batch fit's rule without the start-up prior (:meth:`Tracker.theta_covariance
            <turbinefit.solver.tracker.Tracker.theta_covariance>`; None if the
            information was singular).
        defaults: which fit defaults the options started from (None: a --config file or
            preset).
        initial, causal, final, final_without_back_substitution: accuracy of the initial
            poses, of each keyframe's estimate on arrival, of the final estimates and of
            those without moving marginalised keyframes (None without ground truth).
        verdict, reasons, signals: how far to trust the result
            (:mod:`turbinefit.solver.verdict`; the image signals are measured at each
            keyframe's estimate on arrival, the rest at the end).
    """

    flight: str
    num_keyframes: int
    heatmap_size: tuple[int, int]
    heatmaps: str
    config: TrackerConfig
    latency: LatencyStats | None
    iterations_mean: float
    theta_prior_active_at_end: bool
    initial_turbine: TurbineParams
    final_turbine: TurbineParams
    final_sigma: dict[str, float] | None = None
    initial: Accuracy | None = None
    causal: Accuracy | None = None
    final: Accuracy | None = None
    final_without_back_substitution: Accuracy | None = None
    defaults: str | None = None
    verdict: str = "ok"
    reasons: list[str] = dataclasses.field(default_factory=list)
    signals: Signals | None = None
    init: InitSummary | None = None

    def to_dict(self) -> dict[str, Any]:
        turbine: dict[str, Any] = {"initial": self.initial_turbine.to_dict(),
                                   "final": self.final_turbine.to_dict()}
        if self.final_sigma is not None:
            turbine["final_sigma"] = self.final_sigma
        out: dict[str, Any] = {
            "turbinefit_version": __version__,
            "flight": self.flight,
            "num_keyframes": self.num_keyframes,
            "heatmap_size": list(self.heatmap_size),
            "heatmaps": self.heatmaps,
            "config": tracker_config_dict(self.config),
            "latency": {} if self.latency is None else self.latency.to_dict(),
            "iterations_mean": self.iterations_mean,
            "theta_prior_active_at_end": self.theta_prior_active_at_end,
            "turbine": turbine,
            "verdict": self.verdict,
            "reasons": list(self.reasons),
            "signals": None if self.signals is None else self.signals.to_dict(),
            "turbine_init": None if self.init is None else self.init.to_dict(),
        }
        if self.defaults is not None:
            out["defaults"] = self.defaults
        if (self.initial is not None and self.causal is not None and self.final is not None
                and self.final_without_back_substitution is not None):
            out["accuracy"] = {
                "initial": self.initial.to_dict(), "causal": self.causal.to_dict(),
                "final": self.final.to_dict(),
                "final_without_back_substitution":
                    self.final_without_back_substitution.to_dict()}
        return out


@dataclass
class TrackReport:
    """What :func:`track_folder` did.

    Attributes:
        out_dir: where the outputs were written.
        estimates: the tracker's answer to each keyframe, in time order.
        world_T_cam: (N,) final estimates (window at its last, earlier keyframes moved
            with it by back-substitution).
        turbine: the final turbine.
        latency_ms: (N,) wall time of each keyframe (heat-maps and update) [ms].
        summary: what ``summary.json`` holds.
        theta_covariance: (7, 7) theta's covariance the verdict was made with (the batch
            fit's rule, :meth:`Tracker.theta_covariance
            <turbinefit.solver.tracker.Tracker.theta_covariance>`), or None.
    """

    out_dir: Path
    estimates: list[TrackEstimate]
    world_T_cam: SE3
    turbine: TurbineParams
    latency_ms: np.ndarray
    summary: TrackSummary
    theta_covariance: np.ndarray | None = None

    @property
    def causal(self) -> Accuracy | None:
        return self.summary.causal

    @property
    def final(self) -> Accuracy | None:
        return self.summary.final


def track_folder(
    flight_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: TrackerConfig | None = None,
    *,
    tracker_options: Mapping[str, Any] | None = None,
    options: Mapping[str, Any] | None = None,
    plots: bool = True,
    overwrite: bool = False,
    progress: Callable[[TrackEstimate, int], None] | None = None,
    config_path: str | os.PathLike[str] | None = None,
    from_images: bool | None = None,
    model: str | os.PathLike[str] | None = None,
    detect_options: DetectOptions | None = None,
) -> TrackReport:
    """Replay the flight in ``flight_dir`` keyframe by keyframe through a :class:`Tracker`.

    Writes into ``out_dir`` (atomically, checked as :func:`~turbinefit.jobs.fit.fit_folder`
    checks it): ``causal.txt`` (TUM: each keyframe's estimate when it arrived),
    ``keyframes.txt``, ``turbine.yaml`` and ``turbine.glb`` (the final estimates, as ``fit``
    writes them),
    ``latency.csv`` (``timestamp,latency_ms``), ``config.yaml``, ``summary.json``
    (:class:`TrackSummary`) and, unless ``plots=False``, ``latency.png``, ``errors.png``
    (with ground truth) and ``scene.png``.

    With photos (``images/`` and no ``heatmaps/``, or ``from_images``) each keyframe's photo
    is read and run through the CNN (ONNX ``model`` or the shipped one, with
    ``detect_options``) as it arrives; its latency includes detection.
    ``progress(estimate, total)`` is called after every keyframe. With an ``odometry.txt``
    its consecutive relative poses are the pairwise measurements (keyframes.txt gives the
    first keyframe's pose), as in the batch fit; ``pair_frame="auto"`` then resolves to
    ``estimated``, and the summary and ``config.yaml`` record the frame used.

    Options: ``config`` (None = the tracker's defaults, with the fit options measured best
    for the kind of heat-maps, :func:`turbinefit.jobs.sources.fit_config_for`), with the
    TrackerConfig fields of ``tracker_options`` and the FitConfig fields of ``options`` set
    on top.
    """
    flight_dir = Path(flight_dir)
    out = Path(out_dir)
    TRACK_OUTPUTS.check(out, flight_inputs(flight_dir, None if config_path is None
                                           else Path(config_path)), overwrite)
    folder = read_flight_folder(flight_dir)
    georef = read_flight_georef(flight_dir)
    source = open_heatmaps(folder, from_images, model, detect_options)
    fit_cfg = fit_config_for(source, None if config is None else config.fit, options)
    try:
        cfg = dataclasses.replace(config or TrackerConfig(), fit=fit_cfg,
                                  **(tracker_options or {}))
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), field="track options") from None
    n = folder.num_keyframes
    poses = folder.keyframes.poses
    buffered: list[np.ndarray] = []
    init = None
    initial_turbine = folder.turbine
    if initial_turbine is None:  # no turbine.yaml: from the first keyframes showing it
        init, buffered = _initialise(folder, source, flight_dir)
        initial_turbine = init.turbine
    tracker = Tracker(source.camera, initial_turbine, cfg)
    odometry = folder.odometry  # its steps are the pairwise measurements, if present
    photos = (grey_photos(flight_dir, folder.timestamps, source.camera)
              if fit_cfg.uses_photos else None)
    latency = np.empty(n)
    image: list[ImageEvidence] = []
    for k in range(n):
        t0 = time.perf_counter()
        maps = buffered[k] if k < len(buffered) else source.keyframe(k)
        try:
            est = tracker.update(float(folder.timestamps[k]), poses[k], maps,
                                 odometry=None if odometry is None else odometry[k],
                                 position_sigma=None if folder.position_sigma is None
                                 else folder.position_sigma[k],
                                 photo=None if photos is None else photos[0](k))
        except KeyframeError as exc:
            raise InputError(exc.reason, source.where(k)) from None
        latency[k] = (time.perf_counter() - t0) * 1e3
        image.append(tracker.arrival_evidence())
        if progress is not None:
            progress(est, n)
    cfg = tracker.config  # pair_frame="auto" resolved by the first keyframe
    final_poses = tracker.world_T_cam()
    causal_poses = tracker.causal_world_T_cam()
    turbine = tracker.turbine
    summary = TrackSummary(
        recorded_path(flight_dir, out), n, (source.camera.width, source.camera.height),
        (f"{source.description} (as each keyframe arrives; its latency includes detection)"
         if source.detects else source.description),
        cfg, LatencyStats.of(latency, cfg.window),
        float(np.mean([e.iterations for e in tracker.estimates])),
        tracker.theta_prior_active, initial_turbine, turbine,
        defaults=None if config is not None else source.defaults_name, init=init)
    verdict = tracker.assess(ImageEvidence.concat(image), poses,
                             poses if odometry is None else odometry)
    if verdict.theta_std is not None:
        summary.final_sigma = dict(zip(TurbineParams.NAMES, verdict.theta_std.tolist(),
                                       strict=True))
    summary.signals = verdict.signals
    summary.verdict, summary.reasons = verdict.verdict, verdict.reasons
    geometry = cfg.fit.geometry
    gt_poses, gt_turbine = folder.gt_world_T_cam, folder.gt_turbine
    if gt_poses is not None and gt_turbine is not None:
        summary.initial = accuracy(poses, initial_turbine, gt_poses, gt_turbine, geometry)
        summary.causal = accuracy(causal_poses, turbine, gt_poses, gt_turbine, geometry)
        summary.final = accuracy(final_poses, turbine, gt_poses, gt_turbine, geometry)
        summary.final_without_back_substitution = accuracy(
            tracker.world_T_cam(back_substitution=False), turbine, gt_poses, gt_turbine,
            geometry)
    with TRACK_OUTPUTS.writing(out, overwrite) as tmp:
        write_tum(tmp / "causal.txt", folder.timestamps, causal_poses,
                  comment="turbinefit track: each keyframe's estimate when it arrived")
        write_tum(tmp / "keyframes.txt", folder.timestamps, final_poses)
        write_turbine_yaml(tmp / "turbine.yaml", turbine, comment=FITTED_TURBINE_COMMENT,
                           std=summary.final_sigma, extra=location_text(georef, turbine))
        write_georef_outputs(tmp, georef, folder.timestamps, final_poses)
        write_turbine_glb(tmp / "turbine.glb", turbine, geometry, georef)
        rows = "".join(f"{t:.6f},{ms:.3f}\n" for t, ms in zip(folder.timestamps, latency,
                                                               strict=True))
        write_text_atomic(tmp / "latency.csv", "timestamp,latency_ms\n" + rows, fsync=False)
        write_text_atomic(tmp / "config.yaml", format_tracker_config(cfg), fsync=False)
        write_text_atomic(tmp / "summary.json", summary_json(summary), fsync=False)
        if plots:
            try:
                _track_plots(tmp, folder, final_poses, causal_poses, initial_turbine, turbine,
                             latency, geometry)
            except OSError as exc:
                raise plot_error(exc, out) from exc
    return TrackReport(out, list(tracker.estimates), final_poses, turbine, latency, summary,
                       verdict.theta_covariance)


def _track_plots(out: Path, folder: FlightFolder, final_poses: SE3, causal_poses: SE3,
                 initial_turbine: TurbineParams, turbine: TurbineParams, latency: np.ndarray,
                 geometry: TurbineGeometry) -> None:
    from turbinefit import plots

    initial = folder.keyframes.poses
    plots.plot_latency(out / "latency.png", latency)
    plots.plot_scene(
        out / "scene.png", initial_poses=initial, optimised_poses=final_poses,
        initial_turbine=initial_turbine, optimised_turbine=turbine,
        gt_poses=folder.gt_world_T_cam, gt_turbine=folder.gt_turbine, geometry=geometry)
    if folder.gt_world_T_cam is not None:
        plots.plot_pose_errors(out / "errors.png", folder.timestamps, folder.gt_world_T_cam,
                               initial=initial, optimised=final_poses, causal=causal_poses)


#: The tracker from nothing tries ``init`` every this many keyframes ...
INIT_EVERY = 10
#: ... and starts when two successive estimates agree to within this [m] (mean distance
#: of the model points), or at this many keyframes with the last estimate.
INIT_AGREE_M = 1.5
INIT_MAX_KEYFRAMES = 100


def _initialise(folder: FlightFolder, source: Any, flight_dir: Path
                ) -> tuple[InitSummary, list[np.ndarray]]:
    """The initial turbine of a flight without ``turbine.yaml``, from its first keyframes:
    ``init`` on the first 10, 20, ... keyframes until two successive estimates agree
    (:data:`INIT_AGREE_M`); returns it and the keyframes' maps read so far (the tracker
    then replays them)."""
    n = folder.num_keyframes
    poses = folder.keyframes.poses
    maps: list[np.ndarray] = []
    last: InitSummary | None = None
    while len(maps) < n:
        maps.append(np.asarray(source.keyframe(len(maps))))
        k = len(maps)
        if k % INIT_EVERY and k < n:
            continue
        try:
            est = estimate_turbine(HeatmapStack(maps), source.camera, poses[:k],
                                   where=flight_dir, gt_turbine=folder.gt_turbine)
        except InputError:
            if k == n:
                raise
            continue
        if ((last is not None and model_point_error(est.turbine, last.turbine) < INIT_AGREE_M)
                or k >= min(n, INIT_MAX_KEYFRAMES)):
            return est, maps
        last = est
    assert last is not None  # the last attempt (k == n) returned or raised
    return last, maps
