"""Fit a flight: the outer correspondence loop around Levenberg-Marquardt."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from turbinefit.flight import Flight
from turbinefit.geometry.se3 import SE3
from turbinefit.solver.config import FitConfig
from turbinefit.solver.lm import IterationRecord, levenberg_marquardt
from turbinefit.solver.problem import Correspondences, FitProblem
from turbinefit.turbine.model import TurbineParams


@dataclass
class FitResult:
    """What :func:`fit` returns.

    Attributes:
        world_T_cam: (N,) optimised camera-to-world poses.
        turbine: optimised turbine (canonical angle ranges).
        initial_cost, final_cost: total cost before and after (1/2 sum of squares; with
            corr terms each is measured with the correspondences of that moment).
        initial_terms, final_terms: the cost split by term (points, lines, pairwise, prior).
        iterations: LM iterations over all rounds; rounds: correspondence rounds.
        termination: why the last LM run stopped.
        history: every LM iteration.
        time_s: wall time of the solve [s].
        num_residuals: scalar residuals in the final problem.
        config: the configuration used.
    """

    world_T_cam: SE3
    turbine: TurbineParams
    initial_cost: float
    final_cost: float
    initial_terms: dict[str, float]
    final_terms: dict[str, float]
    iterations: int
    rounds: int
    termination: str
    time_s: float
    num_residuals: int
    config: FitConfig
    history: list[IterationRecord] = field(default_factory=list)


def _corr_change(a: Correspondences, b: Correspondences) -> tuple[float, float]:
    """Fraction of found-flags that changed and mean target shift [px] of the rest."""
    flips = 0
    total = 0
    shifts: list[NDArray[np.float64]] = []
    for ta, fa, tb, fb in ((a.point_target, a.point_found, b.point_target, b.point_found),
                           (a.line_target, a.line_found, b.line_target, b.line_found)):
        if fa is None or fb is None or ta is None or tb is None:
            continue
        flips += int(np.sum(fa != fb))
        total += fa.size
        both = fa & fb
        shifts.append(np.linalg.norm(ta[both] - tb[both], axis=-1))
    allshift = np.concatenate(shifts) if shifts else np.zeros(0)
    shift = float(allshift.mean()) if allshift.size else 0.0
    if a.line_fractions is not None and b.line_fractions is not None:
        # visible-part sampling moved: count samples that moved by > 2 % of their line
        moved = np.abs(a.line_fractions - b.line_fractions) > 0.02
        flips += int(moved.sum())
        total += moved.size
    return flips / max(total, 1), shift


def fit(
    flight: Flight,
    config: FitConfig | None = None,
    *,
    keyframes: NDArray[np.int_] | None = None,
    initial_poses: SE3 | None = None,
    initial_turbine: TurbineParams | None = None,
    callback: Callable[[IterationRecord], None] | None = None,
) -> FitResult:
    """Refine the keyframe poses and/or the turbine of ``flight``.

    Args:
        flight: the flight (initial poses and turbine are the starting point).
        config: options (default :class:`FitConfig`: joint, points=corr, lines=interp).
        keyframes: subset of keyframe indices to use (default: all).
        initial_poses, initial_turbine: override the starting point.
        callback: called after every LM iteration (e.g. for a progress bar).
    """
    cfg = config or FitConfig()
    t0 = time.perf_counter()
    problem = FitProblem(flight, cfg, keyframes)
    kf = problem.keyframes
    poses = initial_poses if initial_poses is not None else flight.world_T_cam[kf]
    theta = (initial_turbine or flight.turbine).to_vector()
    needs_corr = "corr" in (cfg.points, cfg.lines) or (
        cfg.line_sampling == "visible" and cfg.lines != "none")
    corr = problem.find_correspondences(poses, theta) if needs_corr else Correspondences()
    lin = problem.linearize(poses, theta, corr)
    initial_cost, initial_terms = lin.cost, dict(lin.terms)
    history: list[IterationRecord] = []
    iterations = 0
    termination = "max_iterations"
    rounds = 0
    stiff = None
    if cfg.stiff_first_round > 1.0 and cfg.mode != "turbine" and problem.num_keyframes > 1:
        # Round 1 on a stiffened pose graph: the trajectory first moves almost as a whole
        # (with the turbine) onto the image evidence, before it may bend.
        stiff = FitProblem(flight, dataclasses.replace(
            cfg, lambda_pair=cfg.lambda_pair * cfg.stiff_first_round), keyframes)
    mu = cfg.initial_damping
    max_rounds = cfg.max_rounds if needs_corr else (2 if stiff is not None else 1)
    for rounds in range(1, max_rounds + 1):
        prob = stiff if (stiff is not None and rounds == 1) else problem
        if prob is stiff:
            lin = prob.linearize(poses, theta, corr)
        out = levenberg_marquardt(prob, poses, theta, corr, lin, round_index=rounds, mu=mu,
                                  max_iterations=cfg.max_iterations if rounds > 1 else
                                  cfg.first_round_iterations, history=history,
                                  callback=callback)
        poses, theta, lin = out.poses, out.theta, out.linearization
        mu = max(out.mu, cfg.initial_damping)
        iterations += out.iterations
        termination = out.termination
        if not needs_corr:
            if prob is stiff:
                lin = problem.linearize(poses, theta, corr)
                continue
            break
        new_corr = problem.find_correspondences(poses, theta)
        flips, shift = _corr_change(corr, new_corr)
        corr = new_corr
        lin = problem.linearize(poses, theta, corr)
        if prob is problem and flips < 0.005 and shift < 0.25:
            break
    turbine = TurbineParams.from_vector(theta).canonical()
    return FitResult(
        world_T_cam=poses, turbine=turbine, initial_cost=initial_cost, final_cost=lin.cost,
        initial_terms=initial_terms, final_terms=dict(lin.terms), iterations=iterations,
        rounds=rounds, termination=termination, time_s=time.perf_counter() - t0,
        num_residuals=lin.num_residuals, config=cfg, history=history,
    )
