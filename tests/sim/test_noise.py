"""Simulated noise (turbinefit.sim.noise): odometry drift and turbine perturbations."""

from __future__ import annotations

import math

import numpy as np
from support import NRE, look_at, pose_looking_at

from turbinefit.geometry.se3 import SE3, pose_errors
from turbinefit.sim import drift_poses, perturb_turbine
from turbinefit.sim.noise import DEFAULT_TURBINE_SIGMA
from turbinefit.turbine.model import param_errors


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
