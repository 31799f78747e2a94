"""The width term (turbinefit.costs.silhouette_width): depths measured from apparent
widths, the residual's gradient and Gauss-Newton Hessian against finite differences of
its cost, a step that takes a camera moved along its line of sight back to the measured
depth, and the blade section's silhouette half-width (turbinefit.turbine.solid)."""

import math

import numpy as np
import pytest

from turbinefit.costs.robust import RobustLoss
from turbinefit.costs.silhouette_width import WidthDepths, measure_depths, width_terms
from turbinefit.geometry.se3 import SE3
from turbinefit.turbine.model import TurbineParams
from turbinefit.turbine.solid import (
    TurbineSolid,
    blade_profile,
    blade_silhouette_half_width,
    blade_twist,
)


def _poses(n: int, seed: int = 0) -> SE3:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return SE3(np.concatenate([q, rng.normal(0, 3, (n, 3))], axis=1))


def _points_in_front(poses: SE3, m: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    cam_p = np.concatenate([rng.uniform(-3, 3, (len(poses), m, 2)),
                            rng.uniform(6, 14, (len(poses), m, 1))], axis=-1)
    R = poses.rotation_matrix()
    return np.einsum("nij,nmj->nmi", R, cam_p) + poses.translation[:, None]


def test_measured_depth_is_the_one_whose_width_was_seen() -> None:
    z0 = np.array([[10.0, 10.0, 10.0, 10.0]])
    w0 = np.array([[40.0, 40.0, 40.0, 2.0]])  # predicted at z0
    seen = np.array([[50.0, 32.0, 40.0, 2.5]])  # nearer, further, the same, too thin
    m = measure_depths(z0, w0, seen, np.ones_like(z0, bool), separation_sigma=1.0)
    np.testing.assert_allclose(m.depth[0, :3], [8.0, 12.5, 10.0])
    assert m.found.tolist() == [[True, True, True, False]]
    # sigma: z * sigma_w / w
    np.testing.assert_allclose(m.sigma[0, :3], [8.0 / 50, 12.5 / 32, 10.0 / 40])
    m2 = measure_depths(z0, w0, seen, np.ones_like(z0, bool), 1.0, shape_rel_sigma=0.1)
    assert np.all(m2.sigma[0, :3] > m.sigma[0, :3])
    bad = measure_depths(np.array([[np.nan, -1.0]]), np.array([[40.0, 40.0]]),
                         np.array([[40.0, 40.0]]), np.ones((1, 2), bool), 1.0)
    assert not bad.found.any() and np.all(np.isfinite(bad.depth))


@pytest.mark.parametrize("loss", [RobustLoss("none"), RobustLoss("cauchy", 2.0)])
def test_gradient_and_hessian_against_finite_differences(loss: RobustLoss) -> None:
    N, M = 3, 5
    poses = _poses(N)
    pts = _points_in_front(poses, M)
    rng = np.random.default_rng(2)
    JA = rng.normal(size=(M, 3, 7))
    JB = rng.normal(size=(M, 3, 7))
    f = rng.uniform(0, 1, (N, M))
    J_pts = JA[None] * (1 - f)[..., None, None] + JB[None] * f[..., None, None]
    R = poses.rotation_matrix()
    z = np.einsum("nk,nmk->nm", R[:, :, 2], pts - poses.translation[:, None])
    meas = WidthDepths(z + rng.normal(0, 0.5, z.shape), np.full(z.shape, 0.3),
                       np.ones(z.shape, bool))
    meas.found[1, 2] = False

    def cost(dx: np.ndarray) -> float:
        """Cost with pose k updated by dx[k, :6] and the points moved by theta dx[:, 6:]."""
        p = poses.retract(dx[:, :6])
        moved = pts + np.einsum("nmij,j->nmi", J_pts, dx[0, 6:])
        return width_terms(p, moved, None, meas, 1.7, False, loss)[0]

    c, count, H, g = width_terms(poses, pts, (JA, JB, f), meas, 1.7, True, loss)
    assert count == N * M - 1 and H is not None and g is not None
    assert c == pytest.approx(cost(np.zeros((N, 13))))
    eps = 1e-6
    for k in range(N):
        for i in range(6):
            dx = np.zeros((N, 13))
            dx[k, i] = eps
            num = (cost(dx) - cost(-dx)) / (2 * eps)
            assert g[k, i] == pytest.approx(num, rel=1e-5, abs=1e-7)
    # theta is shared: its gradient is the sum over keyframes
    for j in range(7):
        dx = np.zeros((N, 13))
        dx[0, 6 + j] = eps
        num = (cost(dx) - cost(-dx)) / (2 * eps)
        assert g[:, 6 + j].sum() == pytest.approx(num, rel=1e-5, abs=1e-7)
    if loss.name == "none":  # Gauss-Newton is exact for a residual linear in the point
        k, i = 1, 2
        dx = np.zeros((N, 13))
        dx[k, i] = 1e-4
        num = (cost(dx) - 2 * cost(np.zeros((N, 13))) + cost(-dx)) / 1e-8
        assert H[k, i, i] == pytest.approx(num, rel=1e-3)


def test_a_step_takes_the_camera_back_to_the_measured_depth() -> None:
    """A camera moved 2 m back along its optical axis: one Gauss-Newton step of the width
    term alone (translation only) brings it back."""
    poses = _poses(1, seed=5)
    pts = _points_in_front(poses, 8, seed=6)
    R = poses.rotation_matrix()
    z = np.einsum("nk,nmk->nm", R[:, :, 2], pts - poses.translation[:, None])
    meas = WidthDepths(z, np.full(z.shape, 0.2), np.ones(z.shape, bool))
    back = poses.retract(np.concatenate([R[0, :, 2] * -2.0, np.zeros(3)])[None])
    _, _, H, g = width_terms(back, pts, None, meas, 1.0, True, RobustLoss("none"))
    assert H is not None and g is not None
    Ht = H[0, :3, :3] + 1e-9 * np.eye(3)
    dt = -np.linalg.lstsq(Ht, g[0, :3], rcond=None)[0]
    moved = back.retract(np.concatenate([dt, np.zeros(3)])[None])
    depth_axis = R[0, :, 2]
    assert float((moved.translation[0] - poses.translation[0]) @ depth_axis) == \
        pytest.approx(0.0, abs=1e-6)


def test_blade_section_silhouette() -> None:
    """Seen face-on the section shows its chord, edge-on its thickness; dh/dpitch is the
    derivative of h."""
    theta = TurbineParams(0.0, 0.0, 90.0, 0.3, 5.0, 0.2, 60.0).to_vector()
    solid = TurbineSolid(theta)
    u = np.array([0.3, 0.6, 0.9])
    A, B = blade_profile(u.astype(np.float32), solid.b)
    e = solid.tips[1] - solid.hub
    e /= np.linalg.norm(e)
    c0 = solid.chord_axis(1)
    blade = np.full(3, 1)
    for i, ui in enumerate(u):
        beta = float(blade_twist(np.float32(ui), 0.0))
        chord = math.cos(beta) * c0 + math.sin(beta) * np.cross(e, c0)
        thick = np.cross(e, chord)
        h_face, _ = blade_silhouette_half_width(solid, blade[:1], u[i:i + 1], chord[None], 0.0)
        h_edge, _ = blade_silhouette_half_width(solid, blade[:1], u[i:i + 1], thick[None], 0.0)
        assert h_face[0] == pytest.approx(float(A[i]), rel=1e-6)
        assert h_edge[0] == pytest.approx(float(B[i]), rel=1e-6)
    n = np.cross(e, [0.3, 0.4, 0.5])
    n = np.tile(n / np.linalg.norm(n), (3, 1))
    h, dh = blade_silhouette_half_width(solid, blade, u, n, 0.1)
    hp, _ = blade_silhouette_half_width(solid, blade, u, n, 0.1 + 1e-3)
    hm, _ = blade_silhouette_half_width(solid, blade, u, n, 0.1 - 1e-3)
    np.testing.assert_allclose(dh, (hp - hm) / 2e-3, rtol=1e-3, atol=1e-6)  # float32 angles
    assert np.all(h > 0)
