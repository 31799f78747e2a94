"""The in-flight tracker (turbinefit.solver.tracker) against batch fits, with the turbine
out of view, priors, bad keyframes, configuration."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support import simulated_flight

from turbinefit.errors import TurbinefitError
from turbinefit.eval.metrics import accuracy
from turbinefit.flight import Flight
from turbinefit.geometry.se3 import SE3, pose_errors
from turbinefit.heatmaps import HeatmapStack
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import FitResult, fit
from turbinefit.solver.lm import levenberg_marquardt
from turbinefit.solver.problem import FitProblem
from turbinefit.solver.tracker import KeyframeError, Tracker, TrackerConfig
from turbinefit.turbine.model import model_point_error


def track(flight: Flight, config: TrackerConfig, maps: list[np.ndarray] | None = None
          ) -> Tracker:
    tr = Tracker(flight.camera, flight.turbine, config)
    for k in range(flight.num_keyframes):
        tr.update(flight.timestamps[k], flight.world_T_cam[k],
                  flight.heatmaps[k] if maps is None else maps[k])
    return tr


@pytest.fixture(scope="module")
def flight200() -> Flight:
    return simulated_flight(200, width=320)


@pytest.fixture(scope="module")
def batch200(flight200: Flight) -> FitResult:
    return fit(flight200)


def test_unbounded_window_equals_the_batch_fit(flight200: Flight) -> None:
    """Same cost, same data, same solution: with every keyframe kept, the tracker ends in a
    minimum of the batch problem as low as the batch fit's, next to it. (Not bit-equal: the
    heat-map cost is rugged at the sub-pixel scale, and the weakly observable common shift
    of turbine and trajectory is flat, so two converged runs stop ~1 cm apart; measured on
    this flight, the tracker's minimum is even slightly lower.)"""
    assert flight200.gt_world_T_cam is not None and flight200.gt_turbine is not None
    tight = FitConfig(function_tolerance=1e-8, max_iterations=60, max_rounds=6)
    batch = fit(flight200, tight)
    tr = track(flight200, TrackerConfig(fit=tight, window=None, theta_sigma=None,
                                        finish_rounds=6, finish_iterations=60))
    tr.finish()
    poses, theta = tr.world_T_cam(), tr.theta
    dpos, dang = pose_errors(poses, batch.world_T_cam)
    assert dpos.mean() < 0.02 and np.median(dpos) < 0.015, (dpos.mean(), np.median(dpos))
    assert np.degrees(dang).mean() < 0.01
    assert model_point_error(tr.turbine, batch.turbine) < 0.02
    prob = FitProblem(flight200, tight)

    def cost(p: SE3, t: np.ndarray) -> float:
        return prob.linearize(p, t, prob.find_correspondences(p, t), with_jacobian=False).cost

    assert cost(poses, theta) <= 1.001 * cost(batch.world_T_cam, batch.turbine.to_vector())
    gt, gt_t = flight200.gt_world_T_cam, flight200.gt_turbine
    e_t = accuracy(poses, tr.turbine, gt, gt_t).position_error_m
    e_b = accuracy(batch.world_T_cam, batch.turbine, gt, gt_t).position_error_m
    assert abs(e_t - e_b) < 0.03 * e_b, (e_t, e_b)


def test_default_window_within_ten_percent_of_the_batch_fit(flight200: Flight,
                                                            batch200: FitResult) -> None:
    assert flight200.gt_world_T_cam is not None and flight200.gt_turbine is not None
    batch = batch200
    tr = track(flight200, TrackerConfig())
    b = accuracy(batch.world_T_cam, batch.turbine, flight200.gt_world_T_cam, flight200.gt_turbine)
    t = accuracy(tr.world_T_cam(), tr.turbine, flight200.gt_world_T_cam, flight200.gt_turbine)
    assert t.position_error_m <= 1.1 * b.position_error_m, (t, b)
    assert t.orientation_error_deg <= 1.1 * b.orientation_error_deg, (t, b)
    # the per-keyframe work was bounded: never more than the window
    assert max(e.window for e in tr.estimates) == TrackerConfig().window
    # causal estimates (each keyframe on arrival) are worse than the final ones but useful
    c = accuracy(tr.causal_world_T_cam(), tr.turbine, flight200.gt_world_T_cam,
                 flight200.gt_turbine)
    assert t.position_error_m < c.position_error_m < 0.5


def test_window_matches_a_batch_solve_with_the_old_poses_fixed() -> None:
    """The marginal prior stands in for the marginalised keyframes: re-solving the whole
    flight with those poses held at the tracker's estimates leaves the window and theta
    where the tracker put them."""
    flight = simulated_flight(50, seed=4, width=320)
    window = 10
    # marginal_terms="same": the prior then summarises exactly the cost the batch solves
    cfg_t = TrackerConfig(window=window, theta_sigma=None, marginal_terms="same")
    tr = track(flight, cfg_t)
    tr.finish()
    poses = tr.world_T_cam()
    theta = tr.theta
    n = flight.num_keyframes
    fixed = np.arange(n) < n - window
    cfg = FitConfig()
    prob = FitProblem(flight, cfg, fixed=fixed)
    p, t = poses, theta
    for _ in range(4):
        corr = prob.find_correspondences(p, t)
        out = levenberg_marquardt(prob, p, t, corr, prob.linearize(p, t, corr),
                                  max_iterations=15)
        p, t = out.poses, out.theta
    moved, _ = pose_errors(p[n - window:], poses[n - window:])
    assert moved.max() < 0.03, moved
    from turbinefit.turbine.model import TurbineParams

    assert model_point_error(TurbineParams.from_vector(t), tr.turbine) < 0.03
    # without the prior (information of the old keyframes lost) the window moves much more
    # under the same test: the check has teeth
    tr2 = track(flight, cfg_t)
    tr2._marginal = None  # deliberately break the tracker
    tr2.finish()
    moved2, _ = pose_errors(tr2.world_T_cam()[n - window:], p[n - window:])
    assert moved2.mean() > 3 * max(moved.mean(), 1e-3)


def test_turbine_out_of_view_for_twenty_keyframes_does_not_diverge() -> None:
    flight = simulated_flight(100, seed=0, width=320)
    assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
    blank = np.zeros_like(flight.heatmaps[0])
    gap = range(50, 70)
    maps = [blank if k in gap else flight.heatmaps[k] for k in range(flight.num_keyframes)]
    tr = track(flight, TrackerConfig(), maps)
    assert not any(tr.estimates[k].evidence for k in gap)
    causal, _ = pose_errors(tr.causal_world_T_cam(), flight.gt_world_T_cam)
    initial, _ = pose_errors(flight.world_T_cam, flight.gt_world_T_cam)
    # during the gap the poses follow the GPS/IMU steps: no worse than the GPS drift there
    assert causal.max() < 3.0 and causal[list(gap)].mean() < initial[list(gap)].mean() + 0.5
    # after it the tracker finds the turbine again
    assert causal[85:].mean() < 0.6, causal[85:].mean()
    final = accuracy(tr.world_T_cam(), tr.turbine, flight.gt_world_T_cam, flight.gt_turbine)
    assert final.model_point_error_m < 0.5 and final.position_error_m < 0.6


def test_start_up_prior_holds_theta_on_the_first_keyframes() -> None:
    flight = simulated_flight(12, seed=5, width=320)
    assert flight.gt_turbine is not None
    start = model_point_error(flight.turbine, flight.gt_turbine)
    tr = Tracker(flight.camera, flight.turbine)
    for k in range(flight.num_keyframes):
        est = tr.update(flight.timestamps[k], flight.world_T_cam[k], flight.heatmaps[k])
        assert model_point_error(est.turbine, flight.gt_turbine) < max(1.5 * start, 1.0)
        assert est.theta_covariance is not None and np.all(np.isfinite(est.theta_covariance))
        sd = np.sqrt(np.diag(est.theta_covariance))
        assert np.all(sd <= np.asarray(TrackerConfig().theta_sigma) * 1.0001)
    assert tr.theta_prior_active  # 12 keyframes from one side do not outweigh it yet
    # the first keyframe is the gauge: held fixed, zero covariance
    assert tr.estimates[0].pose_covariance is not None
    assert np.all(tr.estimates[0].pose_covariance == 0.0)
    # later keyframes are uncertain by the GPS/IMU steps and the images
    s = tr.estimates[-1].position_sigma_m()
    assert s is not None and 0.0 < s < 5.0


def test_without_a_prior_the_first_keyframe_gives_no_covariance_but_no_crash() -> None:
    flight = simulated_flight(3, seed=5, width=160)
    tr = Tracker(flight.camera, flight.turbine, TrackerConfig(theta_sigma=None))
    est = tr.update(flight.timestamps[0], flight.world_T_cam[0], flight.heatmaps[0])
    assert np.all(np.isfinite(est.world_T_cam.wxyz_xyz))
    assert est.theta_covariance is None or np.all(np.isfinite(est.theta_covariance))


def test_pose_only_tracking_keeps_the_turbine() -> None:
    flight = simulated_flight(30, seed=6)
    cfg = TrackerConfig(fit=FitConfig(mode="pose"))
    tr = track(flight, cfg)
    np.testing.assert_array_equal(tr.turbine.to_vector(), flight.turbine.canonical().to_vector())
    assert all(e.theta_covariance is None for e in tr.estimates)


def test_bad_keyframes_are_refused_and_change_nothing() -> None:
    flight = simulated_flight(3, seed=7)
    tr = Tracker(flight.camera, flight.turbine)
    tr.update(flight.timestamps[1], flight.world_T_cam[1], flight.heatmaps[1])
    cases = [
        (flight.timestamps[0], flight.world_T_cam[0], flight.heatmaps[0], "not after"),
        (flight.timestamps[2], flight.world_T_cam[2], flight.heatmaps[2][:, :10], "shape"),
        (flight.timestamps[2], flight.world_T_cam[2:3], flight.heatmaps[2], "one finite SE3"),
        (float("nan"), flight.world_T_cam[2], flight.heatmaps[2], "not finite"),
    ]
    bad = np.array(flight.heatmaps[2])
    bad[3, 5, 5] = np.nan
    cases.append((flight.timestamps[2], flight.world_T_cam[2], bad, "NaN"))
    for t, pose, maps, why in cases:
        with pytest.raises(KeyframeError, match=why) as info:
            tr.update(t, pose, maps)
        assert info.value.index == 1
        assert isinstance(info.value, TurbinefitError) and isinstance(info.value, ValueError)
        assert tr.num_keyframes == 1
    est = tr.update(flight.timestamps[2], flight.world_T_cam[2], flight.heatmaps[2])
    assert est.index == 1 and tr.num_keyframes == 2


def test_tracker_config_validation() -> None:
    for kw, why in (({"window": 1}, "window"), ({"window": 2.5}, "window"),
                    ({"rounds": 0}, "rounds"), ({"theta_sigma": (1.0,) * 6}, "theta_sigma"),
                    ({"theta_sigma": (1.0,) * 6 + (0.0,)}, "theta_sigma"),
                    ({"fit": FitConfig(mode="turbine")}, "mode"),
                    ({"match_rounds": -1}, "match_rounds"),
                    ({"theta_prior_release": 0.0}, "theta_prior_release"),
                    ({"marginal_terms": "interp"}, "marginal_terms")):
        with pytest.raises(ValueError, match=why):
            TrackerConfig(**kw)  # type: ignore[arg-type]
    assert dataclasses.replace(TrackerConfig(), window=None).window is None


def test_heatmap_stack_of_a_window_is_referenced_not_copied() -> None:
    flight = simulated_flight(2, seed=8)
    maps = [np.ascontiguousarray(flight.heatmaps[k], dtype=np.float32) for k in range(2)]
    tr = Tracker(flight.camera, flight.turbine)
    for k in range(2):
        tr.update(flight.timestamps[k], flight.world_T_cam[k], maps[k])
    assert tr._window is not None
    stack = tr._window.data.heatmaps
    assert isinstance(stack, HeatmapStack)
    assert all(np.shares_memory(stack[k], maps[k]) for k in range(2))


def test_float16_maps_are_kept_as_float16_and_track_as_their_float32_values() -> None:
    """Maps from float16 files stay float16 in the window (half the memory, read as such
    by the kernels) and give the estimates of the same values in float32; a later
    keyframe of the other storage is converted to the window's."""
    flight = simulated_flight(12, seed=8)
    half = [np.asarray(flight.heatmaps[k], dtype=np.float16) for k in range(12)]
    a, b = Tracker(flight.camera, flight.turbine), Tracker(flight.camera, flight.turbine)
    for k in range(12):
        t, pose = flight.timestamps[k], flight.world_T_cam[k]
        a.update(t, pose, half[k] if k != 5 else half[k].astype(np.float32))
        b.update(t, pose, half[k].astype(np.float32))
    assert a._window is not None and a._window.data.heatmaps.half
    assert a._window.data.heatmaps.pointers() is not None
    np.testing.assert_allclose(a.world_T_cam().wxyz_xyz, b.world_T_cam().wxyz_xyz,
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.turbine.to_vector(), b.turbine.to_vector(), rtol=0, atol=1e-9)


def test_auto_pair_frame_follows_the_first_keyframe_and_refuses_mixing() -> None:
    f = simulated_flight(4, seed=1, odometry="vio")
    assert f.odometry is not None
    without = Tracker(f.camera, f.turbine)
    without.update(f.timestamps[0], f.world_T_cam[0], f.heatmaps[0])
    assert without.config.fit.pair_frame == "measured"
    with pytest.raises(KeyframeError, match="keyframe 1: odometry pose given"):
        without.update(f.timestamps[1], f.world_T_cam[1], f.heatmaps[1], odometry=f.odometry[1])
    tr = Tracker(f.camera, f.turbine)
    assert tr.config.fit.pair_frame == "auto"
    tr.update(f.timestamps[0], f.world_T_cam[0], f.heatmaps[0], odometry=f.odometry[0])
    assert tr.config.fit.pair_frame == "estimated"
    with pytest.raises(KeyframeError, match="keyframe 1: no odometry pose"):
        tr.update(f.timestamps[1], f.world_T_cam[1], f.heatmaps[1])
    assert tr.num_keyframes == 1  # refused keyframes change nothing
    tr.update(f.timestamps[1], f.world_T_cam[1], f.heatmaps[1], odometry=f.odometry[1])
    assert tr.num_keyframes == 2


def test_prediction_uses_the_odometry_step() -> None:
    """With odometry the pairwise measurements are its steps, not those of the keyframe
    poses: keyframe poses far off do not move the tracker's estimates."""
    f = simulated_flight(12, seed=1, odometry="vio")
    assert f.odometry is not None and f.gt_world_T_cam is not None
    junk = SE3(f.world_T_cam.wxyz_xyz.copy())
    junk.wxyz_xyz[1:, 4:] += 50.0  # keyframes.txt 50 m off after the first keyframe
    cfg = TrackerConfig(rounds=1, iterations=1, match_rounds=0)
    est = []
    for poses in (f.world_T_cam, junk):
        tr = Tracker(f.camera, f.turbine, cfg)
        for k in range(f.num_keyframes):
            tr.update(f.timestamps[k], poses[k], f.heatmaps[k], odometry=f.odometry[k])
        est.append(tr.causal_world_T_cam().wxyz_xyz)
    np.testing.assert_allclose(est[0], est[1], atol=1e-9)


def test_tracking_an_odometry_flight_with_the_defaults() -> None:
    f = simulated_flight(60, seed=1, odometry="vio")
    assert f.odometry is not None and f.gt_world_T_cam is not None and f.gt_turbine is not None
    tr = Tracker(f.camera, f.turbine)
    for k in range(f.num_keyframes):
        tr.update(f.timestamps[k], f.world_T_cam[k], f.heatmaps[k], odometry=f.odometry[k])
    a = accuracy(tr.world_T_cam(), tr.turbine, f.gt_world_T_cam, f.gt_turbine)
    assert a.position_error_m < 0.4 and a.orientation_error_deg < 0.3
    assert a.model_point_error_m < 0.3


def test_a_refused_keyframe_leaves_the_maps_storage_undecided() -> None:
    """A first keyframe of float16 maps refused for its photo decides nothing: the next
    one, of float32 maps, is kept as float32."""
    flight = simulated_flight(2, seed=8)
    tr = Tracker(flight.camera, flight.turbine)
    t, pose = float(flight.timestamps[0]), flight.world_T_cam[0]
    with pytest.raises(KeyframeError, match="photo"):
        tr.update(t, pose, np.asarray(flight.heatmaps[0], dtype=np.float16),
                  photo=np.zeros((3, 5), np.uint8))
    tr.update(t, pose, np.asarray(flight.heatmaps[0], dtype=np.float32))
    assert tr._window is not None and not tr._window.data.heatmaps.half
