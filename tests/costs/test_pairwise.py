"""The pairwise (odometry) cost (turbinefit.costs.pairwise): zero at the measurement,
Jacobians against finite differences on the pose manifold."""

import numpy as np
import pytest
from support import FD_EPS

from turbinefit.costs.pairwise import pairwise_residuals, relative_poses
from turbinefit.geometry.se3 import SE3


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
                d[e + which, i] = FD_EPS
                rp = pairwise_residuals(noisy.retract(d)[:-1], noisy.retract(d)[1:], meas, L,
                                        False, F)[0][e]
                rm = pairwise_residuals(noisy.retract(-d)[:-1], noisy.retract(-d)[1:], meas, L,
                                        False, F)[0][e]
                num = (rp - rm) / (2 * FD_EPS)
                np.testing.assert_allclose(Jx[e, :, i], num, atol=1e-5)
