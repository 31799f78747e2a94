"""Simulated flights (turbinefit.sim.scenario): determinism, contents per configuration,
presets, a second turbine."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from support import NRE, simulated_flight

from turbinefit.geometry.se3 import pose_errors
from turbinefit.sim import PRESETS, simulate_flight
from turbinefit.sim.turbines import neighbour_turbine
from turbinefit.turbine.model import param_errors


def test_simulation_is_deterministic_and_seed_dependent():
    a = simulated_flight(12, seed=3, width=320)
    b = simulated_flight(12, seed=3, width=320)
    c = simulated_flight(12, seed=4, width=320)
    ha, hb, hc = (np.stack([f.heatmaps[k] for k in range(12)]) for f in (a, b, c))
    assert ha.dtype == np.float32 and ha.shape == (12, 7, 240, 320)
    assert np.array_equal(ha, hb)
    assert np.array_equal(a.world_T_cam.wxyz_xyz, b.world_T_cam.wxyz_xyz)
    assert np.array_equal(a.gt_world_T_cam.wxyz_xyz, b.gt_world_T_cam.wxyz_xyz)
    assert a.turbine == b.turbine and a.gt_turbine == b.gt_turbine
    np.testing.assert_array_equal(a.timestamps, b.timestamps)
    assert not np.array_equal(ha, hc)
    assert not np.allclose(a.gt_world_T_cam.wxyz_xyz, c.gt_world_T_cam.wxyz_xyz)
    assert a.gt_turbine != c.gt_turbine


def test_flight_contents_follow_the_config():
    f = simulated_flight(12, seed=5, width=320)
    assert f.camera.fx == pytest.approx(160.0 / math.tan(math.radians(35.0)))
    assert (f.camera.cx, f.camera.cy) == (159.5, 119.5)
    assert f.odometry is None and f.has_ground_truth
    np.testing.assert_allclose(np.diff(f.timestamps), 1.0)
    # heat-maps come from the ground truth, the initial estimates are perturbed
    dpos, _ = pose_errors(f.world_T_cam, f.gt_world_T_cam)
    assert dpos[0] == 0.0 and dpos[1:].max() > 0.0
    assert np.any(param_errors(f.turbine, f.gt_turbine) != 0.0)
    exact = simulate_flight(replace(PRESETS["exact"], n_keyframes=12, seed=5))
    assert exact.turbine == exact.gt_turbine
    np.testing.assert_array_equal(exact.world_T_cam.wxyz_xyz, exact.gt_world_T_cam.wxyz_xyz)
    # same seed: the same truth whatever the noise settings
    assert exact.gt_turbine == f.gt_turbine
    np.testing.assert_array_equal(exact.gt_world_T_cam.wxyz_xyz, f.gt_world_T_cam.wxyz_xyz)
    for k in range(12):
        h = f.heatmaps[k]
        assert np.all(np.isfinite(h)) and h.min() >= 0.0 and h.max() <= 1.0


def test_presets_all_run():
    for name, cfg in PRESETS.items():
        f = simulate_flight(replace(cfg, n_keyframes=3))
        assert f.num_keyframes == 3, name


def test_second_turbine_adds_responses_far_away():
    base = replace(PRESETS["noiseless"], n_keyframes=40, seed=2)
    one = simulate_flight(base)
    two = simulate_flight(replace(base, second_turbine=True))
    np.testing.assert_array_equal(one.gt_world_T_cam.wxyz_xyz, two.gt_world_T_cam.wxyz_xyz)
    h1 = np.stack([one.heatmaps[k] for k in range(40)])
    h2 = np.stack([two.heatmaps[k] for k in range(40)])
    assert np.all(h2 >= h1)  # max-composited on top
    assert np.count_nonzero((h2 - h1).max(axis=(1, 2, 3)) > 0.5) >= 2
    rng = np.random.default_rng(0)
    for _ in range(20):
        other = neighbour_turbine(NRE, rng)
        d = math.hypot(other.base_x - NRE.base_x, other.base_y - NRE.base_y)
        assert 150.0 <= d <= 400.0


def test_default_gps_flights_are_unchanged():
    """Values of a flight simulated before the odometry stream was added (same seed): the
    default (gps) flight draws the same random numbers as it did.

    The tolerances protect that, not the last bits: a changed random stream moves a pose by
    metres and the heat-maps' sum by whole blobs (tens to thousands), while the same draws
    give values that differ across CPUs and libm builds by rounding alone (the maps' sum by
    2e-8 relative between two x86-64 machines: their exp and float16 rounding differ)."""
    f = simulated_flight(6, seed=3)
    np.testing.assert_allclose(f.world_T_cam.wxyz_xyz[-1], [
        0.6113651535163609, -0.6485274071535837, -0.3439079285107146, 0.2955878683979363,
        76.46589246834193, -56.25982333670883, 89.14863760946272], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(f.turbine.to_vector(), [
        -1.9370586108057386, 1.4307868680994773, 86.03198860672073, 5.653407843687704,
        4.489391546540411, 1.3481186345432985, 63.542734627627425], rtol=1e-9)
    maps = np.stack([f.heatmaps[k] for k in range(6)]).astype(np.float64)
    assert float(maps.sum()) == pytest.approx(9418.60811480457, rel=1e-5)
    assert f.odometry is None


def test_vio_flight_has_body_frame_odometry_and_the_same_scene():
    gps = simulated_flight(8, seed=2)
    vio = simulated_flight(8, seed=2, odometry="vio")
    assert vio.odometry is not None
    np.testing.assert_array_equal(vio.world_T_cam.wxyz_xyz, vio.odometry.wxyz_xyz)
    np.testing.assert_array_equal(vio.gt_world_T_cam.wxyz_xyz, gps.gt_world_T_cam.wxyz_xyz)
    assert vio.turbine == gps.turbine and vio.gt_turbine == gps.gt_turbine
    assert np.array_equal(vio.heatmaps[7], gps.heatmaps[7])
    np.testing.assert_allclose(vio.odometry.wxyz_xyz[0], vio.gt_world_T_cam.wxyz_xyz[0])
    dp, _ = pose_errors(vio.odometry, vio.gt_world_T_cam)
    assert dp[-1] > 0.1  # 8 keyframes: steps of ~170 m, 1 % each
    exact = simulated_flight(8, seed=2, odometry="vio", odometry_noise=0.0)
    dp, dr = pose_errors(exact.odometry, exact.gt_world_T_cam)
    assert dp.max() < 1e-6 and dr.max() < 1e-8
    with pytest.raises(ValueError, match="odometry"):
        simulated_flight(4, odometry="wheel")
    with pytest.raises(ValueError, match="odometry_noise"):
        simulated_flight(4, odometry="vio", odometry_noise=-1.0)


def test_a_large_camera_gets_small_heatmaps() -> None:
    from turbinefit.sim.scenario import HEATMAP_WIDTH, SimConfig, simulate_flight

    cfg = SimConfig(n_keyframes=2, width=5280, height=3956)
    flight = simulate_flight(cfg)
    assert (flight.heatmaps.width, flight.heatmaps.height) == (HEATMAP_WIDTH, 240)
    assert flight.camera == cfg.camera().resized(320, 240)
    assert cfg.render_config().sigma_px == SimConfig().render_config().sigma_px
    # the same turbine seen at 320 x 240 directly: the maps agree to within rounding
    small = simulate_flight(SimConfig(n_keyframes=2, width=320, height=240))
    peak = [np.unravel_index(np.argmax(f.heatmaps[1][2]), (240, 320)) for f in (flight, small)]
    assert np.abs(np.subtract(*peak)).max() <= 1
    assert SimConfig(width=160, height=120).heatmap_camera() == SimConfig(
        width=160, height=120).camera()
    assert SimConfig(width=4000, height=3000, heatmap_size=(400, 300)).heatmap_camera(
        ).width == 400
    with pytest.raises(ValueError, match="heatmap_size"):
        SimConfig(width=640, height=480, heatmap_size=(300, 300))


def test_heatmaps_at_a_larger_size_are_the_same_picture() -> None:
    """Blob widths and false streaks follow the maps' width; the maps of one view at 1280
    x 960, averaged over 4 x 4 blocks, are close to those at 320 x 240."""
    from turbinefit.sim.render import HeatmapNoise
    from turbinefit.sim.scenario import SimConfig, simulate_flight

    noise = HeatmapNoise(spurious_rate=1.0, spurious_length_px=(5.0, 40.0))
    small = SimConfig(n_keyframes=2, heatmap_noise=noise)
    big = SimConfig(n_keyframes=2, width=1280, height=960, heatmap_size=(1280, 960),
                    heatmap_noise=noise)
    assert big.render_config().sigma_px == 4 * small.render_config().sigma_px
    assert big.render_config().noise.spurious_length_px == (20.0, 160.0)
    assert small.render_config().noise == noise
    # pixel noise drawn per 4 x 4 block at 1280 px: the noise of the 320 px maps, finer
    assert (big.render_config().noise_block, small.render_config().noise_block) == (4, 1)
    noisy = simulate_flight(replace(big, heatmap_noise=HeatmapNoise(pixel_sigma=0.05)))
    blocks = np.asarray(noisy.heatmaps[0]).reshape(7, 240, 4, 320, 4)
    lo, hi = blocks.min(axis=(2, 4)), blocks.max(axis=(2, 4))
    # background blocks (noise above the clip at 0 everywhere in them) are constant
    assert (lo > 0).sum() > 10_000 and np.mean(hi[lo > 0] == lo[lo > 0]) > 0.9
    clean = [simulate_flight(SimConfig(n_keyframes=2, width=w, height=3 * w // 4,
                                       heatmap_size=(w, 3 * w // 4), heatmap_noise=HeatmapNoise()))
             for w in (320, 1280)]
    coarse = clean[1].heatmaps[1].reshape(7, 240, 4, 320, 4).mean(axis=(2, 4))
    assert np.abs(coarse - clean[0].heatmaps[1]).max() < 0.05
