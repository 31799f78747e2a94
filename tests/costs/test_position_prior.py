"""The absolute position prior (turbinefit.costs.position_prior): zero at the measured
positions, whitened by the sigmas, Jacobians against finite differences on the pose
manifold."""

import numpy as np
from support import FD_EPS

from turbinefit.costs.position_prior import position_prior_residuals
from turbinefit.geometry.se3 import SE3


def test_position_prior_residuals_and_jacobian() -> None:
    rng = np.random.default_rng(7)
    poses = SE3.from_rotation_translation(rng.normal(size=(5, 4)), rng.normal(scale=20, size=(5, 3)))
    sigma = rng.uniform(0.01, 3.0, size=(5, 3))
    r, _ = position_prior_residuals(poses, poses.translation, sigma)
    np.testing.assert_allclose(r, 0.0, atol=1e-12)
    measured = poses.translation + rng.normal(scale=0.5, size=(5, 3))
    noisy = poses.retract(rng.normal(scale=0.1, size=(5, 6)))
    r, J = position_prior_residuals(noisy, measured, sigma)
    np.testing.assert_allclose(r * sigma, noisy.translation - measured, atol=1e-12)
    assert J is not None and J.shape == (5, 3, 6)
    for k in range(5):
        for i in range(6):
            d = np.zeros((5, 6))
            d[k, i] = FD_EPS
            rp = position_prior_residuals(noisy.retract(d), measured, sigma, False)[0]
            rm = position_prior_residuals(noisy.retract(-d), measured, sigma, False)[0]
            num = (rp - rm) / (2 * FD_EPS)
            np.testing.assert_allclose(J[k, :, i], num[k], atol=1e-6)
            others = np.delete(num, k, axis=0)  # one pose moves only its own residuals
            np.testing.assert_allclose(others, 0.0, atol=1e-9)
