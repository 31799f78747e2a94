"""Jacobians of every cost against central finite differences on the pose manifold."""

import math

import numpy as np
import pytest
from helpers import CAMERA, orbit_poses, smooth_heatmaps

from turbinefit.costs.bicubic import interpolate
from turbinefit.costs.correspondence import find_line_correspondences, find_point_correspondences
from turbinefit.costs.heatmap_cost import G_MIN, border_weight, heatmap_residuals
from turbinefit.costs.pairwise import pairwise_residuals, relative_poses
from turbinefit.costs.projection import project_points
from turbinefit.costs.robust import RobustLoss
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.turbine.model import line_samples, model_points

THETA = np.array([0.0, 0.0, 80.0, 0.6, 5.0, 0.3, 50.0])
EPS = 1e-6


def perturb(poses: SE3, theta: np.ndarray, k: int, i: int, eps: float):
    """Perturb local coordinate i (0-5 pose k, 6-12 theta) by eps."""
    if i < 6:
        d = np.zeros((len(poses), 6))
        d[k, i] = eps
        return poses.retract(d), theta
    t = theta.copy()
    t[i - 6] += eps
    return poses, t


def test_bicubic_reproduces_pixels_and_linear_ramps():
    rng = np.random.default_rng(0)
    maps = rng.uniform(0, 1, (2, 7, 12, 16)).astype(np.float32)
    st = HeatmapStack(maps)
    ii, jj = np.meshgrid(np.arange(2, 10), np.arange(2, 14), indexing="ij")
    uv = np.stack([jj.ravel(), ii.ravel()], -1).astype(float)[None].repeat(2, 0)
    ch = np.full(uv.shape[1], 5)
    val, _ = interpolate(st, np.array([0, 1]), ch, uv)
    np.testing.assert_allclose(val, maps[:, 5, ii.ravel(), jj.ravel()], atol=1e-6)
    # a linear ramp is reproduced exactly between pixels, with the exact gradient
    v, u = np.mgrid[0:12, 0:16]
    ramp = np.zeros((1, 7, 12, 16), np.float32)
    ramp[0, 2] = (0.01 * u + 0.02 * v).astype(np.float32)
    uvq = rng.uniform([2, 2], [13, 9], (1, 30, 2))
    val, grad = interpolate(HeatmapStack(ramp), np.array([0]), np.full(30, 2), uvq)
    np.testing.assert_allclose(val, 0.01 * uvq[..., 0] + 0.02 * uvq[..., 1], atol=1e-6)
    np.testing.assert_allclose(grad, np.broadcast_to([0.01, 0.02], grad.shape), atol=1e-6)


def test_bicubic_gradient_matches_finite_differences():
    maps = smooth_heatmaps(1, 40, 50, seed=3)
    st = HeatmapStack(maps)
    rng = np.random.default_rng(1)
    uv = rng.uniform([3, 3], [46, 36], (1, 40, 2))
    ch = np.full(40, 1)
    _, g = interpolate(st, np.array([0]), ch, uv)
    assert g is not None
    for a in range(2):
        d = np.zeros(2)
        d[a] = 1e-5
        num = (interpolate(st, np.array([0]), ch, uv + d)[0]
               - interpolate(st, np.array([0]), ch, uv - d)[0]) / 2e-5
        np.testing.assert_allclose(g[..., a], num, atol=2e-5)


def test_list_and_stacked_storage_agree():
    maps = smooth_heatmaps(3, 30, 40, seed=5)
    rng = np.random.default_rng(2)
    uv = rng.uniform([0, 0], [39, 29], (2, 9, 2))
    ch = np.arange(9) % 7
    kf = np.array([2, 0])
    a = interpolate(HeatmapStack(maps), kf, ch, uv)
    b = interpolate(HeatmapStack(list(maps)), kf, ch, uv)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_non_finite_heatmap_is_reported():
    maps = np.full((2, 7, 10, 10), 0.5, np.float32)
    maps[1, 3, 5, 5] = np.nan
    st = HeatmapStack(list(maps))
    with pytest.raises(ValueError, match="keyframe 1"):
        interpolate(st, np.array([0, 1]), np.array([3]), np.array([[[5.0, 5.0]], [[5.2, 5.1]]]))


def _model(theta, with_j=True):
    P, JP = model_points(theta, with_jacobian=with_j)
    S, JS, ch = line_samples(P, JP, 6)
    return np.concatenate([P, S]), (None if JP is None else np.concatenate([JP, JS])), ch


def test_projection_jacobian():
    poses = orbit_poses(3)
    pts, J_theta, _ = _model(THETA)
    pr = project_points(CAMERA, poses, pts, J_theta)
    assert pr.inside.sum() > 40
    for k in range(3):
        for i in range(13):
            pp, tp = perturb(poses, THETA, k, i, EPS)
            pm, tm = perturb(poses, THETA, k, i, -EPS)
            num = (project_points(CAMERA, pp, _model(tp, False)[0], None, False).uv[k]
                   - project_points(CAMERA, pm, _model(tm, False)[0], None, False).uv[k]) / (2 * EPS)
            np.testing.assert_allclose(pr.J[k, :, :, i], num, rtol=1e-5, atol=1e-5)


def test_border_weight_gradient():
    rng = np.random.default_rng(3)
    uv = rng.uniform(-5, 330, (200, 2))
    w, g = border_weight(uv, 320, 240, 8.0)
    assert np.all((w >= 0) & (w <= 1))
    assert np.all(w[(uv[:, 0] < 0) | (uv[:, 0] > 319)] == 0)
    for a in range(2):
        d = np.zeros(2)
        d[a] = 1e-6
        num = (border_weight(uv + d, 320, 240, 8.0)[0] - border_weight(uv - d, 320, 240, 8.0)[0]) / 2e-6
        np.testing.assert_allclose(g[:, a], num, atol=1e-5)


def test_heatmap_residual_jacobian():
    poses = orbit_poses(2)
    st = HeatmapStack(smooth_heatmaps(2, seed=7))
    _, _, ch = _model(THETA)
    channels = np.r_[np.array([0, 1, 2, 3, 3, 3]), ch]
    kf = np.array([0, 1])

    def res(p, t, with_j=False):
        pts_, Jt, _ = _model(t, with_j)
        pr = project_points(CAMERA, p, pts_, Jt, with_j)
        return heatmap_residuals(st, kf, channels, pr, 1.3, 8.0)

    r, J = res(poses, THETA, True)
    assert np.all(np.isfinite(r)) and np.all(r >= 0)
    for k in range(2):
        for i in range(13):
            pp, tp = perturb(poses, THETA, k, i, EPS)
            pm, tm = perturb(poses, THETA, k, i, -EPS)
            num = (res(pp, tp)[0][k] - res(pm, tm)[0][k]) / (2 * EPS)
            np.testing.assert_allclose(J[k, :, i], num, rtol=1e-4, atol=1e-5)


def test_heatmap_residual_limits():
    """G -> 1: bounded derivative; G -> 0 (empty heat-map): finite cost, zero gradient."""
    poses = orbit_poses(1)
    pts, J_theta, _ = _model(THETA)
    pr = project_points(CAMERA, poses, pts, J_theta)
    ch = np.zeros(pts.shape[0], dtype=int)
    cases = [(floor, fill) for floor in (G_MIN, 0.05) for fill in (0.0, 1.0)]
    for floor, fill in cases:
        expect = math.log1p(floor) - math.log(floor) if fill == 0.0 else 0.0
        st = HeatmapStack(np.full((1, 7, 240, 320), fill, np.float32))
        r, J = heatmap_residuals(st, np.array([0]), ch, pr, 1.0, 0.0, floor)
        ins = pr.inside[0]
        np.testing.assert_allclose(r[0, ins] ** 2, expect + 1e-6, rtol=1e-9)
        assert np.all(np.isfinite(J)) and np.abs(J).max() < 1e-9
        assert np.all(r[0, ~ins] == 0)


def test_pairwise_jacobian_and_zero_at_measurement():
    rng = np.random.default_rng(4)
    q = rng.normal(size=(5, 4))
    poses = SE3.from_rotation_translation(q, rng.normal(scale=5, size=(5, 3)))
    meas = relative_poses(poses[:-1], poses[1:])
    L = np.diag([10.0, 10, 10, 50, 50, 50])
    r, _, _ = pairwise_residuals(poses[:-1], poses[1:], meas, L)
    np.testing.assert_allclose(r, 0, atol=1e-9)
    noisy = poses.retract(rng.normal(scale=0.1, size=(5, 6)))
    r, Ji, Jj = pairwise_residuals(noisy[:-1], noisy[1:], meas, L)
    for e in range(4):
        for which, Jx in ((0, Ji), (1, Jj)):
            for i in range(6):
                d = np.zeros((5, 6))
                d[e + which, i] = EPS
                num = (pairwise_residuals(noisy.retract(d)[:-1], noisy.retract(d)[1:], meas, L)[0][e]
                       - pairwise_residuals(noisy.retract(-d)[:-1], noisy.retract(-d)[1:], meas, L)[0][e]
                       ) / (2 * EPS)
                np.testing.assert_allclose(Jx[e, :, i], num, atol=1e-5)


def test_robust_losses():
    s = np.linspace(0, 20, 201)
    for name in ("huber", "cauchy"):
        loss = RobustLoss(name, 2.0)
        rho, d = loss.evaluate(s)
        np.testing.assert_allclose(rho[:3], s[:3], rtol=0.03)  # ~quadratic near 0
        assert np.all(rho[-1] < s[-1])
        num = np.gradient(rho, s)
        np.testing.assert_allclose(d[1:-1], num[1:-1], atol=0.02)
    with pytest.raises(ValueError):
        RobustLoss("tukey")


def _blob_maps(uv_pt, h=60, w=80, sigma=2.0):
    v, u = np.mgrid[0:h, 0:w].astype(float)
    maps = np.zeros((1, 7, h, w), np.float32)
    maps[0, 2] = np.exp(-((u - uv_pt[0]) ** 2 + (v - uv_pt[1]) ** 2) / (2 * sigma**2))
    return maps


def test_point_correspondence_subpixel():
    true = np.array([40.3, 25.7])
    st = HeatmapStack(_blob_maps(true))
    uv = np.array([[[48.0, 20.0], [5.0, 5.0]]])
    tgt, found = find_point_correspondences(st, np.array([0]), np.array([2, 2]), uv,
                                            np.array([[True, True]]), 15, 0.3)
    assert found.tolist() == [[True, False]]  # the second is too far from the blob
    np.testing.assert_allclose(tgt[0, 0], true, atol=0.15)


def test_line_correspondence_along_normal():
    h, w = 60, 80
    v = np.mgrid[0:h, 0:w][0].astype(float)
    maps = np.zeros((1, 7, h, w), np.float32)
    maps[0, 6] = np.exp(-((v - 30.4) ** 2) / 8.0)  # horizontal line at v = 30.4
    st = HeatmapStack(maps)
    uv = np.array([[[20.0, 38.0], [50.0, 22.0], [50.0, 5.0]]])
    normal = np.array([[[0.0, 1.0], [0.0, 1.0], [1.0, 0.0]]])
    tgt, found = find_line_correspondences(st, np.array([0]), np.array([6, 6, 6]), uv, normal,
                                           np.ones((1, 3), bool), 12, 0.3)
    assert found.tolist() == [[True, True, False]]
    np.testing.assert_allclose(tgt[0, :2, 1], 30.4, atol=0.15)
    np.testing.assert_allclose(tgt[0, :2, 0], [20.0, 50.0])
