"""Precision beyond the net: what tie points between consecutive photos and the turbine's
silhouette edges at the photo's resolution measure, and what they do to fits from photos.

For each flight (320 x 240 photos: ``--seeds``, the flights of ``bench_defaults.py``;
1280 x 960 photos: ``--seeds-1280``, those of ``bench_resolution.py --photos``):

* **tie points** (:mod:`turbinefit.tiepoints`, photos matched at their own size up to
  1280 px): the share of consecutive pairs with a measurement; the median error of the
  relative rotation and of the direction of motion against the truth, beside the
  GPS/IMU steps' (the pairwise term's measurements); the median of the errors' squared
  Mahalanobis norm under the inliers' own information (5 if it were right) before the
  inflation of :class:`~turbinefit.tiepoints.TiePointOptions`;
* **edges** (``--edges``; :mod:`turbinefit.costs.edges`): at the true poses and turbine,
  the median distance along the normal of the net's line correspondences and of the
  silhouette midpoints from the true lines, tower and blades, in map px;
* **fits** from the photos' detected maps with the photo defaults (``fit`` with no
  options), then with the tie-point term (``lambda_motion`` 1), with motions of the true
  trajectory at given standard deviations instead ("oracle", rotation / direction
  [deg]: what tie points would need to measure), and with ``--edges`` the edge term
  (``lambda_edges`` 1; slow: minutes a flight): mean position / model-point error and
  the mean error of the camera positions in the fitted turbine's own frame against the
  true ones in the true turbine's [m].

Usage::

    python benchmarks/bench_precision.py [--seeds 0] [--seeds-1280 20] [--edges]

Writes ``benchmarks/results/bench_precision.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Any

import numpy as np
from common import RESULTS, write_json

from turbinefit.costs.edges import PhotoStack
from turbinefit.costs.pairwise import relative_poses
from turbinefit.costs.projection import project_points
from turbinefit.costs.relative_motion import RelativeMotions, relative_motion_residuals
from turbinefit.costs.robust import RobustLoss
from turbinefit.eval.metrics import accuracy
from turbinefit.flight import Flight
from turbinefit.geometry.se3 import SE3, quat_conjugate, quat_exp, quat_multiply
from turbinefit.io.flight_folder import FlightFolder, keyframe_images, read_flight_folder
from turbinefit.io.images import read_image, resize_image
from turbinefit.jobs.sources import PhotoHeatmaps, fit_config_for
from turbinefit.solver import fit
from turbinefit.solver.problem import FitProblem
from turbinefit.tiepoints import TiePointOptions, measure_motions
from turbinefit.turbine.model import TurbineParams

#: Oracle motions: (rotation, direction) standard deviations [deg].
ORACLES = ((0.02, 0.5), (0.05, 2.0), (0.2, 0.5), (0.02, 20.0))
#: Photos are matched and searched for edges at most this wide [px].
MAX_WIDTH = 1280


def _angles_deg(q: np.ndarray) -> np.ndarray:
    return np.degrees(2 * np.arcsin(np.minimum(1.0, np.linalg.norm(q[..., 1:], axis=-1))))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def turbine_frame(poses: SE3, turbine: TurbineParams) -> np.ndarray:
    """Camera positions in the turbine's own frame (base at the origin, x along heading)."""
    c, s = np.cos(turbine.heading), np.sin(turbine.heading)
    p = poses.translation - np.array([turbine.base_x, turbine.base_y, 0.0])
    return np.stack([c * p[:, 0] + s * p[:, 1], -s * p[:, 0] + c * p[:, 1], p[:, 2]], axis=1)


def errors(flight: Flight, poses: SE3, turbine: TurbineParams) -> dict[str, float]:
    gt, gt_t = flight.gt_world_T_cam, flight.gt_turbine
    assert gt is not None and gt_t is not None
    a = accuracy(poses, turbine, gt, gt_t)
    tf = np.linalg.norm(turbine_frame(poses, turbine) - turbine_frame(gt, gt_t), axis=1)
    return {"position_m": a.position_error_m, "model_point_m": a.model_point_error_m,
            "turbine_frame_m": float(tf.mean())}


def grey_photos(folder: FlightFolder) -> np.ndarray:
    """The flight's photos in grey levels, at most :data:`MAX_WIDTH` wide."""
    import cv2

    cam = folder.camera.at_most(MAX_WIDTH)
    size = (cam.width, cam.height)
    paths = keyframe_images(folder.root, folder.timestamps)
    return np.stack([cv2.cvtColor(resize_image(read_image(p, reduce_to=size), *size),
                                  cv2.COLOR_RGB2GRAY) for p in paths])


def motion_quality(folder: FlightFolder, motions: RelativeMotions,
                   raw: RelativeMotions) -> dict[str, float]:
    """Tie points' and GPS/IMU steps' errors against the truth (module docstring)."""
    gt, meas = folder.gt_world_T_cam, folder.keyframes.poses
    assert gt is not None
    rel, rel_m = relative_poses(gt[:-1], gt[1:]), relative_poses(meas[:-1], meas[1:])
    v = motions.valid[1:]
    rot_v = _angles_deg(quat_multiply(motions.i_q_j[1:], quat_conjugate(rel.wxyz)))[v]
    rot_g = _angles_deg(quat_multiply(rel_m.wxyz, quat_conjugate(rel.wxyz)))
    d = _unit(rel.translation)
    dir_v = np.degrees(np.arccos(np.clip(np.sum(motions.i_dir_j[1:] * d, 1), -1, 1)))[v]
    dir_g = np.degrees(np.arccos(np.clip(np.sum(_unit(rel_m.translation) * d, 1), -1, 1)))
    r, _, _, _ = relative_motion_residuals(gt[:-1], gt[1:], raw.i_q_j[1:], raw.i_dir_j[1:],
                                           raw.sqrt_info[1:], RobustLoss(), False)
    nees = np.sum(r * r, axis=1)[raw.valid[1:]]
    nan = float("nan")
    return {"measured_share": float(v.mean()),
            "inliers_median": float(np.median(motions.inliers[1:][v])) if v.any() else 0.0,
            "rotation_deg_tiepoints": float(np.median(rot_v)) if v.any() else nan,
            "rotation_deg_gps_imu": float(np.median(rot_g)),
            "direction_deg_tiepoints": float(np.median(dir_v)) if v.any() else nan,
            "direction_deg_gps_imu": float(np.median(dir_g)),
            "nees_median_uninflated": float(np.median(nees)) if nees.size else nan}


def oracle_motions(gt: SE3, sigma_rot_deg: float, sigma_dir_deg: float) -> RelativeMotions:
    """Motions of the true trajectory with Gaussian errors of these standard deviations."""
    rng = np.random.default_rng(1)
    n = len(gt)
    rel = relative_poses(gt[:-1], gt[1:])
    m = RelativeMotions.none(n)
    m.i_q_j[1:] = quat_multiply(quat_exp(rng.normal(0, np.radians(sigma_rot_deg), (n - 1, 3))),
                                rel.wxyz)
    m.i_dir_j[1:] = _unit(_unit(rel.translation)
                          + rng.normal(0, np.radians(sigma_dir_deg), (n - 1, 3)))
    m.sqrt_info[1:] = np.diag([1 / np.radians(sigma_rot_deg)] * 3
                              + [1 / np.radians(sigma_dir_deg)] * 2)
    m.valid[1:] = True
    return m


def edge_quality(flight: Flight, cfg: Any) -> dict[str, float]:
    """Net's line correspondences and silhouette midpoints against the true lines."""
    gt, gt_t = flight.gt_world_T_cam, flight.gt_turbine
    assert gt is not None and gt_t is not None
    prob = FitProblem(flight, dataclasses.replace(cfg, lambda_edges=1.0))
    th = gt_t.to_vector()
    corr = prob.find_correspondences(gt, th)
    assert corr.line_target is not None and corr.line_found is not None
    assert corr.edge_target is not None and corr.edge_found is not None
    assert corr.line_normal is not None
    _, lns = prob.model(th, False, corr.line_fractions)
    uv = project_points(flight.camera, gt, lns.points(), None, with_jacobian=False).uv
    out = {}
    for part, sel in (("tower", prob._line_index == 0), ("blades", prob._line_index >= 2)):
        nrm = corr.line_normal[:, sel]
        for what, tgt, found in (("net", corr.line_target, corr.line_found),
                                 ("edges", corr.edge_target, corr.edge_found)):
            d = np.abs(np.sum((tgt[:, sel] - uv[:, sel]) * nrm, -1))[found[:, sel]]
            out[f"{part}_{what}_median_px"] = float(np.median(d)) if d.size else float("nan")
            out[f"{part}_{what}_found"] = int(found[:, sel].sum())
    return out


def run_flight(folder: FlightFolder, edges: bool) -> dict[str, Any]:
    source = PhotoHeatmaps(folder)
    t0 = time.perf_counter()
    flight = folder.flight(source.stack(), source.camera)
    cfg = fit_config_for(source)
    photos = grey_photos(folder)
    cam = folder.camera.at_most(MAX_WIDTH)
    opts = TiePointOptions(max_width=MAX_WIDTH)
    raw = measure_motions(lambda k: photos[k], len(photos), cam,
                          dataclasses.replace(opts, inflation=1.0))
    # the same measurements with the default inflation (it only scales the information)
    motions = dataclasses.replace(raw, sqrt_info=raw.sqrt_info / np.sqrt(opts.inflation))
    row: dict[str, Any] = {"flight": folder.root.name, "load_s": time.perf_counter() - t0,
                           "tie_points": motion_quality(folder, motions, raw)}
    gt = flight.gt_world_T_cam
    assert gt is not None
    fits = {"photo defaults": (flight, cfg),
            "tie points": (dataclasses.replace(flight, motions=motions),
                           dataclasses.replace(cfg, lambda_motion=1.0))}
    for sr, sd in ORACLES:
        fits[f"oracle {sr:g} / {sd:g} deg"] = (
            dataclasses.replace(flight, motions=oracle_motions(gt, sr, sd)),
            dataclasses.replace(cfg, lambda_motion=1.0))
    if edges:
        with_photos = dataclasses.replace(flight, photos=PhotoStack(
            photos, photos.shape[2] / flight.camera.width))
        row["edges"] = edge_quality(with_photos, cfg)
        fits["edges"] = (with_photos, dataclasses.replace(cfg, lambda_edges=1.0))
    row["fits"] = {}
    for name, (fl, c) in fits.items():
        res = fit(fl, c)
        row["fits"][name] = {**errors(fl, res.world_T_cam, res.turbine),
                             "verdict": res.verdict}
        e = row["fits"][name]
        print(f"  {folder.root.name} {name:26s} position {e['position_m']:.3f} m, model points "
              f"{e['model_point_m']:.3f} m, turbine frame {e['turbine_frame_m']:.3f} m, "
              f"{e['verdict']}", flush=True)
    print(f"  {folder.root.name} tie points: {row['tie_points']}", flush=True)
    if edges:
        print(f"  {folder.root.name} edges: {row['edges']}", flush=True)
    return row


def main() -> None:
    from bench_defaults import simulate
    from bench_resolution import photo_flight

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="*", default=[0])
    ap.add_argument("--seeds-1280", type=int, nargs="*", default=[20])
    ap.add_argument("--keyframes", type=int, default=200)
    ap.add_argument("--edges", action="store_true", help="also the edge term (slow)")
    ap.add_argument("--out", default=str(RESULTS / "bench_precision.json"))
    args = ap.parse_args()
    rows = []
    for seed in args.seeds:
        rows.append(run_flight(read_flight_folder(simulate(seed, args.keyframes)), args.edges))
    for seed in args.seeds_1280:
        rows.append(run_flight(read_flight_folder(photo_flight(seed, args.keyframes)),
                               args.edges))
    write_json(__import__("pathlib").Path(args.out), {"flights": rows})


if __name__ == "__main__":
    main()
