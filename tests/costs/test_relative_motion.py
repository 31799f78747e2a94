"""The tie-point term (turbinefit.costs.relative_motion): zero at the poses' own relative
motion, blind to the step's length, Jacobians against finite differences on the pose
manifold; entries kept only between consecutive keyframes."""

import numpy as np
from support import FD_EPS

from turbinefit.costs.pairwise import relative_poses
from turbinefit.costs.relative_motion import RelativeMotions, relative_motion_residuals
from turbinefit.costs.robust import RobustLoss
from turbinefit.geometry.se3 import SE3


def _poses(rng: np.random.Generator, n: int) -> SE3:
    return SE3.from_rotation_translation(rng.normal(size=(n, 4)), rng.normal(scale=10, size=(n, 3)))


def _measured(a: SE3, b: SE3) -> tuple[np.ndarray, np.ndarray]:
    rel = relative_poses(a, b)
    return rel.wxyz, rel.translation / np.linalg.norm(rel.translation, axis=-1, keepdims=True)


def test_zero_at_the_measured_motion_whatever_the_step_length() -> None:
    rng = np.random.default_rng(3)
    a, b = _poses(rng, 4), _poses(rng, 4)
    q, d = _measured(a, b)
    L = np.broadcast_to(np.diag([100.0, 100, 100, 20, 20]), (4, 5, 5))
    r, rho, _, _ = relative_motion_residuals(a, b, q, d, L, RobustLoss(), False)
    np.testing.assert_allclose(r, 0.0, atol=1e-9)
    # the camera j three times further along the same direction: still zero
    far = SE3.from_rotation_translation(b.wxyz, a.translation + 3 * (b.translation - a.translation))
    r, _, _, _ = relative_motion_residuals(a, far, q, d, L, RobustLoss(), False)
    np.testing.assert_allclose(r, 0.0, atol=1e-9)
    # a sideways move is seen
    side = SE3.from_rotation_translation(b.wxyz, b.translation + rng.normal(size=(4, 3)))
    r, rho, _, _ = relative_motion_residuals(a, side, q, d, L, RobustLoss(), False)
    assert np.all(np.abs(r[:, 3:]).sum(axis=1) > 1e-3) and np.all(rho > 0)


def test_jacobians_against_finite_differences() -> None:
    rng = np.random.default_rng(5)
    n = 3
    a, b = _poses(rng, n), _poses(rng, n)
    q, d = _measured(a.retract(rng.normal(scale=0.05, size=(n, 6))), b)
    L = np.triu(rng.normal(size=(n, 5, 5))) + 3 * np.eye(5)
    for loss in (RobustLoss(), RobustLoss("cauchy", 1e3)):
        _, _, Ji, Jj = relative_motion_residuals(a, b, q, d, L, loss)
        assert Ji is not None and Jj is not None
        for which, J in ((0, Ji), (1, Jj)):
            for i in range(6):
                dx = np.zeros((n, 6))
                dx[:, i] = FD_EPS
                pa, pb = (a.retract(dx), b) if which == 0 else (a, b.retract(dx))
                ma, mb = (a.retract(-dx), b) if which == 0 else (a, b.retract(-dx))
                rp = relative_motion_residuals(pa, pb, q, d, L, loss, False)[0]
                rm = relative_motion_residuals(ma, mb, q, d, L, loss, False)[0]
                np.testing.assert_allclose(J[:, :, i], (rp - rm) / (2 * FD_EPS), atol=2e-5)


def test_cauchy_loss_bounds_a_wrong_measurement() -> None:
    rng = np.random.default_rng(8)
    a, b = _poses(rng, 1), _poses(rng, 1)
    q, _ = _measured(a, b)
    wrong = np.array([[0.0, 1.0, 0.0]])
    L = np.eye(5)[None] * 1e3
    r_plain, rho_plain, _, _ = relative_motion_residuals(a, b, q, wrong, L, RobustLoss(), False)
    r_c, rho_c, _, _ = relative_motion_residuals(a, b, q, wrong, L, RobustLoss("cauchy", 3.0), False)
    assert rho_c[0] < 0.01 * rho_plain[0]
    assert np.linalg.norm(r_c) < 0.01 * np.linalg.norm(r_plain)


def test_take_keeps_only_consecutive_entries() -> None:
    m = RelativeMotions.none(6)
    m.valid[1:] = True
    kept = m.take(np.array([1, 2, 4, 5]))
    assert kept.valid.tolist() == [False, True, False, True]
    assert m.append(RelativeMotions.none(2)).valid.tolist() == [False] + [True] * 5 + [False] * 2
