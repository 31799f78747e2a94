"""Solves on small simulated flights (turbinefit.solver.fit): ground truth is a fixed point,
noiseless flights are recovered, noisy ones improved, every mode and unary configuration
runs."""

import dataclasses
import math

import numpy as np
import pytest
from support import simulated_flight

from turbinefit.eval import accuracy
from turbinefit.flight import Flight
from turbinefit.solver import PRESETS, FitConfig, fit
from turbinefit.turbine.model import TurbineParams


@pytest.fixture(scope="module")
def exact_flight() -> Flight:
    # 320 px (the simulator's standard): at 160 px the heat-map ridges are 1 px wide and
    # their bicubic interpolant and rounded ends bias the interp optimum by ~3 cm
    return simulated_flight(40, "exact", width=320)


@pytest.fixture(scope="module")
def noiseless_flight() -> Flight:
    return simulated_flight(40, "noiseless", drift_pos_m=1.0, drift_rot_deg=1.0)


@pytest.mark.parametrize("mode", ["joint", "pose", "turbine"])
def test_ground_truth_is_a_fixed_point(exact_flight, mode):
    fl = exact_flight
    res = fit(fl, FitConfig(mode=mode))
    acc = accuracy(res.world_T_cam, res.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert acc.position_error_m < 0.02
    assert acc.orientation_error_deg < 0.02
    assert acc.model_point_error_m < 0.02
    assert res.final_cost <= res.initial_cost + 1e-9


def test_turbine_only_recovers_parameters(exact_flight):
    fl = exact_flight
    gt = fl.gt_turbine.to_vector()
    start = TurbineParams.from_vector(gt + np.array([0.8, -0.6, 1.5, math.radians(3), 0.3,
                                                     math.radians(3), -1.5]))
    res = fit(fl, FitConfig(mode="turbine"), initial_turbine=start)
    err = accuracy(fl.gt_world_T_cam, res.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert err.model_point_error_m < 0.05
    assert abs(err.param_errors["heading"]) < 0.1
    assert abs(err.param_errors["blade_rotation"]) < 0.1
    np.testing.assert_allclose(res.world_T_cam.wxyz_xyz, fl.gt_world_T_cam.wxyz_xyz)


def test_pose_only_with_true_turbine_removes_drift(noiseless_flight):
    fl = noiseless_flight
    res = fit(fl, FitConfig(mode="pose"), initial_turbine=fl.gt_turbine)
    before = accuracy(fl.world_T_cam, fl.gt_turbine, fl.gt_world_T_cam, fl.gt_turbine)
    after = accuracy(res.world_T_cam, res.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert after.position_error_m < 0.5 * before.position_error_m
    assert after.orientation_error_deg < 0.5 * before.orientation_error_deg
    assert res.turbine == fl.gt_turbine.canonical()


def test_joint_recovers_turbine_and_improves_poses(noiseless_flight):
    fl = noiseless_flight
    res = fit(fl, FitConfig())
    before = accuracy(fl.world_T_cam, fl.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    after = accuracy(res.world_T_cam, res.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert after.model_point_error_m < 0.25 * before.model_point_error_m
    assert after.orientation_error_deg < before.orientation_error_deg
    assert res.final_cost < 0.5 * res.initial_cost
    assert res.history and res.iterations == len(res.history)
    assert res.termination in {"function_tolerance", "gradient_tolerance", "parameter_tolerance",
                               "max_iterations", "no_progress"}
    assert 0 <= res.turbine.heading < 2 * math.pi
    assert 0 <= res.turbine.blade_rotation < 2 * math.pi / 3


def test_joint_beats_pose_only_when_turbine_is_wrong(noiseless_flight):
    fl = noiseless_flight
    joint = fit(fl, FitConfig())
    pose = fit(fl, FitConfig(mode="pose"))
    aj = accuracy(joint.world_T_cam, joint.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    ap = accuracy(pose.world_T_cam, pose.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert aj.position_error_m < ap.position_error_m
    assert aj.orientation_error_deg < ap.orientation_error_deg


@pytest.mark.parametrize("name", ["paper-best", "all-interp", "all-corr", "paper-worst"])
def test_four_unary_configurations_run_and_reduce_cost(noiseless_flight, name):
    fl = noiseless_flight
    res = fit(fl, PRESETS[name])
    assert np.all(np.isfinite(res.world_T_cam.wxyz_xyz))
    assert res.final_cost < res.initial_cost
    acc = accuracy(res.world_T_cam, res.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    before = accuracy(fl.world_T_cam, fl.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert acc.model_point_error_m < before.model_point_error_m


def test_noisy_heatmaps_and_second_turbine_still_improve():
    fl = simulated_flight(40, "default", seed=2, second_turbine=True)
    res = fit(fl, FitConfig(robust="cauchy"))
    before = accuracy(fl.world_T_cam, fl.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    after = accuracy(res.world_T_cam, res.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert after.model_point_error_m < 0.5 * before.model_point_error_m


def test_turbine_out_of_view_is_not_a_crash():
    fl = simulated_flight(10, "noiseless")
    # point every camera at the sky: nothing of the turbine is in view
    far = fl.world_T_cam.translation + np.array([0.0, 0.0, 5000.0])
    from turbinefit.geometry.se3 import SE3

    away = SE3(np.concatenate([fl.world_T_cam.wxyz, far], axis=-1))
    res = fit(fl, FitConfig(), initial_poses=away)
    assert np.all(np.isfinite(res.world_T_cam.wxyz_xyz))
    assert math.isfinite(res.final_cost)


@pytest.mark.parametrize("seed", [0, 1])
def test_joint_recovers_noiseless_flight_with_wrong_turbine(seed):
    """Clean heat-maps, exact poses, turbine off by the default sigmas: joint mode must
    recover the turbine and keep the poses to a few centimetres."""
    fl = simulated_flight(40, "noiseless", seed=seed, drift_pos_m=0.0, drift_rot_deg=0.0)
    before = accuracy(fl.world_T_cam, fl.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert before.model_point_error_m > 1.0
    res = fit(fl, FitConfig())
    after = accuracy(res.world_T_cam, res.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert after.model_point_error_m < 0.1
    assert after.position_error_m < 0.1
    assert after.orientation_error_deg < 0.05


def test_warmup_widens_the_basin():
    """Heading and blade rotation 12 deg off (the interp basin is a few pixels): the
    correspondence warm-up brings the fit in; without it, the refine stage stalls."""
    fl = simulated_flight(60, "noiseless", seed=1, width=320)
    v = fl.gt_turbine.to_vector() + np.array([1.5, -1.5, 3.0, math.radians(12), 0.8,
                                              math.radians(12), -3.0])
    start = TurbineParams.from_vector(v)
    before = accuracy(fl.world_T_cam, start, fl.gt_world_T_cam, fl.gt_turbine)
    warm = fit(fl, FitConfig(), initial_turbine=start)
    cold = fit(fl, FitConfig(warmup=False), initial_turbine=start)
    aw = accuracy(warm.world_T_cam, warm.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    ac = accuracy(cold.world_T_cam, cold.turbine, fl.gt_world_T_cam, fl.gt_turbine)
    assert aw.model_point_error_m < 0.05 * before.model_point_error_m
    assert aw.position_error_m < 0.5 < before.position_error_m
    assert ac.model_point_error_m > 2 * aw.model_point_error_m
    stages = [h.stage for h in warm.history]
    assert stages[0] == "align" and "match" in stages and stages[-1] == "refine"
    assert stages == sorted(stages, key=["align", "match", "refine"].index)
    assert {h.stage for h in cold.history} == {"refine"}


@pytest.fixture(scope="module", params=["gps", "vio"])
def odometry_flight(request) -> Flight:
    return simulated_flight(60, seed=1, odometry=request.param)


def test_default_fit_picks_the_pair_frame_of_the_measurements(odometry_flight):
    """auto: the paper's residual (estimated) on body-frame odometry, measured on GPS/IMU
    keyframes; the result records it, FitProblem resolves it alike, and the small flight
    fits to its tolerance with the defaults."""
    from turbinefit.solver.problem import FitProblem

    f = odometry_flight
    want = "measured" if f.odometry is None else "estimated"
    assert FitProblem(f, FitConfig()).config.pair_frame == want
    res = fit(f)
    assert res.config.pair_frame == want
    assert dataclasses.replace(res.config, pair_frame="auto", pixel_scale=None) == FitConfig()
    assert res.config.pixel_scale == 1.0  # maps no wider than 320 px: settings as written
    a0 = accuracy(f.world_T_cam, f.turbine, f.gt_world_T_cam, f.gt_turbine)
    a = accuracy(res.world_T_cam, res.turbine, f.gt_world_T_cam, f.gt_turbine)
    assert a.position_error_m < 0.45 < a0.position_error_m
    assert a.orientation_error_deg < 0.35
    assert a.model_point_error_m < 0.35 < a0.model_point_error_m


def test_ideal_maps_at_twice_the_resolution_fit_to_the_same_result():
    """The same flight's noiseless maps at 320 x 240 and 640 x 480 fit to nearly the same
    poses and turbine: the pixel settings follow the maps' scale. With the 320 px values
    used as 640 px values (pixel_scale 1), the turbine ends measurably worse."""
    cfg = FitConfig(lines="corr", line_residual="normal", robust="cauchy")
    results = {}
    for width, scale in ((320, None), (640, None), (640, 1.0)):
        f = simulated_flight(20, "noiseless", seed=5, width=width,
                             heatmap_size=(width, width * 3 // 4))
        res = fit(f, dataclasses.replace(cfg, pixel_scale=scale))
        results[width, scale] = (res, accuracy(res.world_T_cam, res.turbine, f.gt_world_T_cam,
                                               f.gt_turbine))
    (r1, a1), (r2, a2), (_, a_px) = results.values()
    assert (r1.config.pixel_scale, r2.config.pixel_scale) == (1.0, 2.0)
    assert a2.position_error_m == pytest.approx(a1.position_error_m, abs=0.02)
    assert a2.model_point_error_m == pytest.approx(a1.model_point_error_m, abs=0.02)
    assert a2.orientation_error_deg == pytest.approx(a1.orientation_error_deg, abs=0.02)
    assert a_px.model_point_error_m > 2 * a2.model_point_error_m
