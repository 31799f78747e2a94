"""Marginalisation (turbinefit.solver.marginal): Schur complements as Gaussian marginals,
priors, sequential marginalisation, back substitution."""

from __future__ import annotations

import numpy as np
import pytest
from support import simulated_flight

from turbinefit.geometry.se3 import SE3
from turbinefit.solver.config import FitConfig
from turbinefit.solver.marginal import GaussianPrior, back_substitute, marginalize_pose, schur_eliminate
from turbinefit.solver.problem import FitProblem, Linearization


def dense(lin: Linearization) -> tuple[np.ndarray, np.ndarray]:
    """The full normal equations (6N + 7) of an arrow linearisation."""
    assert lin.D is not None and lin.B is not None and lin.C is not None and lin.E is not None
    assert lin.g_p is not None and lin.g_t is not None
    n = lin.D.shape[0]
    H = np.zeros((6 * n + 7, 6 * n + 7))
    for k in range(n):
        H[6 * k:6 * k + 6, 6 * k:6 * k + 6] = lin.D[k]
        H[6 * k:6 * k + 6, 6 * n:] = lin.C[k]
        H[6 * n:, 6 * k:6 * k + 6] = lin.C[k].T
        if k + 1 < n:
            H[6 * k + 6:6 * k + 12, 6 * k:6 * k + 6] = lin.B[k]
            H[6 * k:6 * k + 6, 6 * k + 6:6 * k + 12] = lin.B[k].T
    H[6 * n:, 6 * n:] = lin.E
    return H, np.concatenate([lin.g_p.ravel(), lin.g_t])


def test_schur_eliminate_is_the_marginal_of_a_gaussian() -> None:
    rng = np.random.default_rng(0)
    A = rng.normal(size=(19, 19))
    H = A @ A.T + 0.5 * np.eye(19)
    g = rng.normal(size=19)
    Hn, gn, K, k = schur_eliminate(H, g, 6)
    # marginal covariance = block of the full covariance; the minimiser agrees
    np.testing.assert_allclose(np.linalg.inv(Hn), np.linalg.inv(H)[6:, 6:], rtol=1e-9, atol=1e-12)
    x = np.linalg.solve(H, -g)
    np.testing.assert_allclose(np.linalg.solve(Hn, -gn), x[6:], rtol=1e-9, atol=1e-12)
    # the conditional gives the eliminated part back from the rest
    np.testing.assert_allclose(k + K @ x[6:], x[:6], rtol=1e-9, atol=1e-12)


def test_gaussian_prior_checks_its_input() -> None:
    pose = SE3.identity()
    with pytest.raises(ValueError, match="NaN"):
        GaussianPrior(pose, np.zeros(7), np.full((13, 13), np.nan), np.zeros(13))
    with pytest.raises(ValueError, match="single pose"):
        GaussianPrior(SE3.identity((2,)), np.zeros(7), np.zeros((13, 13)), np.zeros(13))
    with pytest.raises(ValueError, match="positive"):
        GaussianPrior.on_theta(pose, np.zeros(7), np.zeros(7))
    p = GaussianPrior.on_theta(pose, np.ones(7), np.full(7, 2.0))
    np.testing.assert_allclose(p.gradient(pose, np.ones(7) + 2.0)[6:], np.full(7, 0.5))


def test_sequential_marginalisation_equals_the_batch_schur_complement() -> None:
    """Eliminating keyframes 0..m-1 one at a time (all at one linearisation point) leaves
    exactly the batch problem's Schur complement onto (x_m, theta)."""
    flight = simulated_flight(10, seed=2)
    cfg = FitConfig()
    m = 6
    poses = flight.world_T_cam
    theta = flight.turbine.to_vector()
    batch = FitProblem(flight, cfg, keyframes=np.arange(m + 1))  # keyframe 0 fixed (gauge)
    prior = None
    for j in range(m):
        one = FitProblem(flight, cfg, keyframes=np.array([j]), fixed=np.array([j == 0]))
        lin1 = one.linearize(poses[j:j + 1], theta, one.find_correspondences(poses[j:j + 1], theta))
        assert lin1.D is not None and lin1.C is not None and lin1.g_p is not None
        r, Ji, Jj = batch.pairwise_edge(poses, j)
        prior, cond = marginalize_pose(
            D=lin1.D[0], C=lin1.C[0], E=lin1.E, g_p=lin1.g_p[0], g_t=lin1.g_t, fixed=j == 0,
            pair_Ji=Ji, pair_Jj=Jj, pair_r=r, prior=prior, world_T_drop=poses[j],
            world_T_next=poses[j + 1], theta=theta)
        assert (cond is None) == (j == 0)
    assert prior is not None
    # batch: all keyframes 0..m, minus keyframe m's own image terms, poses 1..m-1 eliminated
    kf = batch.keyframes
    H, g = dense(batch.linearize(poses[kf], theta, batch.find_correspondences(poses[kf], theta)))
    last = FitProblem(flight, cfg, keyframes=np.array([m]), fixed=np.array([False]))
    Hm, gm = dense(last.linearize(poses[m:m + 1], theta,
                                  last.find_correspondences(poses[m:m + 1], theta)))
    idx = np.r_[6 * m:6 * m + 6, 6 * (m + 1):6 * (m + 1) + 7]
    H[np.ix_(idx, idx)] -= Hm
    g[idx] -= gm
    keep = np.r_[6:6 * (m + 1) + 7]  # drop the fixed keyframe 0
    Hn, gn, _, _ = schur_eliminate(H[np.ix_(keep, keep)], g[keep], 6 * (m - 1))
    scale = np.abs(Hn).max()
    np.testing.assert_allclose(prior.H, Hn, rtol=1e-7, atol=1e-9 * scale)
    np.testing.assert_allclose(prior.g, gn, rtol=1e-7, atol=1e-9 * np.abs(gn).max())


def test_back_substitution_of_a_linear_chain_is_exact() -> None:
    """On quadratic data, back-substituting the stored conditionals from the final state
    reproduces the joint minimiser (marginalise, solve the rest, recover the rest)."""
    rng = np.random.default_rng(3)
    pose0, pose1 = SE3.identity(), SE3.identity().retract(rng.normal(size=6) * 0.01)
    A = rng.normal(size=(19, 19))
    H = A @ A.T + np.eye(19)
    g = rng.normal(size=19)
    theta = rng.normal(size=7)
    Hn, gn, K, k = schur_eliminate(H, g, 6)
    prior = GaussianPrior(pose1, theta, Hn, gn)
    from turbinefit.solver.marginal import PoseConditional

    x = np.linalg.solve(H, -g)
    moved = back_substitute([PoseConditional(pose0, K, k)], [prior], [pose0],
                            pose1.retract(x[6:12]), theta + x[12:])
    np.testing.assert_allclose(pose0.local(moved[0]), x[:6], atol=1e-9)
    # without a conditional a pose stays where it was frozen
    assert back_substitute([None], [None], [pose0], pose1, theta)[0] is pose0
