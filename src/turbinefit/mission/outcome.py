"""What a simulated mission achieved (:func:`mission_outcome`), judged against the truth:

* **coverage**: per blade side (and tower face), the fraction of its span the mission's
  photos show at the GSD asked for or finer, from the photos' *true* poses, the true
  turbine and the camera at its full size (:func:`~turbinefit.inspection.coverage.flight_coverage`);
* **safety**: the closest the *true* path came to the blades and the spinner, and to the
  tower and the nacelle, waypoints and the straight legs between them
  (:func:`~turbinefit.inspection.clearance.path_clearance`);
* **the estimate**: a batch fit of all the mission's keyframes from their recorded poses
  and the tracker's final turbine (what ``turbinefit fit`` of the flight gives), and the
  tracker's final and on-arrival poses, against the truth: positions in the world frame
  and in the turbine's own frame (what placing a defect on a blade depends on);
* **defects**: every box of a known defect in view located on the turbine
  (:func:`~turbinefit.inspection.surface.locate_box`) and scored against its truth
  (:func:`~turbinefit.eval.damage.score_damage`), from the fit's poses and turbine, and
  from what an operator has without turbinefit: the recorded GNSS poses and the typed-in
  turbine.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.edges import PhotoStack
from turbinefit.eval.damage import DamageScore, score_damage
from turbinefit.eval.metrics import accuracy
from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.inspection.clearance import ROTOR, STRUCTURE, path_clearance, solid_samples
from turbinefit.inspection.coverage import COVERED_PARTS, flight_coverage, side_names
from turbinefit.inspection.surface import PARTS, SurfaceShape, TurbineSurface, locate_box
from turbinefit.io.defects import LocatedDamage
from turbinefit.mission.loop import Keyframe, Mission, grey_photo
from turbinefit.mission.replan import plausible
from turbinefit.solver.fit import FitResult, fit
from turbinefit.turbine.model import TurbineParams

FloatArray = NDArray[np.float64]


def turbine_frame(world_T_cam: SE3, turbine: TurbineParams) -> FloatArray:
    """Camera positions (N, 3) in the turbine's own frame: origin at the base, x along the
    heading (the rotor's axis, downwind to upwind), z up [m]."""
    c, s = math.cos(turbine.heading), math.sin(turbine.heading)
    p = world_T_cam.translation.reshape(-1, 3) - np.array([turbine.base_x, turbine.base_y, 0.0])
    return np.stack([c * p[:, 0] + s * p[:, 1], -s * p[:, 0] + c * p[:, 1], p[:, 2]], axis=1)


@dataclass
class MissionOutcome:
    """The figures of a mission (module docstring); :meth:`summary` as plain numbers."""

    coverage: dict[str, dict[str, float]]
    least_side_coverage: float
    clearance_rotor_m: float
    clearance_structure_m: float
    estimate: dict[str, Any]
    damage: dict[str, Any]
    damage_baseline: dict[str, Any]
    fit: FitResult
    timings: dict[str, float]
    damage_score: DamageScore | None = None
    baseline_score: DamageScore | None = None

    def summary(self) -> dict[str, Any]:
        return {"coverage": self.coverage,
                "least_blade_side_coverage": self.least_side_coverage,
                "closest_true_approach_m": {"rotor": self.clearance_rotor_m,
                                            "tower_nacelle": self.clearance_structure_m},
                "estimate": self.estimate, "damage": self.damage,
                "damage_without_turbinefit": self.damage_baseline, "timings_s": self.timings}


def _poses(kfs: list[Keyframe], which: str) -> SE3:
    return SE3(np.stack([getattr(k, which).wxyz_xyz for k in kfs]).reshape(-1, 7))


def locate_defects(kfs: list[Keyframe], poses: SE3, turbine: TurbineParams,
                   camera: PinholeCamera, shape: SurfaceShape | None = None
                   ) -> list[LocatedDamage]:
    """Every defect box of the keyframes ``kfs`` located on ``turbine`` (of blades
    ``shape``) from ``poses`` (one per keyframe), as rows of ``damage.csv``."""
    surface = TurbineSurface(turbine, shape=shape or SurfaceShape())
    out = []
    for i, kf in enumerate(kfs):
        for b in kf.boxes:
            x0, y0, x1, y1 = (float(x) for x in b.box)
            loc = locate_box(surface, camera, poses[i], (x0, y0, x1, y1))
            area = float((b.box[2] - b.box[0]) * (b.box[3] - b.box[1]))
            out.append(LocatedDamage(f"{kf.index:04d}", kf.index, b.kind, loc.part, loc.side,
                                     loc.span_m, loc.chord, loc.distance_m, b.defect, area))
    return out


def final_start(mission: Mission) -> tuple[SE3 | None, TurbineParams]:
    """Where the final fit starts: the tracker's final poses and turbine if its turbine is
    plausible (:func:`~turbinefit.mission.replan.plausible`), else the recorded poses (None)
    and the typed-in turbine."""
    turbine = mission.tracker.turbine
    if plausible(turbine, mission.typed_in, mission.config.initial_error):
        return mission.tracker.world_T_cam(), turbine
    return None, mission.typed_in


def final_fit(mission: Mission) -> FitResult:
    """A batch fit of every keyframe of ``mission`` from the recorded poses (the tracker's
    options), started from :func:`final_start`, as ``turbinefit fit`` of the flight does."""
    kfs = mission.keyframes
    rtk = mission.config.gnss == "rtk"
    config = mission.config.final_fit_config(mission.known_pitch)
    flight = Flight(camera=mission.config.map_camera(),
                    timestamps=np.array([k.timestamp for k in kfs]),
                    world_T_cam=_poses(kfs, "recorded"),
                    heatmaps=HeatmapStack(np.stack([k.heatmaps for k in kfs])),
                    turbine=mission.typed_in,
                    odometry=_poses(kfs, "odometry") if kfs[0].odometry is not None else None,
                    gt_world_T_cam=_poses(kfs, "true"), gt_turbine=mission.truth,
                    position_sigma=np.stack([k.position_sigma for k in kfs]) if rtk else None,
                    photos=_photos(kfs, mission.config.map_camera().width)
                    if config.uses_photos else None)
    poses, turbine = final_start(mission)
    return fit(flight, config, initial_poses=poses, initial_turbine=turbine)


def _photos(kfs: list[Keyframe], map_width: int) -> PhotoStack | None:
    """The keyframes' grey photos (None unless every keyframe has one)."""
    grey = [grey_photo(k) for k in kfs]
    if not grey or any(g is None for g in grey):
        return None
    images = np.stack([g for g in grey if g is not None])
    return PhotoStack(images, images.shape[2] / map_width)


def mission_outcome(mission: Mission, result: FitResult | None = None) -> MissionOutcome:
    """The figures of ``mission`` (module docstring); ``result``: its final fit, if made
    already (:func:`final_fit`)."""
    t0 = time.perf_counter()
    cfg = mission.config
    truth = mission.truth
    insp = mission.inspection
    true_surface = TurbineSurface(truth, shape=mission.shape)
    cover: dict[str, dict[str, float]] = {}
    least = math.nan
    if insp:
        cov = flight_coverage(true_surface, cfg.camera, _poses(insp, "true"))
        fractions = []
        for g in cov.grids:
            fine = g.covered(cfg.gsd_mm)
            cover[PARTS[g.part]] = {n: round(float(fine[i]), 4)
                                    for i, n in enumerate(side_names(g.part))}
            if g.part < COVERED_PARTS.index("tower"):
                fractions += [float(v) for v in fine]
        least = min(fractions) if fractions else math.nan
    t_cov = time.perf_counter() - t0

    t0 = time.perf_counter()
    clear = path_clearance(mission.path_true, solid_samples(true_surface))
    rotor = clear.least(ROTOR)[0]
    structure = clear.least(STRUCTURE)[0]
    t_clear = time.perf_counter() - t0

    t0 = time.perf_counter()
    result = result if result is not None else final_fit(mission)
    t_fit = time.perf_counter() - t0
    gt = _poses(mission.keyframes, "true")
    est: dict[str, Any] = {}
    for name, poses, turbine in (
            ("recorded", _poses(mission.keyframes, "recorded"), mission.typed_in),
            ("tracker_final", mission.tracker.world_T_cam(), mission.tracker.turbine),
            ("fit", result.world_T_cam, result.turbine)):
        acc = accuracy(poses, turbine, gt, truth)
        rel = np.linalg.norm(turbine_frame(poses, turbine) - turbine_frame(gt, truth), axis=1)
        est[name] = {"position_m": acc.position_error_m,
                     "orientation_deg": acc.orientation_error_deg,
                     "model_points_m": acc.model_point_error_m,
                     "turbine_frame_position_m": float(np.mean(rel)),
                     "turbine_frame_position_p95_m": float(np.percentile(rel, 95))}
    est["fit"]["verdict"] = result.verdict
    causal = [k for k in insp if k.causal is not None]
    if causal:
        rel = np.linalg.norm(turbine_frame(_poses(causal, "causal"), mission.tracker.turbine)
                             - turbine_frame(_poses(causal, "true"), truth), axis=1)
        est["tracker_causal_turbine_frame_position_m"] = float(np.mean(rel))

    t0 = time.perf_counter()
    photo_cam = cfg.photo_camera()
    index = {k.index: i for i, k in enumerate(mission.keyframes)}
    fitted = SE3(result.world_T_cam.wxyz_xyz[[index[k.index] for k in insp]].reshape(-1, 7))
    damage = score_damage(locate_defects(insp, fitted, result.turbine, photo_cam,
                                         mission.shape), mission.defects)
    baseline = score_damage(locate_defects(insp, _poses(insp, "recorded"), mission.typed_in,
                                           photo_cam, mission.shape), mission.defects)
    t_dmg = time.perf_counter() - t0
    return MissionOutcome(cover, least, rotor, structure, est, damage.summary(),
                          baseline.summary(), result,
                          {"coverage": t_cov, "clearance": t_clear, "fit": t_fit,
                           "damage": t_dmg}, damage, baseline)
