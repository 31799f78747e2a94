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


def test_body_odometry_steps_are_the_truth_plus_noise_of_the_documented_size():
    """Each relative pose of the odometry is the ground truth's relative pose plus
    translation noise of sigma sqrt(floor^2 + (f |step|)^2) per axis and rotation noise of
    sigma_r per axis; chained from the first pose, its world frame drifts away."""
    from turbinefit.costs.pairwise import relative_poses
    from turbinefit.geometry.se3 import quat_conjugate, quat_log, quat_multiply
    from turbinefit.sim.noise import (
        VIO_SIGMA_R_DEG,
        VIO_SIGMA_T_M,
        VIO_SIGMA_T_PER_M,
        body_odometry,
    )

    rng = np.random.default_rng(1)
    n = 4001
    # steps of 2-10 m with a turning camera (look-at along a random walk)
    eye = np.cumsum(rng.normal(0, 3.5, (n, 3)), axis=0) + np.array([0, 0, 100])
    gt = look_at(eye, eye + rng.normal(0, 1, (n, 3)) + np.array([30.0, 0, 0]))
    odo = body_odometry(gt, np.random.default_rng(2))
    np.testing.assert_allclose(odo.wxyz_xyz[0], gt.wxyz_xyz[0])
    rel_gt = relative_poses(gt[:-1], gt[1:])
    rel = relative_poses(odo[:-1], odo[1:])
    step = np.linalg.norm(rel_gt.translation, axis=-1)
    sig_t = np.sqrt(VIO_SIGMA_T_M**2 + (VIO_SIGMA_T_PER_M * step) ** 2)
    z = (rel.translation - rel_gt.translation) / sig_t[:, None]  # in the camera's frame
    assert abs(z.mean()) < 0.05 and 0.95 < z.std() < 1.05
    dq = quat_multiply(rel.wxyz, quat_conjugate(rel_gt.wxyz))
    phi = quat_log(np.where(dq[:, :1] < 0, -dq, dq))
    assert 0.95 < np.degrees(phi.std(axis=0)).mean() / VIO_SIGMA_R_DEG < 1.05
    dp, _ = pose_errors(odo, gt)
    assert dp[-1] > 5.0  # the chained frame drifts far over 4000 steps
    exact = body_odometry(gt, np.random.default_rng(2), scale=0.0)
    dp, dr = pose_errors(exact, gt)
    assert dp.max() < 1e-6 and dr.max() < 1e-8
