"""Levenberg-Marquardt over keyframe poses and turbine parameters.

Written by hand on top of :mod:`turbinefit.solver.linalg`: the solver study measured
generic Python back-ends (scipy ``least_squares``, pyceres/GTSAM/SymForce with Python
factors) 5-30x slower on this problem, all of the gap being per-factor Python overhead,
while one vectorised evaluation plus an O(N) structured solve matches the C++ reference.

Convergence: the heat-map terms make the cost slightly rugged at the sub-pixel scale, where
LM creeps with many tiny steps that change neither cost nor accuracy; the solver therefore
stops when the cost fell by less than ``function_tolerance`` (relative) over the last
``stall_iterations`` accepted steps, or after 8 rejected steps in a row.

The trust-region strategy follows Ceres: damping ``mu * clip(diag(J^T J), 1e-6, 1e32)``,
step accepted when the gain ratio exceeds 1e-3, ``mu`` scaled by
``max(1/3, 1 - (2 rho - 1)^3)`` on success and by a doubling factor on failure.

Bounds: theta stays inside :data:`~turbinefit.turbine.model.THETA_LOWER` /
``THETA_UPPER`` (widened to include a start outside them): a step that would leave them
is the minimiser of the damped model with the offending entries held on their bounds
(:func:`~turbinefit.solver.linalg.bounded_step`), and its predicted decrease is then that
of the undamped model for the step taken.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.se3 import SE3
from turbinefit.solver.linalg import bounded_step, solve_arrow
from turbinefit.solver.problem import Correspondences, FitProblem, Linearization
from turbinefit.turbine.model import THETA_LOWER, THETA_UPPER

FloatArray = NDArray[np.float64]


@dataclass
class IterationRecord:
    """One LM iteration: the cost after it, whether the step was taken, and timing."""

    round: int
    iteration: int
    stage: str
    cost: float
    step_norm: float
    mu: float
    accepted: bool
    time_s: float


@dataclass
class LMOutcome:
    poses: SE3
    theta: FloatArray
    mu: float
    linearization: Linearization
    iterations: int
    termination: str


def _damp(M: FloatArray, mu: float) -> FloatArray:
    out = M.copy()
    idx = np.arange(M.shape[-1])
    diag = M[..., idx, idx]
    out[..., idx, idx] = diag + mu * np.clip(diag, 1e-6, 1e32)
    return out


def _diag_scale(M: FloatArray) -> FloatArray:
    idx = np.arange(M.shape[-1])
    return np.clip(M[..., idx, idx], 1e-6, 1e32)


def theta_step_bounds(theta: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Bounds (lower, upper) on a step of ``theta`` that keep it inside the plausible
    ranges (widened to include ``theta`` itself)."""
    return (np.minimum(THETA_LOWER, theta) - theta, np.maximum(THETA_UPPER, theta) - theta)


def _model_decrease(lin: Linearization, dp: FloatArray, dt: FloatArray | None) -> float:
    """``-(g^T d + 1/2 d^T M d)``: the decrease the undamped Gauss-Newton model predicts
    for any step ``d = (dp, dt)``."""
    assert lin.D is not None and lin.B is not None and lin.g_p is not None
    quad = float(np.einsum("na,nab,nb->", dp, lin.D, dp))
    if dp.shape[0] > 1:
        quad += 2.0 * float(np.einsum("na,nab,nb->", dp[1:], lin.B, dp[:-1]))
    lin_term = float(np.sum(lin.g_p * dp))
    if dt is not None and lin.E is not None and lin.C is not None and lin.g_t is not None:
        quad += 2.0 * float(np.einsum("na,nai,i->", dp, lin.C, dt)) + float(dt @ lin.E @ dt)
        lin_term += float(lin.g_t @ dt)
    return -lin_term - 0.5 * quad


def levenberg_marquardt(
    problem: FitProblem,
    poses: SE3,
    theta: FloatArray,
    corr: Correspondences,
    lin: Linearization,
    *,
    round_index: int = 0,
    mu: float | None = None,
    max_iterations: int | None = None,
    history: list[IterationRecord] | None = None,
    callback: Callable[[IterationRecord], None] | None = None,
    stage: str = "refine",
) -> LMOutcome:
    """Run LM from ``(poses, theta)`` whose linearisation is ``lin``, correspondences fixed.

    ``mu`` is the starting damping (default ``config.initial_damping``; the outer loop
    passes on the previous round's), ``max_iterations`` overrides the config's."""
    cfg = problem.config
    mu = cfg.initial_damping if mu is None else mu
    nu = 2.0
    optimise_poses = not problem.fixed.all()
    termination = "max_iterations"
    t0 = time.perf_counter()
    costs = [lin.cost]
    rejections = 0
    evaluated = 0  # trial steps evaluated (= records in history)
    for _ in range(max_iterations or cfg.max_iterations):
        assert lin.D is not None and lin.B is not None and lin.g_p is not None
        g_inf = float(np.max(np.abs(lin.g_p))) if optimise_poses else 0.0
        if lin.g_t is not None:
            g_inf = max(g_inf, float(np.max(np.abs(lin.g_t))))
        if g_inf < cfg.gradient_tolerance:
            termination = "gradient_tolerance"
            break
        bounds = theta_step_bounds(theta)
        try:
            if optimise_poses:
                dp, dt = solve_arrow(
                    _damp(lin.D, mu), lin.B, lin.C,
                    None if lin.E is None else _damp(lin.E, mu), lin.g_p, lin.g_t, bounds)
            else:
                assert lin.E is not None and lin.g_t is not None
                dp = np.zeros_like(lin.g_p)
                dt = bounded_step(_damp(lin.E, mu), -lin.g_t, bounds)
        except np.linalg.LinAlgError:
            mu *= nu
            nu *= 2.0
            continue
        if dt is not None and bool(np.any((dt <= bounds[0]) | (dt >= bounds[1]))):
            pred = _model_decrease(lin, dp, dt)  # a step held on a bound
        else:
            # predicted decrease of the Gauss-Newton model: 1/2 (mu d^T diag d - g^T d)
            scale_p = _diag_scale(lin.D)
            pred = 0.5 * (mu * float(np.sum(dp * dp * scale_p)) - float(np.sum(dp * lin.g_p)))
            if dt is not None and lin.g_t is not None and lin.E is not None:
                pred += 0.5 * (mu * float(np.sum(dt * dt * _diag_scale(lin.E)))
                               - float(dt @ lin.g_t))
        step_norm = float(np.sqrt(np.sum(dp * dp) + (0.0 if dt is None else dt @ dt)))
        with np.errstate(over="ignore"):  # inf for absurd inputs: no step is then small
            x_norm = float(np.linalg.norm(theta) + np.linalg.norm(poses.translation))
        if step_norm <= cfg.parameter_tolerance * (x_norm + cfg.parameter_tolerance):
            termination = "parameter_tolerance"
            break
        new_poses = poses.retract(dp) if optimise_poses else poses
        new_theta = theta + dt if dt is not None else theta
        new_lin = problem.linearize(new_poses, new_theta, corr)
        evaluated += 1
        actual = lin.cost - new_lin.cost
        gain = actual / pred if pred > 0 else -1.0
        accepted = bool(np.isfinite(new_lin.cost) and gain > 1e-3)
        if accepted:
            poses, theta, lin = new_poses, new_theta, new_lin
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            nu = 2.0
        else:
            mu *= nu
            nu *= 2.0
        rec = IterationRecord(round_index, evaluated, stage, lin.cost, step_norm, mu, accepted,
                              time.perf_counter() - t0)
        if history is not None:
            history.append(rec)
        if callback is not None:
            callback(rec)
        if accepted:
            rejections = 0
            costs.append(lin.cost)
            window = cfg.stall_iterations
            if len(costs) > window and (
                costs[-1 - window] - costs[-1] <= cfg.function_tolerance * max(costs[-1], 1e-300)
            ):
                termination = "function_tolerance"
                break
        else:
            rejections += 1
        if mu > 1e16 or rejections >= 8:
            termination = "no_progress"
            break
    return LMOutcome(poses, theta, mu, lin, evaluated, termination)
