"""The tie-point term in the fit and the tracker: relative motions of the true trajectory
(rotation and direction of motion, as tie points measure them) given to a simulated
flight pull the fitted poses towards the truth; off by default (lambda_motion 0), and a
flight's motions never change a fit that does not weigh them."""

import dataclasses

import numpy as np
import pytest
from support import simulated_flight

from turbinefit.costs.pairwise import relative_poses
from turbinefit.costs.relative_motion import RelativeMotions
from turbinefit.flight import Flight
from turbinefit.geometry.se3 import pose_errors
from turbinefit.solver import FitConfig, Tracker, TrackerConfig, fit
from turbinefit.solver.tracker import KeyframeError

N = 40
CONFIG = FitConfig(lines="corr", line_residual="normal", robust="cauchy", lambda_motion=1.0)


def true_motions(flight: Flight, sigma_rot_deg: float = 0.02,
                 sigma_dir_deg: float = 0.2) -> RelativeMotions:
    gt = flight.gt_world_T_cam
    assert gt is not None
    rel = relative_poses(gt[:-1], gt[1:])
    m = RelativeMotions.none(len(gt))
    m.i_q_j[1:] = rel.wxyz
    m.i_dir_j[1:] = rel.translation / np.linalg.norm(rel.translation, axis=-1, keepdims=True)
    m.sqrt_info[1:] = np.diag([1 / np.radians(sigma_rot_deg)] * 3
                              + [1 / np.radians(sigma_dir_deg)] * 2)
    m.valid[1:] = True
    return m


def position_error(poses, flight: Flight) -> float:
    assert flight.gt_world_T_cam is not None
    return float(pose_errors(poses, flight.gt_world_T_cam)[0].mean())


def test_fit_with_true_motions_is_nearer_the_truth() -> None:
    f = simulated_flight(N, seed=2)
    with_m = dataclasses.replace(f, motions=true_motions(f))
    plain = position_error(fit(f, CONFIG).world_T_cam, f)
    moved = position_error(fit(with_m, CONFIG).world_T_cam, f)
    assert moved < 0.8 * plain
    # off by default: the same fit as without motions
    off = dataclasses.replace(CONFIG, lambda_motion=0.0)
    assert position_error(fit(with_m, off).world_T_cam, f) == pytest.approx(
        position_error(fit(f, off).world_T_cam, f), abs=1e-9)


def test_tracker_takes_one_motion_per_keyframe() -> None:
    f = simulated_flight(N, seed=2)
    motions = true_motions(f)
    errors = []
    for use in (False, True):
        tracker = Tracker(f.camera, f.turbine, TrackerConfig(fit=CONFIG, window=10))
        for k in range(N):
            m = motions.take(np.array([k])) if use and k > 0 else None
            if m is not None:
                m = RelativeMotions(m.i_q_j, m.i_dir_j, m.sqrt_info, np.array([True]), m.inliers)
            tracker.update(float(f.timestamps[k]), f.world_T_cam[k], f.heatmaps[k], motion=m)
        tracker.finish()
        errors.append(position_error(tracker.world_T_cam(), f))
    assert errors[1] < 0.8 * errors[0]
    with pytest.raises(KeyframeError, match="one entry"):
        tracker.update(float(f.timestamps[-1]) + 1.0, f.world_T_cam[-1], f.heatmaps[-1],
                       motion=motions)
