"""Simulated heat-maps (turbinefit.sim.render): point peaks and line ridges on the
(distorted) projection, clipping, flights, missed and spurious responses."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from support import NRE, SIM_CAMERA, look_at, pose_looking_at

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.sim import HeatmapNoise, RenderConfig, render_flight, render_heatmaps
from turbinefit.turbine.model import LINES, POINT_CHANNELS, TurbineParams, model_points

DISTORTED = replace(SIM_CAMERA, distortion=(-0.25, 0.08, 0.002, -0.001, 0.0))

SIGMA = 2.0


def project(camera: PinholeCamera, pose: SE3, world_p: np.ndarray):
    uv, valid, _ = camera.project(pose.inverse() @ world_p)
    return uv, valid


@pytest.mark.parametrize("camera", [SIM_CAMERA, DISTORTED], ids=["pinhole", "distorted"])
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
    h = render_heatmaps(SIM_CAMERA, pose, theta.to_vector(), cfg=RenderConfig(sigma_px=SIGMA))
    pts, _ = model_points(theta.to_vector())
    cam_p = pose.inverse() @ pts
    uv, _, _ = SIM_CAMERA.project_unbounded(cam_p)
    # the tower's midpoint projects at the image centre row; profile across it
    mid_world = 0.5 * (pts[0] + pts[1])
    m_uv, m_valid = project(SIM_CAMERA, pose, mid_world)
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
    straight = render_heatmaps(SIM_CAMERA, pose, NRE.to_vector(), cfg=RenderConfig(sigma_px=SIGMA))
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
    h = render_heatmaps(SIM_CAMERA, pose, theta.to_vector(), cfg=RenderConfig(sigma_px=SIGMA))
    assert np.all(np.isfinite(h))
    assert h[0].max() == 0.0 and h[1].max() == 0.0 and h[2].max() == 0.0  # behind: no blob
    assert h[4].max() == 0.0 and h[5].max() == 0.0  # tower and nacelle wholly behind
    uv, valid = project(SIM_CAMERA, pose, tip)
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
    h2 = render_heatmaps(SIM_CAMERA, away, theta.to_vector())
    assert np.all(np.isfinite(h2)) and h2.max() == 0.0


def test_render_flight_matches_single_frames_and_noise_is_bounded():
    poses = look_at(np.array([[150.0, 20.0, 60.0], [-100.0, 80.0, 90.0], [30.0, -12.0, 40.0]]),
                    np.array([[0.0, 0.0, 80.0], [0.0, 0.0, 90.0], [0.0, 0.0, 40.0]]))
    clean = render_flight(SIM_CAMERA, poses, NRE.to_vector(), progress=False)
    for k in range(3):
        np.testing.assert_array_equal(clean[k], render_heatmaps(SIM_CAMERA, poses[k], NRE.to_vector()))
    noise = HeatmapNoise(pixel_sigma=0.05, miss_prob=0.3, spurious_rate=3.0, amplitude_jitter=0.2)
    noisy = render_flight(SIM_CAMERA, poses, NRE.to_vector(), cfg=RenderConfig(noise=noise),
                          rng=np.random.default_rng(1), progress=False)
    assert noisy.dtype == np.float32 and np.all(np.isfinite(noisy))
    assert noisy.min() >= 0.0 and noisy.max() <= 1.0
    bg = clean == 0.0
    assert 0.01 < noisy[bg].mean() < 0.05  # clipped N(0, 0.05): mean 0.05 / sqrt(2 pi)
    with pytest.raises(ValueError, match="rng"):
        render_flight(SIM_CAMERA, poses, NRE.to_vector(), cfg=RenderConfig(noise=noise))


def test_missed_parts_and_spurious_responses():
    pose = pose_looking_at((150.0, 20.0, 60.0), (0.0, 0.0, 80.0))
    rng = np.random.default_rng(0)
    gone = render_heatmaps(SIM_CAMERA, pose, NRE.to_vector(),
                           cfg=RenderConfig(noise=HeatmapNoise(miss_prob=1.0)), rng=rng)
    full = render_heatmaps(SIM_CAMERA, pose, NRE.to_vector())
    assert full[:4].max() > 0.9 and gone[:4].max() == 0.0  # every point dropped
    for ch in (4, 5, 6):  # every line loses a stretch (maybe out of view), keeps the rest
        assert 0 < np.count_nonzero(gone[ch] > 0.5) <= np.count_nonzero(full[ch] > 0.5)
    assert np.all(gone[4:] <= full[4:] + 1e-6)
    assert np.count_nonzero(gone[4:] > 0.5) < 0.9 * np.count_nonzero(full[4:] > 0.5)
    away = pose_looking_at((0.0, 0.0, 300.0), (600.0, 0.0, 400.0))  # looking at the sky
    spur = render_heatmaps(SIM_CAMERA, away, NRE.to_vector(),
                           cfg=RenderConfig(noise=HeatmapNoise(spurious_rate=20.0)), rng=rng)
    assert spur.max() > 0.3 and np.count_nonzero(spur.max(axis=(1, 2)) > 0) >= 3
