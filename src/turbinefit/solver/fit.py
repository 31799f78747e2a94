"""Fit a flight: stages of correspondence rounds around Levenberg-Marquardt.

1. *align* (warm-up): point and line correspondences (20 px search windows, a Huber loss,
   line residuals along the search normal so that the model may slide along its lines) on
   a pose graph stiffened ``warmup_stiffness`` times: the trajectory moves nearly rigidly,
   with the turbine, onto the heat-maps, which removes most of the smooth GPS/IMU drift
   and the turbine's error.
2. *match* (warm-up): the same correspondences on the normal pose graph: each keyframe
   comes within a few pixels of its heat-maps.
3. *refine*: the configured cost (by default the paper's best: point correspondences and
   heat-map interpolation for the lines) to convergence.

Each stage runs rounds: LM with fixed correspondences (and visible-part line samples),
then a new search; a stage ends when a search changes almost nothing. The heat-map term's
basin is a few pixels wide, so without the warm-up (``warmup=False``) initial errors of a
few degrees in heading or blade rotation leave it stranded (see the tests).
"""

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


def corr_change(a: Correspondences, b: Correspondences) -> tuple[float, float]:
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


@dataclass
class _Stage:
    name: str
    problem: FitProblem
    rounds: int
    iterations: int


def match_config(cfg: FitConfig) -> FitConfig:
    """The options of the *match* warm-up stage derived from ``cfg``: point and line
    correspondences (wide basins), a Huber loss, line residuals along the search normal."""
    return dataclasses.replace(
        cfg, points="corr" if cfg.points != "none" else "none",
        lines="corr" if cfg.lines != "none" else "none",
        pixel_sigma=cfg.warmup_pixel_sigma, robust="huber", robust_scale=2.0,
        line_residual="normal", function_tolerance=cfg.warmup_function_tolerance,
        stall_iterations=1)


def _stages(flight: Flight, cfg: FitConfig, problem: FitProblem,
            keyframes: NDArray[np.int_] | None) -> list[_Stage]:
    """The warm-up stages (see :class:`FitConfig`) and the configured cost."""
    out: list[_Stage] = []
    if cfg.warmup:
        corr_cfg = match_config(cfg)
        moves_poses = cfg.mode != "turbine" and problem.num_keyframes > 1
        if moves_poses and cfg.warmup_align_rounds > 0 and cfg.lambda_pair > 0:
            align = dataclasses.replace(corr_cfg, lambda_pair=cfg.lambda_pair * cfg.warmup_stiffness)
            out.append(_Stage("align", FitProblem(flight, align, keyframes),
                              cfg.warmup_align_rounds, cfg.warmup_iterations))
        if cfg.warmup_match_rounds > 0:
            out.append(_Stage("match", FitProblem(flight, corr_cfg, keyframes),
                              cfg.warmup_match_rounds, cfg.warmup_iterations))
    out.append(_Stage("refine", problem, cfg.max_rounds if problem.needs_correspondences else 1,
                      cfg.max_iterations))
    return out


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
    stages = _stages(flight, cfg, problem, keyframes)
    history: list[IterationRecord] = []
    iterations = 0
    termination = "max_iterations"
    rounds = 0
    # the configured cost at the start, for the summary (its correspondences are reused if
    # the configured cost is also the first stage)
    corr0 = (problem.find_correspondences(poses, theta) if problem.needs_correspondences
             else Correspondences())
    start = problem.linearize(poses, theta, corr0, with_jacobian=False)
    lin = start
    for stage in stages:
        prob = stage.problem
        if prob is problem and stage is stages[0]:
            corr = corr0
        else:
            corr = (prob.find_correspondences(poses, theta) if prob.needs_correspondences
                    else Correspondences())
        lin = prob.linearize(poses, theta, corr)
        mu = cfg.initial_damping
        final_stage = stage is stages[-1]
        for r in range(stage.rounds):
            rounds += 1
            out = levenberg_marquardt(prob, poses, theta, corr, lin, round_index=rounds,
                                      mu=mu, max_iterations=stage.iterations,
                                      history=history, callback=callback, stage=stage.name)
            poses, theta, lin = out.poses, out.theta, out.linearization
            mu = max(out.mu, cfg.initial_damping)
            iterations += out.iterations
            termination = out.termination
            last = r == stage.rounds - 1
            if not prob.needs_correspondences or (last and not final_stage):
                break  # (the next stage searches for its own correspondences)
            new_corr = prob.find_correspondences(poses, theta)
            flips, shift = corr_change(corr, new_corr)
            corr = new_corr
            done = last or (flips < 0.005 and shift < 0.25)
            if done and not final_stage:
                break
            # the final cost is measured with the correspondences of the final estimate
            lin = prob.linearize(poses, theta, corr, with_jacobian=not done)
            if done:
                break
    turbine = TurbineParams.from_vector(theta).canonical()
    return FitResult(
        world_T_cam=poses, turbine=turbine, initial_cost=start.cost, final_cost=lin.cost,
        initial_terms=dict(start.terms), final_terms=dict(lin.terms), iterations=iterations,
        rounds=rounds, termination=termination, time_s=time.perf_counter() - t0,
        num_residuals=lin.num_residuals, config=cfg, history=history,
    )
