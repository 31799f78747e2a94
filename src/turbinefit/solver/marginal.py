"""Marginalisation for the fixed-lag smoother: Gaussian priors and Schur complements.

When the tracker (:mod:`turbinefit.solver.tracker`) drops its oldest keyframe ``j``
from the window, every factor that touches pose ``x_j`` (its image terms, its pairwise
edge to ``x_{j+1}``, and the prior left by earlier marginalisations) is linearised at the
current estimate into a quadratic over ``(x_j, x_{j+1}, theta)``; ``x_j`` is then
eliminated by a Schur complement, which leaves a quadratic over ``(x_{j+1}, theta)``: the
new :class:`GaussianPrior`. Its linearisation point stays fixed from then on (first-estimate
Jacobians), so the information already folded in is never re-linearised; the cost of the
prior at a state ``y`` near its point ``y0`` is::

    E_prior(y) = 1/2 d^T H d + g^T d,    d = [x0.local(x); theta - theta0]

with gradient ``H d + g`` and Hessian ``H`` (the rotation part of ``local`` is taken as
linear, exact to first order in the small offsets the window moves its oldest pose by).

The algebra is a dense 19x19 elimination per keyframe, written here with numpy: the
incremental smoothers of GTSAM (iSAM2, ``IncrementalFixedLagSmoother``) do the same
symbolically, but need every factor as a Python object, the overhead the solver study
measured 5-30x slower than our vectorised evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.se3 import SE3

FloatArray = NDArray[np.float64]

#: Size of the state a prior acts on: one pose (6 local coordinates) and theta (7).
PRIOR_DIM = 13


@dataclass(frozen=True)
class GaussianPrior:
    """A quadratic cost on one keyframe pose and theta, linearised at a fixed point.

    Attributes:
        world_T_cam: linearisation point of the pose (a single ``SE3``, camera-to-world).
        theta: (7,) linearisation point of the turbine parameters.
        H: (13, 13) symmetric positive semi-definite information (pose first, in the
            local coordinates of :meth:`SE3.retract`: metres, radians; then theta's units).
        g: (13,) gradient of the cost at the linearisation point.
    """

    world_T_cam: SE3
    theta: FloatArray
    H: FloatArray
    g: FloatArray

    def __post_init__(self) -> None:
        if self.world_T_cam.batch_shape != ():
            raise ValueError(f"prior pose must be a single pose, got {self.world_T_cam.batch_shape}")
        if self.theta.shape != (7,) or self.H.shape != (13, 13) or self.g.shape != (13,):
            raise ValueError("prior needs theta (7,), H (13, 13) and g (13,)")
        if not (np.all(np.isfinite(self.H)) and np.all(np.isfinite(self.g))
                and np.all(np.isfinite(self.theta))):
            raise ValueError("prior contains NaN or inf")

    @staticmethod
    def on_theta(world_T_cam: SE3, theta: FloatArray, sigma: FloatArray) -> GaussianPrior:
        """A prior on theta alone: independent Gaussians of standard deviation ``sigma``
        (7,) around ``theta``; no information on the pose."""
        sigma = np.asarray(sigma, dtype=np.float64)
        if sigma.shape != (7,) or not np.all(sigma > 0):
            raise ValueError("theta prior needs 7 positive standard deviations")
        H = np.zeros((13, 13))
        H[6:, 6:] = np.diag(1.0 / sigma**2)
        return GaussianPrior(world_T_cam, np.asarray(theta, dtype=np.float64).copy(), H,
                             np.zeros(13))

    def delta(self, world_T_cam: SE3, theta: FloatArray) -> FloatArray:
        """(13,) offset of ``(world_T_cam, theta)`` from the linearisation point."""
        return np.concatenate([self.world_T_cam.local(world_T_cam), theta - self.theta])

    def gradient(self, world_T_cam: SE3, theta: FloatArray) -> FloatArray:
        """(13,) gradient ``H d + g`` of the prior's cost at ``(world_T_cam, theta)``."""
        return self.H @ self.delta(world_T_cam, theta) + self.g


@dataclass(frozen=True)
class PoseConditional:
    """What eliminating a pose leaves besides the prior: the pose's linear dependence on
    the variables that remain, ``x = x0.retract(k + K d)`` with ``d`` the offset of
    ``(x_next, theta)`` from the prior's linearisation point. Used for back-substitution
    (:func:`back_substitute`): when later keyframes move the next pose and theta, the
    frozen pose follows as the quadratic model says, without touching its images.

    Attributes:
        world_T_cam: the pose's estimate when it was eliminated.
        K: (6, 13) gain, ``-H_dd^-1 H_dr``.
        k: (6,) offset, ``-H_dd^-1 g_d``.
    """

    world_T_cam: SE3
    K: FloatArray
    k: FloatArray


def schur_eliminate(H: FloatArray, g: FloatArray, drop: int
                    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Marginalise the first ``drop`` variables of the quadratic ``1/2 x^T H x + g^T x``.

    Returns ``(H_rr - H_rd H_dd^-1 H_dr, g_r - H_rd H_dd^-1 g_d)``, symmetrised, and the
    conditional's gain ``-H_dd^-1 H_dr`` and offset ``-H_dd^-1 g_d``. Raises
    ``numpy.linalg.LinAlgError`` if ``H_dd`` is singular or a result is not finite.
    """
    Hdd, Hdr, Hrr = H[:drop, :drop], H[:drop, drop:], H[drop:, drop:]
    X = np.linalg.solve(0.5 * (Hdd + Hdd.T), np.concatenate([Hdr, g[:drop, None]], axis=1))
    Hn = Hrr - Hdr.T @ X[:, :-1]
    gn = g[drop:] - Hdr.T @ X[:, -1]
    Hn = 0.5 * (Hn + Hn.T)
    if not (np.all(np.isfinite(Hn)) and np.all(np.isfinite(gn)) and np.all(np.isfinite(X))):
        raise np.linalg.LinAlgError("non-finite marginal")
    return Hn, gn, -X[:, :-1], -X[:, -1]


def back_substitute(conditionals: list[PoseConditional | None], priors: list[GaussianPrior | None],
                    frozen: list[SE3], last: SE3, theta: FloatArray) -> list[SE3]:
    """Move eliminated poses with the state that remains, newest first.

    ``conditionals[i]`` and ``priors[i]`` come from eliminating pose ``i`` (the prior's
    linearisation point is pose ``i + 1`` and theta at that moment), ``frozen[i]`` is its
    estimate then; ``last`` is the current estimate of the pose after the newest eliminated
    one, ``theta`` the current turbine. A pose without a conditional (a fixed pose, or a
    failed elimination) stays frozen. Linear in the offsets: O(N).
    """
    out = list(frozen)
    nxt = last
    for i in range(len(conditionals) - 1, -1, -1):
        c, p = conditionals[i], priors[i]
        if c is not None and p is not None:
            out[i] = c.world_T_cam.retract(c.k + c.K @ p.delta(nxt, theta))
        nxt = out[i]
    return out


def marginalize_pose(
    *,
    D: FloatArray, C: FloatArray | None, E: FloatArray | None, g_p: FloatArray,
    g_t: FloatArray | None, fixed: bool,
    pair_Ji: FloatArray | None, pair_Jj: FloatArray | None, pair_r: FloatArray | None,
    prior: GaussianPrior | None, world_T_drop: SE3, world_T_next: SE3, theta: FloatArray,
) -> tuple[GaussianPrior, PoseConditional | None]:
    """The prior on ``(x_next, theta)`` left by eliminating pose ``x_drop``, and the
    conditional of ``x_drop`` (None if it is fixed or nothing follows it).

    Args:
        D, C, E, g_p, g_t: the dropped keyframe's own image (and absolute-prior) terms at
            the current estimate: ``J^T H J`` blocks pose-pose (6, 6), pose-theta (6, 7),
            theta-theta (7, 7) and gradient (6,), (7,); C, E, g_t None if theta is fixed.
        fixed: the dropped pose is held fixed (a gauge): it is not a variable, its terms
            only inform ``x_next`` and theta.
        pair_Ji, pair_Jj, pair_r: whitened Jacobians (6, 6) w.r.t. ``x_drop`` and
            ``x_next`` and residual (6,) of the pairwise edge between them, or None if the
            window has no next keyframe (then the prior sits on theta alone, on
            ``world_T_drop``'s linearisation point with a zero pose block).
        prior: the prior currently on ``(x_drop, theta)``, or None.
        world_T_drop, world_T_next, theta: the current estimate.
    """
    # variables: [x_drop (0:6), x_next (6:12), theta (12:19)]
    H = np.zeros((19, 19))
    g = np.zeros(19)
    H[:6, :6] += D
    g[:6] += g_p
    if C is not None and E is not None and g_t is not None:
        H[:6, 12:] += C
        H[12:, :6] += C.T
        H[12:, 12:] += E
        g[12:] += g_t
    if prior is not None:
        gp = prior.gradient(world_T_drop, theta)
        idx = np.r_[0:6, 12:19]
        H[np.ix_(idx, idx)] += prior.H
        g[idx] += gp
    if pair_Ji is not None and pair_Jj is not None and pair_r is not None:
        J = np.concatenate([pair_Ji, pair_Jj], axis=1)  # (6, 12)
        H[:12, :12] += J.T @ J
        g[:12] += J.T @ pair_r
    has_next = pair_Ji is not None
    cond = None
    if fixed:
        Hn, gn = H[6:, 6:].copy(), g[6:].copy()
    else:
        Hn, gn, K, k = schur_eliminate(H, g, 6)
        if has_next:
            cond = PoseConditional(world_T_drop, K, k)
    if not has_next:
        Hn[:6, :] = 0.0
        Hn[:, :6] = 0.0
        gn[:6] = 0.0
    anchor = world_T_next if has_next else world_T_drop
    return GaussianPrior(anchor, np.asarray(theta, dtype=np.float64).copy(), Hn, gn), cond
