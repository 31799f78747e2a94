"""The ``mission`` job: one simulated inspection mission in the loop
(:func:`turbinefit.mission.run_mission`), written as the folders the other commands write,
and judged against the truth (:func:`turbinefit.mission.mission_outcome`).

:func:`mission_folder` writes, atomically, into ``out_dir``:

* ``flight/``: a flight folder of the mission's photos (the approach orbit's, then the
  inspection's): ``camera.yaml`` (the photos' camera), ``keyframes.txt`` (the poses the
  GNSS recorded), ``odometry.txt`` (the drone's odometry), ``keyframes_sigma.csv`` (with
  RTK), ``heatmaps/`` (as the tracker read them), ``images/``, ``turbine.yaml`` (the
  typed-in turbine), ``groundtruth.txt``, ``turbine_groundtruth.yaml``,
  ``defects_groundtruth.csv``, ``defect_boxes.csv``: ``turbinefit fit`` and ``track`` run
  on it as on any flight;
* ``track/``: what the tracker estimated in flight: ``causal.txt`` (each photo's pose when
  it arrived, TUM), ``keyframes.txt`` and ``turbine.yaml`` (its final estimates),
  ``latency.csv`` (each update's time, detection included);
* ``fit/``: ``turbinefit fit`` of ``flight/`` (the mission's options);
* ``coverage/``: ``turbinefit coverage`` of ``fit/`` at the camera's full size, the defect
  boxes located and scored (``damage.csv``, ``summary.json``'s ``damage_score``);
* ``plan/``: the first plan as ``plan`` writes it (``waypoints.csv``, ``keyframes.txt``
  of its photos, ``turbine.yaml`` it was made for); ``path.csv``: every position flown
  (``index, true_x..z, recorded_x..z, believed_x..z``);
* ``mission.json``: the configuration and the figures (coverage per blade side at the GSD,
  the closest true approach to the rotor and the tower, replans, the estimate's errors,
  the defects located from the fit and without turbinefit, timings).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.flight import Flight
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.inspection.clearance import solid_samples
from turbinefit.inspection.plan import PlanError, check_margin
from turbinefit.inspection.surface import TurbineSurface
from turbinefit.io.atomic import atomic_output_dir, write_text_atomic
from turbinefit.io.defects import format_defect_boxes_csv, format_defects_csv
from turbinefit.io.flight_folder import DEFECT_BOXES_FILE, DEFECTS_FILE, write_flight
from turbinefit.io.heatmap_files import keyframe_stem
from turbinefit.io.quantities import Quantity
from turbinefit.io.tum import format_tum
from turbinefit.io.turbine_yaml import format_turbine_yaml
from turbinefit.jobs.coverage import coverage_folder
from turbinefit.jobs.fit import fit_folder
from turbinefit.jobs.outputs import OVERWRITE_HINT, summary_json
from turbinefit.jobs.plan import format_waypoints_csv, photo_poses
from turbinefit.mission import Mission, MissionConfig, MissionOutcome, mission_outcome, run_mission
from turbinefit.mission.outcome import final_start
from turbinefit.sim.turbines import PRESETS as TURBINE_PRESETS
from turbinefit.turbine.model import TurbineParams

#: ``--standoff`` [m]: ``plan``'s range.
STANDOFF = Quantity("stand-off", "m", 3.0, 100.0)
#: ``--gsd`` [mm/px].
GSD = Quantity("resolution", "mm/px", 0.0, 100.0, lo_open=True)
#: ``--defects``: how many known defects are painted.
DEFECTS = Quantity("defects", "", 0, 200, integer=True)
#: ``--photo-width`` [px]: the photos rendered (the camera scaled to it).
PHOTO_WIDTH = Quantity("photo width", "px", 64, 2000, integer=True)
#: ``--max-photos``: a short mission.
MAX_PHOTOS = Quantity("photos", "", 1, 100_000, integer=True)
#: ``--max-gimbal-up`` [deg].
GIMBAL_UP = Quantity("largest upward gimbal pitch", "deg", 0.0, 90.0)

#: What a mission folder holds (what ``--overwrite`` may replace).
MISSION_ENTRIES = frozenset({"flight", "track", "fit", "coverage", "plan", "path.csv",
                             "mission.json"})
MISSION_FILE = "mission.json"


@dataclass
class MissionReport:
    """What :func:`mission_folder` did: the mission, its figures, where they were written
    and what ``mission.json`` holds."""

    mission: Mission
    outcome: MissionOutcome
    out_dir: Path
    summary: dict[str, Any]


def _foreign(folder: Path) -> str | None:
    for entry in folder.iterdir():
        if entry.name not in MISSION_ENTRIES:
            return f"{entry.name!r} is not an output of turbinefit mission"
    return None


def check_mission(config: MissionConfig) -> None:
    """Refuse a mission that cannot be flown before flying it: a camera that cannot reach
    the GSD at the stand-off (naming the focal length that would).

    Raises:
        InputError: naming the option.
    """
    STANDOFF.check(config.standoff, field="--standoff")
    GSD.check(config.gsd_mm, field="--gsd")
    margin = check_margin(solid_samples(TurbineSurface(_nominal(config))))
    f = math.sqrt(config.camera.fx * config.camera.fy)
    flown = config.standoff + margin
    if 1000.0 * flown / f > config.gsd_mm * (1 + 1e-9):
        raise InputError(
            f"the camera (focal length {f:.0f} px) reaches {1000.0 * flown / f:.2f} mm/px at a "
            f"stand-off of {config.standoff:g} m, coarser than {config.gsd_mm:g} mm/px: a "
            f"focal length of at least {1000.0 * flown / config.gsd_mm:.0f} px would reach it",
            field="--camera")


def _nominal(config: MissionConfig) -> TurbineParams:
    """The turbine type's nominal dimensions (its pose does not matter here)."""
    return TURBINE_PRESETS[config.turbine]


def _tum(kfs: list[Any], which: str) -> str:
    poses = SE3(np.stack([getattr(k, which).wxyz_xyz for k in kfs]).reshape(-1, 7))
    return format_tum(np.array([k.timestamp for k in kfs]), poses)


def _flight(mission: Mission) -> tuple[Flight, list[tuple[str, int, int, str, Any, str]]]:
    """The mission's photos as a flight (the maps' camera), and its defect-box rows."""
    cfg = mission.config
    kfs = mission.keyframes
    poses = SE3(np.stack([k.recorded.wxyz_xyz for k in kfs]))
    odo = None
    if kfs[0].odometry is not None:
        odo = SE3(np.stack([k.odometry.wxyz_xyz for k in kfs]))  # type: ignore[union-attr]
    flight = Flight(camera=cfg.map_camera(), timestamps=np.array([k.timestamp for k in kfs]),
                    world_T_cam=poses, heatmaps=HeatmapStack(np.stack([k.heatmaps for k in kfs])),
                    turbine=mission.typed_in, odometry=odo,
                    gt_world_T_cam=SE3(np.stack([k.true.wxyz_xyz for k in kfs])),
                    gt_turbine=mission.truth,
                    position_sigma=np.stack([k.position_sigma for k in kfs])
                    if cfg.gnss == "rtk" else None)
    cam = cfg.photo_camera()
    rows = [(keyframe_stem(k.timestamp) + ".png", cam.width, cam.height, b.kind, b.box,
             b.defect) for k in kfs for b in k.boxes]
    return flight, rows


def _path_csv(mission: Mission) -> str:
    lines = ["index,true_x,true_y,true_z,recorded_x,recorded_y,recorded_z,believed_x,"
             "believed_y,believed_z"]
    for i, (t, r, b) in enumerate(zip(mission.path_true, mission.path_recorded,
                                      mission.path_estimated, strict=True)):
        lines.append(",".join([str(i), *(f"{v:.4f}" for v in (*t, *r, *b))]))
    return "\n".join(lines) + "\n"


def _latency_csv(mission: Mission) -> str:
    rows = [f"{k.timestamp:.6f},{1000.0 * (k.update_s or 0.0):.3f}" for k in mission.inspection]
    return "\n".join(["timestamp,latency_ms", *rows]) + "\n"


def mission_summary(mission: Mission, outcome: MissionOutcome) -> dict[str, Any]:
    """What ``mission.json`` holds."""
    cfg = mission.config
    updates = np.array([k.update_s for k in mission.inspection if k.update_s is not None])
    config = {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)
              if f.name not in ("camera", "tracker", "initial_error")}
    config["camera"] = {"width": cfg.camera.width, "height": cfg.camera.height,
                        "fx": cfg.camera.fx, "fy": cfg.camera.fy}
    config["initial_error"] = dataclasses.asdict(cfg.initial_error)
    return {
        "turbinefit": __version__, "config": config,
        "photos": {"orbit": len(mission.keyframes) - len(mission.inspection),
                   "inspection": len(mission.inspection)},
        "replans": mission.replans, "replans_refused": mission.replan_failures,
        "initial_turbine": mission.init_note,
        "tracker_update_ms": {
            "median": float(1000 * np.median(updates)) if updates.size else None,
            "p90": float(1000 * np.percentile(updates, 90)) if updates.size else None,
            "max": float(1000 * updates.max()) if updates.size else None},
        **outcome.summary(),
        "timings_s": {**{k: round(v, 3) for k, v in mission.timings.items()},
                      **{f"outcome_{k}": round(v, 3) for k, v in outcome.timings.items()}},
    }


def mission_folder(out_dir: str | os.PathLike[str], config: MissionConfig, *,
                   overwrite: bool = False, plots: bool = True,
                   progress: Callable[[str, int, int], None] | None = None) -> MissionReport:
    """Simulate one mission and write it to ``out_dir`` (module docstring).

    Raises:
        InputError: a bad ``out_dir`` or a mission that cannot be flown (checked first);
            nothing is written.
    """
    out = Path(out_dir)
    from turbinefit.io.atomic import check_output_dir, reserve_output

    check_output_dir(out, overwrite, _foreign, OVERWRITE_HINT)
    reserve_output(out)
    check_mission(config)
    t0 = time.perf_counter()
    try:
        mission = run_mission(config, progress)
    except PlanError as e:
        raise InputError(str(e), field=f"--{e.option.replace('_', '-')}") from None
    t_run = time.perf_counter() - t0
    flight, rows = _flight(mission)
    with atomic_output_dir(out, overwrite=overwrite, may_replace=_foreign,
                           overwrite_hint=OVERWRITE_HINT) as tmp:
        images = [k.image for k in mission.keyframes if k.image is not None]
        write_flight(flight, tmp / "flight",
                     images=images if len(images) == len(mission.keyframes) else None,
            camera=config.photo_camera(), camera_name="turbinefit mission",
            extra_texts={DEFECTS_FILE: format_defects_csv(mission.defects),
                         DEFECT_BOXES_FILE: format_defect_boxes_csv(rows)})
        track = tmp / "track"
        track.mkdir()
        write_text_atomic(track / "causal.txt", _tum(
            [k for k in mission.keyframes if k.causal is not None], "causal"), fsync=False)
        final = mission.tracker.world_T_cam()
        write_text_atomic(track / "keyframes.txt", format_tum(
            np.array([k.timestamp for k in mission.keyframes]), final), fsync=False)
        write_text_atomic(track / "turbine.yaml", format_turbine_yaml(
            mission.tracker.turbine, comment="turbinefit mission: the tracker's final "
            "estimate"), fsync=False)
        write_text_atomic(track / "latency.csv", _latency_csv(mission), fsync=False)
        poses, turbine = final_start(mission)
        report = fit_folder(tmp / "flight", tmp / "fit",
                            config.final_fit_config(mission.known_pitch), plots=plots,
                            initial_poses=poses, initial_turbine=turbine)
        outcome = mission_outcome(mission, report.result)
        coverage_folder(tmp / "fit", tmp / "coverage", flight_dir=tmp / "flight",
                        camera=config.camera, max_gsd_mm=config.gsd_mm,
                        blade_pitch=mission.shape.blade_pitch,
                        blade_twist=mission.shape.blade_twist,
                        damage=tmp / "flight" / DEFECT_BOXES_FILE if rows else None,
                        truth=tmp / "flight" / DEFECTS_FILE if rows else None, plots=plots)
        first = mission.plans[0]
        (tmp / "plan").mkdir()
        write_text_atomic(tmp / "plan" / "waypoints.csv", format_waypoints_csv(first),
                          fsync=False)
        write_text_atomic(tmp / "plan" / "keyframes.txt", format_tum(
            np.arange(len(first.photos), dtype=np.float64), photo_poses(first)), fsync=False)
        write_text_atomic(tmp / "plan" / "turbine.yaml", format_turbine_yaml(
            mission.plan_turbines[0],
            comment="turbinefit mission: the turbine the first plan was made for"),
            fsync=False)
        write_text_atomic(tmp / "path.csv", _path_csv(mission), fsync=False)
        summary = mission_summary(mission, outcome)
        summary["timings_s"]["mission"] = round(t_run, 3)
        write_text_atomic(tmp / MISSION_FILE, summary_json(summary), fsync=False)
    return MissionReport(mission, outcome, out, json.loads(summary_json(summary)))


