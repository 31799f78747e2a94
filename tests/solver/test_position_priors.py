"""Position priors in the fit and the tracker: a simulated flight whose initial positions
are RTK-accurate (2 cm) but whose attitudes drift, fitted with and without its position
sigmas. Without them the images and the pairwise term pull the positions about (0.3 m);
with them the fit keeps the positions the receiver vouches for."""

import dataclasses

import numpy as np
import pytest
from support import simulated_flight

from turbinefit.flight import Flight
from turbinefit.geometry.se3 import SE3, pose_errors
from turbinefit.solver import FitConfig, Tracker, TrackerConfig, fit

N = 60
RTK_SIGMA = 0.02
CONFIG = FitConfig(lines="corr", line_residual="normal", robust="cauchy")


def rtk_flight(seed: int) -> tuple[Flight, Flight]:
    """The simulated flight with RTK-like initial positions, without and with sigmas."""
    f = simulated_flight(N, seed=seed)
    assert f.gt_world_T_cam is not None
    rng = np.random.default_rng(seed)
    pos = f.gt_world_T_cam.translation + rng.normal(scale=RTK_SIGMA, size=(N, 3))
    plain = dataclasses.replace(
        f, world_T_cam=SE3.from_rotation_translation(f.world_T_cam.rotation_matrix(), pos))
    return plain, dataclasses.replace(plain, position_sigma=np.full((N, 3), RTK_SIGMA))


def position_error(poses: SE3, flight: Flight) -> float:
    assert flight.gt_world_T_cam is not None
    return float(pose_errors(poses, flight.gt_world_T_cam)[0].mean())


def test_fit_keeps_rtk_positions() -> None:
    plain, rtk = rtk_flight(1)
    start = position_error(plain.world_T_cam, plain)
    without = position_error(fit(plain, CONFIG).world_T_cam, plain)
    with_sigma = position_error(fit(rtk, CONFIG).world_T_cam, plain)
    assert start < 0.04
    assert without > 0.15  # measured 0.29-0.37 m on seeds 0-2
    assert with_sigma < 1.2 * start  # measured 0.026-0.031 m
    assert with_sigma < 0.25 * without


def test_tracker_uses_position_sigmas() -> None:
    plain, rtk = rtk_flight(2)
    results = []
    for flight in (plain, rtk):
        tracker = Tracker(flight.camera, flight.turbine, TrackerConfig(fit=CONFIG))
        for k in range(N):
            sigma = None if flight.position_sigma is None else flight.position_sigma[k]
            tracker.update(float(flight.timestamps[k]), flight.world_T_cam[k],
                           flight.heatmaps[k], position_sigma=sigma)
        tracker.finish()
        results.append(position_error(tracker.world_T_cam(), plain))
    assert results[1] < 0.5 * results[0]
    assert results[1] < 0.05


def test_tracker_refuses_sigmas_for_some_keyframes_only() -> None:
    from turbinefit.solver.tracker import KeyframeError

    _, rtk = rtk_flight(0)
    tracker = Tracker(rtk.camera, rtk.turbine)
    tracker.update(0.0, rtk.world_T_cam[0], rtk.heatmaps[0], position_sigma=np.ones(3))
    with pytest.raises(KeyframeError, match="no position_sigma"):
        tracker.update(1.0, rtk.world_T_cam[1], rtk.heatmaps[1])
    with pytest.raises(KeyframeError, match="3 positive finite"):
        tracker.update(1.0, rtk.world_T_cam[1], rtk.heatmaps[1],
                       position_sigma=np.array([1.0, 0.0, 1.0]))
