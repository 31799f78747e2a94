"""The heat-map cost (turbinefit.costs.heatmap_cost): border weight, gradient and Hessian
against finite differences, the PSD projection, limits."""

import math

import numpy as np
from support import CAMERA, FD_THETA, model_and_samples, orbit_poses, smooth_heatmaps

from turbinefit.costs.heatmap_cost import G_MIN, border_weight, heatmap_terms, psd_2x2
from turbinefit.costs.projection import Projection, project_points
from turbinefit.heatmaps import HeatmapStack


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
    pts, J_theta, _ = model_and_samples(FD_THETA)
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
