"""Structured solve of the damped normal equations.

The Hessian approximation of the joint problem is an *arrow* matrix::

    [ A    C ]   A: block-tridiagonal over the N keyframe poses (6x6 blocks: each pose's
    [ C^T  E ]      image terms on the diagonal, pairwise edges (k, k+1) off it)
                 C: (6N x 7) pose-turbine coupling, E: (7 x 7) turbine block

It is solved in O(N) work: A by a sequential block Cholesky in the compiled kernels
(:mod:`turbinefit._native`), or, without them, by block cyclic reduction in numpy
(odd-even elimination, log2(N) levels of batched 6x6 solves, all right-hand sides at
once, since a sequential sweep would loop in Python); the 7 turbine unknowns by a Schur
complement. Written by hand: no library in the scientific Python stack exploits this
shape (scipy.sparse has no sparse Cholesky and its LU is several times slower here), and
LAPACK's banded Cholesky would need scipy.linalg, whose import alone (0.3 s) costs more
than all the linear solves of a 1000-keyframe fit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from turbinefit import _native

FloatArray = NDArray[np.float64]


def solve_block_tridiagonal(D: FloatArray, B: FloatArray, b: FloatArray) -> FloatArray:
    """Solve ``A x = b`` for symmetric block-tridiagonal A by block cyclic reduction.

    Args:
        D: (n, s, s) diagonal blocks.
        B: (n-1, s, s) sub-diagonal blocks, ``B[k] = A[k+1, k]`` (``A[k, k+1] = B[k]^T``).
        b: (n, s, m) right-hand sides.

    Returns:
        x: (n, s, m). Raises ``numpy.linalg.LinAlgError`` if a pivot block is singular.
    """
    n, s = D.shape[0], D.shape[1]
    if s == 6 and _native.available():
        return _native.block_tridiag_solve(D, B, b)
    if n == 1:
        return np.linalg.solve(D[0], b[0])[None]
    Bp = np.zeros((n, s, s))
    Bp[: n - 1] = B  # Bp[n-1] = 0: no coupling past the end
    odd = np.arange(1, n, 2)
    even = np.arange(0, n, 2)
    m = b.shape[2]
    rhs = np.concatenate([Bp[odd - 1], np.swapaxes(Bp[odd], 1, 2), b[odd]], axis=2)
    X = np.linalg.solve(D[odd], rhs)
    X1, X2, xb = X[..., :s], X[..., s:2 * s], X[..., 2 * s:]  # D^-1 A[i,i-1], A[i,i+1], b
    # Schur complement onto the even blocks
    D2 = D[even].copy()
    b2 = b[even].copy()
    # left odd neighbour i = j - 1 of even j >= 2 (odd[k] = even[k+1] - 1)
    left = odd[: even.size - 1] if even.size > 1 else odd[:0]
    kl = np.arange(left.size)
    D2[1:1 + left.size] -= Bp[left] @ X2[kl]
    b2[1:1 + left.size] -= Bp[left] @ xb[kl]
    # right odd neighbour i = j + 1 of even j (exists for the first odd.size evens)
    r = odd.size
    BT = np.swapaxes(Bp[odd - 1], 1, 2)
    D2[:r] -= BT @ X1
    b2[:r] -= BT @ xb
    # new coupling between even j and j + 2 through odd i = j + 1 (if j + 2 exists)
    nb = even.size - 1
    B2 = -(Bp[odd[:nb]] @ X1[:nb])
    x_even = solve_block_tridiagonal(D2, B2, b2)
    x = np.empty((n, s, m))
    x[even] = x_even
    x_left = x_even[: odd.size]  # x[i - 1]
    x_right = np.zeros((odd.size, s, m))
    has_right = odd + 1 < n
    x_right[has_right] = x_even[1: 1 + int(has_right.sum())]
    x[odd] = xb - X1 @ x_left - X2 @ x_right
    return x


def bounded_step(S: FloatArray, rhs: FloatArray,
                 bounds: tuple[FloatArray, FloatArray] | None = None) -> FloatArray:
    """Minimise ``1/2 x^T S x - rhs^T x`` (S symmetric positive definite, small) subject to
    ``lower <= x <= upper`` (``bounds``; None: unbounded, ``x = S^-1 rhs``).

    Active set: an entry that leaves its bounds is held on the bound it crossed and the
    others are solved again, until none leaves (at most once per entry). The result is the
    exact minimiser over the entries left free, feasible by construction; entries are not
    released again, which is enough for the few bounds of theta (a step that starts inside
    and is pushed onto a bound)."""
    x = np.asarray(np.linalg.solve(S, rhs), dtype=np.float64)
    if bounds is None:
        return x
    lower, upper = bounds
    held = np.zeros(x.size, dtype=bool)
    for _ in range(x.size):
        out = ~held & ((x < lower) | (x > upper))
        if not out.any():
            break
        held |= out
        x = np.where(held, np.clip(x, lower, upper), x)
        free = ~held
        if free.any():
            x[free] = np.linalg.solve(S[np.ix_(free, free)],
                                      rhs[free] - S[np.ix_(free, held)] @ x[held])
    return np.clip(x, lower, upper)


def solve_arrow(
    D: FloatArray, B: FloatArray, C: FloatArray | None, E: FloatArray | None,
    g_p: FloatArray, g_t: FloatArray | None,
    theta_bounds: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """Solve ``[[A, C], [C^T, E]] [dp; dt] = -[g_p; g_t]``.

    Args:
        D: (N, 6, 6) diagonal blocks of A (symmetric positive definite as a whole).
        B: (N-1, 6, 6) sub-diagonal blocks, ``B[k] = A[k+1, k]``.
        C: (N, 6, 7) coupling blocks, or None (turbine fixed).
        E: (7, 7) turbine block, or None.
        g_p: (N, 6), g_t: (7,) or None: gradient.
        theta_bounds: (lower, upper) (7,) each: bounds on ``dt``. The step then minimises
            the quadratic model with ``dt`` inside them (:func:`bounded_step` on the
            Schur complement; the poses follow ``dt`` exactly).

    Returns:
        dp (N, 6), dt (7,) or None. Raises ``numpy.linalg.LinAlgError`` if singular.
    """
    if C is None or E is None or g_t is None:
        x = solve_block_tridiagonal(D, B, g_p[..., None])
        return -x[..., 0], None
    rhs = np.concatenate([g_p[..., None], C], axis=2)  # (N, 6, 8)
    X = solve_block_tridiagonal(D, B, rhs)
    Xg, XC = X[..., 0], X[..., 1:]
    S = E - np.einsum("nai,naj->ij", C, XC)
    rhs_t = -(g_t - np.einsum("nai,na->i", C, Xg))
    dt = bounded_step(0.5 * (S + S.T), rhs_t, theta_bounds)
    dp = -Xg - XC @ dt
    if not (np.all(np.isfinite(dp)) and np.all(np.isfinite(dt))):
        raise np.linalg.LinAlgError("non-finite step")
    return dp, dt


def inverse_spd(S: FloatArray) -> FloatArray:
    """The inverse of a symmetric positive definite matrix, by its Cholesky factor.

    Raises ``numpy.linalg.LinAlgError`` if ``S`` is not positive definite in floating
    point (a direction with no information, or rounding that made one negative: a plain
    inverse would then return negative variances) or the inverse is not finite."""
    L = np.linalg.cholesky(0.5 * (S + S.T))
    Linv = np.linalg.inv(L)
    out = Linv.T @ Linv
    if not np.all(np.isfinite(out)):
        raise np.linalg.LinAlgError("non-finite inverse")
    return np.asarray(out, dtype=np.float64)


def arrow_theta(
    D: FloatArray, B: FloatArray, C: FloatArray, E: FloatArray, g_p: FloatArray,
    g_t: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """theta's information and gradient with the poses eliminated, in O(N).

    Returns ``S = E - C^T A^-1 C`` (symmetrised; its inverse is theta's covariance) and
    ``r = g_t - C^T A^-1 g_p``: the undamped Gauss-Newton step of :func:`solve_arrow` moves
    theta by ``-S^-1 r``. Raises ``numpy.linalg.LinAlgError`` if A is singular."""
    rhs = np.concatenate([g_p[..., None], C], axis=2)  # (N, 6, 8)
    X = solve_block_tridiagonal(D, B, rhs)
    S = E - np.einsum("nai,naj->ij", C, X[..., 1:])
    r = g_t - np.einsum("nai,na->i", C, X[..., 0])
    return 0.5 * (S + S.T), r


def arrow_covariance(
    D: FloatArray, B: FloatArray, C: FloatArray | None, E: FloatArray | None, index: int,
) -> tuple[FloatArray, FloatArray | None]:
    """Marginal covariances of pose ``index`` (6, 6) and of theta (7, 7) or None.

    The covariance is the inverse of the (undamped) arrow matrix ``[[A, C], [C^T, E]]``
    of :func:`solve_arrow`; only the wanted blocks are formed, in O(N): with
    ``S = E - C^T A^-1 C``, ``cov(theta) = S^-1`` and
    ``cov(x_k) = (A^-1)_kk + (A^-1 C)_k S^-1 (A^-1 C)_k^T``. Raises
    ``numpy.linalg.LinAlgError`` if the matrix is singular (``S`` not positive definite,
    :func:`inverse_spd`).
    """
    n = D.shape[0]
    unit = np.zeros((n, 6, 6))
    unit[index] = np.eye(6)
    rhs = unit if C is None else np.concatenate([unit, C], axis=2)
    X = solve_block_tridiagonal(D, B, rhs)
    cov_p = X[index, :, :6]
    cov_t = None
    if C is not None and E is not None:
        XC = X[..., 6:]
        S = E - np.einsum("nai,naj->ij", C, XC)
        cov_t = inverse_spd(S)
        cov_p = cov_p + XC[index] @ cov_t @ XC[index].T
    cov_p = 0.5 * (cov_p + cov_p.T)
    if not (np.all(np.isfinite(cov_p)) and (cov_t is None or np.all(np.isfinite(cov_t)))):
        raise np.linalg.LinAlgError("non-finite covariance")
    return cov_p, cov_t
