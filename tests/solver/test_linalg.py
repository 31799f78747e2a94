"""Structured linear algebra (turbinefit.solver.linalg): arrow solves and covariances
against dense ones."""

from __future__ import annotations

import numpy as np
import pytest

from turbinefit.solver.linalg import arrow_covariance, solve_arrow


@pytest.mark.parametrize("n", [2, 3, 7, 16, 33])
def test_structured_solve_matches_dense(n):
    rng = np.random.default_rng(n)
    J = rng.normal(size=(12 * n, 6 * n + 7))
    # impose the arrow sparsity: each row touches two consecutive poses and theta
    for r in range(12 * n):
        k = r % max(n - 1, 1)
        mask = np.zeros(6 * n + 7, bool)
        mask[6 * k: 6 * k + 12] = True
        mask[6 * n:] = True
        J[r, ~mask] = 0
    H = J.T @ J + 0.1 * np.eye(6 * n + 7)
    g = rng.normal(size=6 * n + 7)
    D = np.stack([H[6 * k:6 * k + 6, 6 * k:6 * k + 6] for k in range(n)])
    B = np.stack([H[6 * k + 6:6 * k + 12, 6 * k:6 * k + 6] for k in range(n - 1)])
    C = np.stack([H[6 * k:6 * k + 6, 6 * n:] for k in range(n)])
    E = H[6 * n:, 6 * n:]
    dp, dt = solve_arrow(D, B, C, E, g[:6 * n].reshape(n, 6), g[6 * n:])
    ref = np.linalg.solve(H, -g)
    np.testing.assert_allclose(np.r_[dp.ravel(), dt], ref, rtol=1e-8, atol=1e-10)
    dp2, none = solve_arrow(D, B, None, None, g[:6 * n].reshape(n, 6), None)
    assert none is None
    np.testing.assert_allclose(dp2.ravel(), np.linalg.solve(H[:6 * n, :6 * n], -g[:6 * n]),
                               rtol=1e-8, atol=1e-10)


def test_arrow_covariance_equals_the_dense_inverse() -> None:
    rng = np.random.default_rng(1)
    n = 5
    A = rng.normal(size=(6 * n + 7, 6 * n + 7))
    M = A @ A.T + np.eye(6 * n + 7)
    # keep only the arrow pattern (block-tridiagonal poses, dense theta), still SPD
    mask = np.zeros_like(M, dtype=bool)
    for i in range(n):
        for j in range(max(0, i - 1), min(n, i + 2)):
            mask[6 * i:6 * i + 6, 6 * j:6 * j + 6] = True
    mask[6 * n:, :] = mask[:, 6 * n:] = True
    M = np.where(mask, M, 0.0)
    M += np.eye(M.shape[0]) * (np.abs(M).sum(axis=1).max())
    D = np.stack([M[6 * k:6 * k + 6, 6 * k:6 * k + 6] for k in range(n)])
    B = np.stack([M[6 * k + 6:6 * k + 12, 6 * k:6 * k + 6] for k in range(n - 1)])
    C = np.stack([M[6 * k:6 * k + 6, 6 * n:] for k in range(n)])
    E = M[6 * n:, 6 * n:]
    inv = np.linalg.inv(M)
    for index in (0, 2, n - 1):
        cov_p, cov_t = arrow_covariance(D, B, C, E, index)
        np.testing.assert_allclose(cov_p, inv[6 * index:6 * index + 6, 6 * index:6 * index + 6],
                                   rtol=1e-8, atol=1e-12)
        assert cov_t is not None
        np.testing.assert_allclose(cov_t, inv[6 * n:, 6 * n:], rtol=1e-8, atol=1e-12)


def test_bounded_step_is_the_constrained_minimiser() -> None:
    """Free entries have zero gradient; entries held on a bound have a gradient pushing
    them outward; without bounds it is the plain solve."""
    from turbinefit.solver.linalg import bounded_step

    rng = np.random.default_rng(3)
    A = rng.normal(size=(7, 7))
    S = A @ A.T + 7 * np.eye(7)
    rhs = rng.normal(size=7) * 5
    np.testing.assert_allclose(bounded_step(S, rhs), np.linalg.solve(S, rhs))
    lower, upper = np.full(7, -np.inf), np.full(7, np.inf)
    x0 = np.linalg.solve(S, rhs)
    upper[np.argmax(x0)] = 0.5 * x0.max()
    lower[np.argmin(x0)] = 0.5 * x0.min()
    x = bounded_step(S, rhs, (lower, upper))
    assert np.all(x >= lower) and np.all(x <= upper)
    grad = S @ x - rhs  # of 1/2 x^T S x - rhs^T x
    at_up, at_lo = x >= upper, x <= lower
    free = ~(at_up | at_lo)
    assert at_up.any() and at_lo.any()
    np.testing.assert_allclose(grad[free], 0.0, atol=1e-9)
    assert np.all(grad[at_up] <= 1e-12) and np.all(grad[at_lo] >= -1e-12)
