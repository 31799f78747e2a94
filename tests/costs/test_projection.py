"""Projecting the model (turbinefit.costs.projection): the Jacobian against central finite
differences on the pose manifold."""

import numpy as np
from support import CAMERA, FD_EPS, FD_THETA, model_and_samples, orbit_poses, perturb

from turbinefit.costs.projection import project_points


def test_projection_jacobian():
    poses = orbit_poses(3)
    pts, J_theta, _ = model_and_samples(FD_THETA)
    pr = project_points(CAMERA, poses, pts, J_theta)
    assert pr.inside.sum() > 40
    for k in range(3):
        for i in range(13):
            pp, tp = perturb(poses, FD_THETA, k, i, FD_EPS)
            pm, tm = perturb(poses, FD_THETA, k, i, -FD_EPS)
            up = project_points(CAMERA, pp, model_and_samples(tp, False)[0], None, False).uv[k]
            down = project_points(CAMERA, pm, model_and_samples(tm, False)[0], None, False).uv[k]
            num = (up - down) / (2 * FD_EPS)
            np.testing.assert_allclose(pr.J[k, :, :, i], num, rtol=1e-5, atol=1e-5)
