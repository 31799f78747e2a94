"""Jacobians of every cost against central finite differences on the pose manifold."""

import math

import numpy as np
import pytest
from helpers import CAMERA, orbit_poses, smooth_heatmaps

from turbinefit.costs.bicubic import interpolate
from turbinefit.costs.correspondence import (
    correspondence_terms,
    find_line_correspondences,
    find_point_correspondences,
)
from turbinefit.costs.heatmap_cost import G_MIN, border_weight, heatmap_terms, psd_2x2
from turbinefit.costs.pairwise import pairwise_residuals, relative_poses
from turbinefit.costs.projection import Projection, project_points
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
    val, _, _ = interpolate(st, np.array([0, 1]), ch, uv)
    np.testing.assert_allclose(val, maps[:, 5, ii.ravel(), jj.ravel()], atol=1e-6)
    # a linear ramp is reproduced exactly between pixels, with the exact gradient
    v, u = np.mgrid[0:12, 0:16]
    ramp = np.zeros((1, 7, 12, 16), np.float32)
    ramp[0, 2] = (0.01 * u + 0.02 * v).astype(np.float32)
    uvq = rng.uniform([2, 2], [13, 9], (1, 30, 2))
    val, grad, _ = interpolate(HeatmapStack(ramp), np.array([0]), np.full(30, 2), uvq)
    np.testing.assert_allclose(val, 0.01 * uvq[..., 0] + 0.02 * uvq[..., 1], atol=1e-6)
    np.testing.assert_allclose(grad, np.broadcast_to([0.01, 0.02], grad.shape), atol=1e-6)


def test_bicubic_gradient_matches_finite_differences():
    maps = smooth_heatmaps(1, 40, 50, seed=3)
    st = HeatmapStack(maps)
    rng = np.random.default_rng(1)
    uv = rng.uniform([3, 3], [46, 36], (1, 40, 2))
    ch = np.full(40, 1)
    _, g, _ = interpolate(st, np.array([0]), ch, uv)
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


def _pixels(uv: np.ndarray) -> Projection:
    n, m = uv.shape[:2]
    ones = np.ones((n, m), bool)
    return Projection(uv=uv, front=ones, inside=ones, J=None)


def _uv_inside_cells(rng, n, m, lo=12.0, hi=(300.0, 220.0)):
    """Pixels away from the image border and from cell edges (the bicubic Hessian is
    discontinuous across pixel cells, so finite differences must stay inside one)."""
    base = np.floor(rng.uniform(lo, hi, (n, m, 2)))
    return base + rng.uniform(0.25, 0.75, (n, m, 2))


def test_heatmap_gradient_and_hessian():
    """g is the gradient of 1/2 s; the exact Hessian model is the true Hessian wherever
    that is positive semi-definite, and its nearest PSD matrix elsewhere."""
    rng = np.random.default_rng(5)
    st = HeatmapStack(smooth_heatmaps(2, seed=7))
    uv = _uv_inside_cells(rng, 2, 40)
    ch = rng.integers(0, 7, 40)
    kf = np.array([0, 1])
    lam, margin = 1.7, 8.0
    t = heatmap_terms(st, kf, ch, _pixels(uv), lam, margin, 0.05)
    assert t.g is not None and t.H is not None
    h = 1e-5
    for a in range(2):
        d = np.zeros(2)
        d[a] = h
        sp = heatmap_terms(st, kf, ch, _pixels(uv + d), lam, margin, 0.05, False).s
        sm = heatmap_terms(st, kf, ch, _pixels(uv - d), lam, margin, 0.05, False).s
        np.testing.assert_allclose(t.g[..., a], 0.5 * (sp - sm) / (2 * h), rtol=1e-5, atol=1e-8)
    # numerical Hessian (the points are far from the border: no fade term)
    Hn = np.empty((2, 40, 2, 2))
    for a in range(2):
        d = np.zeros(2)
        d[a] = h
        gp = heatmap_terms(st, kf, ch, _pixels(uv + d), lam, margin, 0.05).g
        gm = heatmap_terms(st, kf, ch, _pixels(uv - d), lam, margin, 0.05).g
        Hn[..., a] = (gp - gm) / (2 * h)
    Hn = 0.5 * (Hn + np.swapaxes(Hn, -1, -2))
    ev = np.linalg.eigvalsh(Hn)
    psd = ev[..., 0] > 1e-9
    assert psd.any() and (~psd).any()
    np.testing.assert_allclose(t.H[psd], Hn[psd], rtol=1e-4, atol=1e-7)
    assert np.all(np.linalg.eigvalsh(t.H)[..., 0] > -1e-12)


def test_psd_2x2_is_the_nearest_psd_matrix():
    rng = np.random.default_rng(1)
    a, b, c = rng.normal(size=(3, 500))
    out = psd_2x2(a, b, c)
    M = np.stack([np.stack([a, b], -1), np.stack([b, c], -1)], -2)
    w, V = np.linalg.eigh(M)
    ref = np.einsum("nij,nj,nkj->nik", V, np.maximum(w, 0.0), V)
    np.testing.assert_allclose(out, ref, atol=1e-12)


def test_heatmap_limits():
    """G -> 1: zero cost; G -> 0 (empty heat-map): finite cost; no gradient or curvature
    from a clamped heat-map; no evidence (zero cost) outside the image."""
    poses = orbit_poses(1)
    pts, J_theta, _ = _model(THETA)
    pr = project_points(CAMERA, poses, pts, J_theta)
    ch = np.zeros(pts.shape[0], dtype=int)
    cases = [(floor, fill) for floor in (G_MIN, 0.05) for fill in (0.0, 1.0)]
    for floor, fill in cases:
        expect = math.log1p(floor) - math.log(floor) if fill == 0.0 else 0.0
        st = HeatmapStack(np.full((1, 7, 240, 320), fill, np.float32))
        t = heatmap_terms(st, np.array([0]), ch, pr, 1.0, 0.0, floor)
        ins = pr.inside[0]
        np.testing.assert_allclose(t.s[0, ins], expect, rtol=1e-9, atol=1e-12)
        assert t.g is not None and t.H is not None
        assert np.all(np.isfinite(t.g)) and np.abs(t.g).max() < 1e-9
        assert np.abs(t.H).max() < 1e-9
        assert np.all(t.s[0, ~ins] == 0)


@pytest.mark.parametrize("frame", ["estimated", "measured"])
def test_pairwise_jacobian_and_zero_at_measurement(frame):
    rng = np.random.default_rng(4)
    q = rng.normal(size=(5, 4))
    poses = SE3.from_rotation_translation(q, rng.normal(scale=5, size=(5, 3)))
    meas = relative_poses(poses[:-1], poses[1:])
    F = poses[:-1].rotation_matrix() if frame == "measured" else None
    L = np.diag([10.0, 10, 10, 50, 50, 50])
    r, _, _ = pairwise_residuals(poses[:-1], poses[1:], meas, L, True, F)
    np.testing.assert_allclose(r, 0, atol=1e-9)
    noisy = poses.retract(rng.normal(scale=0.1, size=(5, 6)))
    r, Ji, Jj = pairwise_residuals(noisy[:-1], noisy[1:], meas, L, True, F)
    if frame == "measured":
        # the translation residual ignores the estimate's attitude
        rot = noisy.retract(np.c_[np.zeros((5, 3)), rng.normal(scale=0.1, size=(5, 3))])
        r2, _, _ = pairwise_residuals(rot[:-1], rot[1:], meas, L, True, F)
        np.testing.assert_allclose(r2[:, :3], r[:, :3], atol=1e-12)
    for e in range(4):
        for which, Jx in ((0, Ji), (1, Jj)):
            for i in range(6):
                d = np.zeros((5, 6))
                d[e + which, i] = EPS
                rp = pairwise_residuals(noisy.retract(d)[:-1], noisy.retract(d)[1:], meas, L,
                                        False, F)[0][e]
                rm = pairwise_residuals(noisy.retract(-d)[:-1], noisy.retract(-d)[1:], meas, L,
                                        False, F)[0][e]
                num = (rp - rm) / (2 * EPS)
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


@pytest.mark.parametrize("along_normal", [False, True])
def test_correspondence_gradient_and_gauss_newton_hessian(along_normal):
    rng = np.random.default_rng(5)
    uv = rng.uniform(0, 50, (2, 6, 2))
    front = np.ones((2, 6), dtype=bool)
    front[1, 0] = False
    found = rng.uniform(size=(2, 6)) > 0.3
    target = uv + rng.normal(scale=2.0, size=uv.shape)
    ang = rng.uniform(0, 2 * np.pi, (2, 6))
    normal = np.stack([np.cos(ang), np.sin(ang)], -1) if along_normal else None

    def terms(x, derivatives=False):
        return correspondence_terms(Projection(x, front, front, None), target, found, normal,
                                    2.0, 1.5, derivatives)

    ct = terms(uv, True)
    assert ct.g is not None and ct.H is not None
    assert np.array_equal(ct.used, found & front) and np.all(ct.s[~ct.used] == 0.0)
    for a in range(2):
        d = np.zeros_like(uv)
        d[..., a] = EPS
        num = (terms(uv + d).s - terms(uv - d).s) / (4 * EPS)  # of 1/2 s
        np.testing.assert_allclose(ct.g[..., a], num, atol=1e-6)
        # a quadratic: the Gauss-Newton Hessian is the exact one
        num_h = (terms(uv + d, True).g - terms(uv - d, True).g) / (2 * EPS)
        np.testing.assert_allclose(ct.H[..., :, a], num_h, atol=1e-6)
