"""Tests of the flight simulator (turbinefit.sim)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from helpers import look_at

from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, pose_errors, quat_conjugate, quat_log, quat_multiply
from turbinefit.sim import (
    PRESETS,
    HeatmapNoise,
    RenderConfig,
    SimConfig,
    drift_poses,
    inspection_trajectory,
    perturb_turbine,
    plan_inspection,
    preset_turbine,
    render_flight,
    render_heatmaps,
    sample_turbine,
    simulate_flight,
)
from turbinefit.sim.noise import DEFAULT_TURBINE_SIGMA
from turbinefit.sim.trajectory import PHASES, distance_to_segments
from turbinefit.sim.turbines import REALISTIC_GEOMETRY, neighbour_turbine
from turbinefit.turbine.model import (
    LINES,
    PAPER_GEOMETRY,
    POINT_CHANNELS,
    TurbineGeometry,
    TurbineParams,
    model_points,
    param_errors,
    skeleton_segments,
)

CAMERA = PinholeCamera(320, 240, 228.5, 228.5, 159.5, 119.5)
DISTORTED = replace(CAMERA, distortion=(-0.25, 0.08, 0.002, -0.001, 0.0))
NRE = TurbineParams(1.0, -2.0, 87.6, 0.6, 5.0, 0.3, 63.0)
SIGMA = 2.0


def small_flight(seed: int = 3) -> Flight:
    return simulate_flight(SimConfig(n_keyframes=12, seed=seed))


def visible_parts(poses: SE3, theta: TurbineParams, geometry: TurbineGeometry = PAPER_GEOMETRY,
                  camera: PinholeCamera = CAMERA) -> tuple[np.ndarray, np.ndarray]:
    """Per keyframe: how many of the 6 model points, and whether any of 6 points + 250
    line samples, project inside the image."""
    pts, _ = model_points(theta.to_vector(), geometry)
    s = np.linspace(0.0, 1.0, 50)[:, None]
    samples = np.concatenate([pts[a] * (1 - s) + pts[b] * s for a, b, _ in LINES])
    allp = np.concatenate([pts, samples])
    cam_p = poses.inverse()[:, None] @ allp[None]
    _, valid, _ = camera.project(cam_p)
    return valid[:, :6].sum(axis=1), valid.any(axis=1)


# ---- determinism -------------------------------------------------------------------------


def test_simulation_is_deterministic_and_seed_dependent():
    a = small_flight(seed=3)
    b = small_flight(seed=3)
    c = small_flight(seed=4)
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
    f = small_flight(seed=5)
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


# ---- rendering ----------------------------------------------------------------------------


def pose_looking_at(eye, target) -> SE3:
    return look_at(np.asarray(eye, float), np.asarray(target, float))[0]


def project(camera: PinholeCamera, pose: SE3, world_p: np.ndarray):
    uv, valid, _ = camera.project(pose.inverse() @ world_p)
    return uv, valid


@pytest.mark.parametrize("camera", [CAMERA, DISTORTED], ids=["pinhole", "distorted"])
def test_point_peaks_lie_on_the_projected_points(camera):
    pts, _ = model_points(NRE.to_vector())
    checked = 0
    for eye, target in [((150, 60, 40), (0, 0, 60)), ((-120, 90, 80), (0, 0, 80)),
                        ((40, -200, 60), (0, 0, 70)), ((-60, 0, 60), (0, 0, 85))]:
        pose = pose_looking_at(eye, target)
        h = render_heatmaps(camera, pose, NRE.to_vector(), cfg=RenderConfig(sigma_px=SIGMA))
        uv, valid = project(camera, pose, pts)
        for i in range(3):  # base, tower top, hub: one point per channel
            ch = POINT_CHANNELS[i]
            if not (valid[i] and camera.in_image(uv[i], margin=2.0)):
                if not camera.in_image(uv[i], margin=-5.0 * SIGMA):  # well outside
                    assert h[ch].max() < 1e-3
                continue
            iv, ju = np.unravel_index(np.argmax(h[ch]), h[ch].shape)
            assert math.hypot(ju - uv[i, 0], iv - uv[i, 1]) <= 1.0
            assert h[ch].max() > 0.85
            checked += 1
    assert checked >= 6


def ridge_expected(uv0, uv1, u, v, sigma=SIGMA):
    e = uv1 - uv0
    p = np.stack([u, v], -1) - uv0
    t = np.clip(p @ e / (e @ e), 0, 1)
    d = p - t[..., None] * e
    return np.exp(-np.sum(d * d, -1) / (2 * sigma**2))


def test_line_channels_are_gaussian_ridges_along_the_projected_segments():
    pose = pose_looking_at((0, -60, 45), (0, 0, 45))  # tower across the image, vertically
    theta = TurbineParams(0.0, 0.0, 87.6, math.pi / 2, 5.0, 0.0, 63.0)  # rotor faces +y
    h = render_heatmaps(CAMERA, pose, theta.to_vector(), cfg=RenderConfig(sigma_px=SIGMA))
    pts, _ = model_points(theta.to_vector())
    cam_p = pose.inverse() @ pts
    uv, _, _ = CAMERA.project_unbounded(cam_p)
    # the tower's midpoint projects at the image centre row; profile across it
    mid_world = 0.5 * (pts[0] + pts[1])
    m_uv, m_valid = project(CAMERA, pose, mid_world)
    assert m_valid
    ju, iv = round(m_uv[0]), round(m_uv[1])
    assert h[4, iv, ju] > 0.9
    cols = np.arange(ju - 6, ju + 7)
    expected = ridge_expected(uv[0], uv[1], cols.astype(float), np.full(cols.size, float(iv)))
    np.testing.assert_allclose(h[4, iv, cols], expected, atol=2e-3)
    # far from every tower pixel: ~0
    far = np.abs(np.arange(320) - m_uv[0]) > 6 * SIGMA
    assert h[4][:, far].max() < 1e-3
    assert h[4][:, ~far].max() > 0.95


def test_distorted_lines_follow_the_distorted_projection():
    pose = pose_looking_at((30, -110, 70), (0, 0, 95))
    h = render_heatmaps(DISTORTED, pose, NRE.to_vector(), cfg=RenderConfig(sigma_px=SIGMA))
    pts, _ = model_points(NRE.to_vector())
    hits = 0
    for a, b, ch in LINES:
        s = np.linspace(0.0, 1.0, 400)[:, None]
        uv, valid = project(DISTORTED, pose, pts[a] * (1 - s) + pts[b] * s)
        ok = valid & DISTORTED.in_image(uv, margin=1.0)
        for u, v in uv[ok]:
            iv, ju = round(v), round(u)
            assert h[ch, iv - 1:iv + 2, ju - 1:ju + 2].max() > 0.9
            hits += 1
    assert hits > 300
    # the pinhole-straight chord would be wrong: distortion bends the blade lines
    straight = render_heatmaps(CAMERA, pose, NRE.to_vector(), cfg=RenderConfig(sigma_px=SIGMA))
    assert np.abs(straight[6] - h[6]).max() > 0.5


def test_points_behind_the_camera_draw_nothing_and_lines_are_clipped():
    # heading 0, blade 1 horizontal along -y: hub (5, 0, 80), tip (5, -50, 80)
    theta = TurbineParams(0.0, 0.0, 80.0, 0.0, 5.0, math.pi / 2, 50.0)
    pts, _ = model_points(theta.to_vector())
    hub, tip = pts[2], pts[3]
    # camera 3 m in front of blade 1, half way along it, looking along it towards the tip
    eye = 0.5 * (hub + tip) + np.array([3.0, 0.0, 0.0])
    pose = pose_looking_at(eye, tip + np.array([3.0, 0.0, 0.0]))
    cam_p = pose.inverse() @ pts
    assert np.all(cam_p[[0, 1, 2, 4, 5], 2] < 0) and cam_p[3, 2] > 0  # only tip 1 in front
    h = render_heatmaps(CAMERA, pose, theta.to_vector(), cfg=RenderConfig(sigma_px=SIGMA))
    assert np.all(np.isfinite(h))
    assert h[0].max() == 0.0 and h[1].max() == 0.0 and h[2].max() == 0.0  # behind: no blob
    assert h[4].max() == 0.0 and h[5].max() == 0.0  # tower and nacelle wholly behind
    uv, valid = project(CAMERA, pose, tip)
    assert valid
    iv, ju = np.unravel_index(np.argmax(h[3]), h[3].shape)
    assert math.hypot(ju - uv[0], iv - uv[1]) <= 1.0  # the tip ahead is drawn
    # the visible part of blade 1 runs from the tip out of the image (towards the camera)
    ridge = h[6] > 0.5
    assert np.count_nonzero(ridge) > 100
    _, cols = np.nonzero(ridge)
    assert cols.min() <= 1 or cols.max() >= 318 or np.nonzero(ridge)[0].min() <= 1
    # looking away from the turbine: everything is behind, nothing is drawn
    away = pose_looking_at(eye, eye + np.array([10.0, 0.0, 0.0]))
    h2 = render_heatmaps(CAMERA, away, theta.to_vector())
    assert np.all(np.isfinite(h2)) and h2.max() == 0.0


def test_render_flight_matches_single_frames_and_noise_is_bounded():
    poses = look_at(np.array([[150.0, 20.0, 60.0], [-100.0, 80.0, 90.0], [30.0, -12.0, 40.0]]),
                    np.array([[0.0, 0.0, 80.0], [0.0, 0.0, 90.0], [0.0, 0.0, 40.0]]))
    clean = render_flight(CAMERA, poses, NRE.to_vector(), progress=False)
    for k in range(3):
        np.testing.assert_array_equal(clean[k], render_heatmaps(CAMERA, poses[k], NRE.to_vector()))
    noise = HeatmapNoise(pixel_sigma=0.05, miss_prob=0.3, spurious_rate=3.0, amplitude_jitter=0.2)
    noisy = render_flight(CAMERA, poses, NRE.to_vector(), cfg=RenderConfig(noise=noise),
                          rng=np.random.default_rng(1), progress=False)
    assert noisy.dtype == np.float32 and np.all(np.isfinite(noisy))
    assert noisy.min() >= 0.0 and noisy.max() <= 1.0
    bg = clean == 0.0
    assert 0.01 < noisy[bg].mean() < 0.05  # clipped N(0, 0.05): mean 0.05 / sqrt(2 pi)
    with pytest.raises(ValueError, match="rng"):
        render_flight(CAMERA, poses, NRE.to_vector(), cfg=RenderConfig(noise=noise))


def test_missed_parts_and_spurious_responses():
    pose = pose_looking_at((150.0, 20.0, 60.0), (0.0, 0.0, 80.0))
    rng = np.random.default_rng(0)
    gone = render_heatmaps(CAMERA, pose, NRE.to_vector(),
                           cfg=RenderConfig(noise=HeatmapNoise(miss_prob=1.0)), rng=rng)
    full = render_heatmaps(CAMERA, pose, NRE.to_vector())
    assert full[:4].max() > 0.9 and gone[:4].max() == 0.0  # every point dropped
    for ch in (4, 5, 6):  # every line loses a stretch (maybe out of view), keeps the rest
        assert 0 < np.count_nonzero(gone[ch] > 0.5) <= np.count_nonzero(full[ch] > 0.5)
    assert np.all(gone[4:] <= full[4:] + 1e-6)
    assert np.count_nonzero(gone[4:] > 0.5) < 0.9 * np.count_nonzero(full[4:] > 0.5)
    away = pose_looking_at((0.0, 0.0, 300.0), (600.0, 0.0, 400.0))  # looking at the sky
    spur = render_heatmaps(CAMERA, away, NRE.to_vector(),
                           cfg=RenderConfig(noise=HeatmapNoise(spurious_rate=20.0)), rng=rng)
    assert spur.max() > 0.3 and np.count_nonzero(spur.max(axis=(1, 2)) > 0) >= 3


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


# ---- trajectory ----------------------------------------------------------------------------


@pytest.mark.parametrize("seed,n,geometry", [
    (0, 2, PAPER_GEOMETRY), (1, 60, REALISTIC_GEOMETRY), (2, 400, PAPER_GEOMETRY),
    (3, 1500, REALISTIC_GEOMETRY), (4, 250, PAPER_GEOMETRY), (5, 250, REALISTIC_GEOMETRY),
])
def test_trajectory_keeps_clear_and_looks_at_the_turbine(seed, n, geometry):
    rng = np.random.default_rng(seed)
    theta = sample_turbine(rng) if seed % 2 else preset_turbine("nrel5mw", rng)
    path = plan_inspection(theta, n, rng, geometry)
    poses = path.world_T_cam
    assert poses.batch_shape == (n,)
    p = poses.translation
    d, _ = distance_to_segments(p, skeleton_segments(theta, geometry))
    assert d.min() >= 3.0
    assert p[:, 2].min() >= 2.0
    R = poses.rotation_matrix()
    assert np.all(R[:, 2, 1] < -0.5)  # camera y points down in the world
    assert np.abs(R[:, 2, 0]).max() < math.sin(math.radians(5.0))  # (almost) no roll
    n_pts, any_part = visible_parts(poses, theta, geometry)
    assert any_part.mean() >= 0.95
    if n >= 60:
        assert set(np.unique(path.phase)) == set(range(len(PHASES)))
        close = path.phase == PHASES.index("blades")
        assert np.mean(n_pts[close] < 6) > 0.9  # close views are partial
        assert n_pts[0] == 6  # the approach starts with the whole turbine in view


def test_trajectory_is_smooth_and_independent_of_n():
    rng_state = 7
    theta = preset_turbine("v80", np.random.default_rng(1))
    dense = inspection_trajectory(theta, 3000, np.random.default_rng(rng_state))
    sparse = inspection_trajectory(theta, 30, np.random.default_rng(rng_state))
    step = np.linalg.norm(np.diff(dense.translation, axis=0), axis=-1)
    assert step.max() < 3.0 * np.median(step)  # evenly spread, no jumps
    dq = quat_multiply(quat_conjugate(dense.wxyz[:-1]), dense.wxyz[1:])
    assert np.degrees(np.linalg.norm(quat_log(dq), axis=-1)).max() < 5.0
    # the sparse flight's keyframes lie on the dense flight's path
    gap = np.linalg.norm(sparse.translation[:, None] - dense.translation[None], axis=-1)
    assert gap.min(axis=1).max() < 1.0
    np.testing.assert_allclose(sparse.translation[[0, -1]], dense.translation[[0, -1]])
    one = inspection_trajectory(theta, 1, np.random.default_rng(rng_state))
    np.testing.assert_allclose(one.translation[0], dense.translation[0])


# ---- turbines and noise ---------------------------------------------------------------------


def test_sampled_turbines_are_realistic():
    rng = np.random.default_rng(0)
    for _ in range(200):
        t = sample_turbine(rng)
        assert 70.0 <= t.tower_height <= 100.0
        assert 40.0 <= t.blade_length <= 63.0 and t.blade_length <= t.tower_height - 20.0
        assert 4.0 <= t.nacelle_length <= 7.0
        assert math.hypot(t.base_x, t.base_y) <= 3.0
        assert t == t.canonical()
    assert preset_turbine("nrel5mw").tower_height == 87.6
    with pytest.raises(ValueError):
        preset_turbine("nonesuch")


def test_drift_starts_at_zero_and_has_the_configured_size():
    poses = look_at(np.random.default_rng(0).normal(0, 50, (500, 3)) + np.array([0, 0, 100]),
                    np.zeros((500, 3)))
    ends_p, ends_r = [], []
    for seed in range(60):
        drifted = drift_poses(poses, np.random.default_rng(seed), 3.0, 4.0)
        dp, dr = pose_errors(drifted, poses)
        assert dp[0] == 0.0 and dr[0] < 1e-7
        assert np.all(np.diff(dp) < 1.0)  # sequential: small steps, no jumps
        ends_p.append(dp[-1])
        ends_r.append(math.degrees(dr[-1]))
    assert 0.7 * 3.0 < math.sqrt(np.mean(np.square(ends_p))) < 1.3 * 3.0
    assert 0.7 * 4.0 < math.sqrt(np.mean(np.square(ends_r))) < 1.3 * 4.0
    none = drift_poses(poses, np.random.default_rng(0), 0.0, 0.0)
    np.testing.assert_array_equal(none.wxyz_xyz, poses.wxyz_xyz)


def test_drift_rotation_is_world_frame():
    R0 = pose_looking_at((10, 0, 5), (0, 0, 5))
    R1 = pose_looking_at((0, 10, 5), (0, 0, 5))
    poses = SE3(np.stack([R0.wxyz_xyz, R0.wxyz_xyz, R1.wxyz_xyz]))
    # the same random step applied to two different orientations: R' R^T = Exp(dphi) must
    # not depend on R (it would if the drift were applied in the camera frame)
    a = drift_poses(SE3(poses.wxyz_xyz[[0, 1]]), np.random.default_rng(5), 0.0, 10.0)
    b = drift_poses(SE3(poses.wxyz_xyz[[0, 2]]), np.random.default_rng(5), 0.0, 10.0)
    qa = a.rotation_matrix()[1] @ poses.rotation_matrix()[1].T
    qb = b.rotation_matrix()[1] @ poses.rotation_matrix()[2].T
    np.testing.assert_allclose(qa, qb, atol=1e-12)
    assert np.degrees(np.arccos((np.trace(qa) - 1) / 2)) > 1.0


def test_perturb_turbine_uses_the_given_sigmas():
    rng = np.random.default_rng(0)
    errs = np.array([param_errors(perturb_turbine(NRE, DEFAULT_TURBINE_SIGMA, rng), NRE)
                     for _ in range(2000)])
    np.testing.assert_allclose(errs.std(axis=0), DEFAULT_TURBINE_SIGMA, rtol=0.1)
    assert np.abs(errs.mean(axis=0)).max() < 0.15
    same = perturb_turbine(NRE, np.zeros(7), rng)
    np.testing.assert_allclose(param_errors(same, NRE), 0.0, atol=1e-12)
