"""Fit a flight: stages of correspondence rounds around Levenberg-Marquardt.

1. *align* (warm-up): point and line correspondences (search windows of 20 px at 320 px
   wide maps, a Huber loss, line residuals along the search normal so that the model may
   slide along its lines) on a pose graph stiffened ``warmup_stiffness`` times: the
   trajectory moves nearly rigidly, with the turbine, onto the heat-maps, which removes
   most of the smooth GPS/IMU drift and the turbine's error.
2. *match* (warm-up): the same correspondences on the normal pose graph: each keyframe
   comes within a few pixels of its heat-maps.
3. *refine*: the configured cost (by default the paper's best: point correspondences and
   heat-map interpolation for the lines) to convergence.

Each stage runs rounds (:func:`turbinefit.solver.rounds.run_rounds`): LM with fixed
correspondences (and visible-part line samples), then a new search; a stage ends when a
search changes almost nothing. The heat-map term's
basin is a few pixels wide, so without the warm-up (``warmup=False``) initial errors of a
few degrees in heading or blade rotation leave it stranded (see the tests).

At the end, theta's covariance (and how far theta is from the optimum, in its standard
deviations) is taken from the normal equations at the estimate (with the final
correspondences), and the result is judged (:mod:`turbinefit.solver.verdict`):
``ok``, ``doubtful`` or ``failed``, with reasons and the signals they come from.
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
from turbinefit.solver.config import FitConfig, resolve_pair_frame, resolve_pixel_scale
from turbinefit.solver.lm import IterationRecord
from turbinefit.solver.problem import Correspondences, FitProblem
from turbinefit.solver.rounds import initial_correspondences, run_rounds
from turbinefit.solver.verdict import (
    ImageEvidence,
    Signals,
    Verdict,
    image_evidence,
    judge,
    measure,
    theta_uncertainty,
)
from turbinefit.turbine.model import TurbineParams

FloatArray = NDArray[np.float64]


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
        config: the configuration used (``pair_frame`` resolved: never ``auto``;
            ``pixel_scale`` resolved from the heat-maps' width).
        theta_covariance: (7, 7) covariance of theta (metres, radians) from the final
            normal equations; None with the turbine fixed or singular information.
        signals, verdict, reasons: how far to trust the result
            (:mod:`turbinefit.solver.verdict`).
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
    theta_covariance: FloatArray | None = None
    signals: Signals | None = None
    verdict: Verdict = "ok"
    reasons: list[str] = field(default_factory=list)

    @property
    def theta_std(self) -> FloatArray | None:
        """(7,) theta's standard deviations (metres, radians), or None."""
        return None if self.signals is None else self.signals.theta_std


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
        config: options (default :class:`FitConfig`: joint, points=corr, lines=interp);
            ``pair_frame="auto"`` becomes estimated if ``flight.odometry`` is given,
            measured otherwise, an unset ``pixel_scale`` the heat-maps' width / 320 (at
            least 1), and the result's ``config`` records which.
        keyframes: subset of keyframe indices to use (default: all).
        initial_poses, initial_turbine: override the starting point.
        callback: called after every LM iteration (e.g. for a progress bar).
    """
    # auto resolved once, here: every stage and the result use the frame of the flight and
    # the pixel scale of its heat-maps
    cfg = resolve_pixel_scale(
        resolve_pair_frame(config or FitConfig(), flight.odometry is not None),
        flight.camera.width)
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
    corr0 = initial_correspondences(problem, poses, theta)
    start = problem.linearize(poses, theta, corr0, with_jacobian=False)
    lin = start
    corr = corr0
    for stage in stages:
        final_stage = stage is stages[-1]
        out = run_rounds(stage.problem, poses, theta, stage.rounds, stage.iterations,
                         corr=corr0 if stage.problem is problem and stage is stages[0] else None,
                         finish="cost" if final_stage else "skip", first_round=rounds,
                         history=history, callback=callback, stage=stage.name)
        poses, theta, lin = out.poses, out.theta, out.linearization
        iterations += out.iterations
        termination = out.termination
        rounds += out.rounds
        corr = out.correspondences
    initial = initial_poses if initial_poses is not None else flight.world_T_cam[kf]
    cov, signals = _assess(problem, initial, poses, theta, corr, iterations,
                           (start.cost, lin.cost))
    verdict, reasons = judge(signals)
    finite = bool(np.all(np.isfinite(theta)))
    turbine = (TurbineParams.from_vector(theta).canonical() if finite
               else TurbineParams.from_vector(np.nan_to_num(theta)))
    return FitResult(
        world_T_cam=poses, turbine=turbine, initial_cost=start.cost, final_cost=lin.cost,
        initial_terms=dict(start.terms), final_terms=dict(lin.terms), iterations=iterations,
        rounds=rounds, termination=termination, time_s=time.perf_counter() - t0,
        num_residuals=lin.num_residuals, config=cfg, history=history,
        theta_covariance=cov, signals=signals, verdict=verdict, reasons=reasons,
    )


def _assess(problem: FitProblem, initial: SE3, poses: SE3, theta: FloatArray,
            corr: Correspondences, iterations: int, costs: tuple[float, ...]
            ) -> tuple[FloatArray | None, Signals]:
    """theta's covariance and the signals of the estimate ``(poses, theta)``."""
    kf = problem.keyframes
    finite = bool(np.all(np.isfinite(theta)) and np.all(np.isfinite(poses.wxyz_xyz)))
    cov = step = None
    if finite and problem.optimise_theta:
        cov, step = theta_uncertainty(problem.linearize(poses, theta, corr))
    if finite:
        image = image_evidence(problem.data, poses, theta, problem.config, kf, corr)
    else:
        none = np.zeros(kf.size, dtype=np.int64)
        image = ImageEvidence(np.zeros(kf.size, dtype=bool), none, none, none, np.zeros(0),
                              problem.data.camera.width)
    return cov, measure(image, initial, poses, problem.data.measurement_poses()[kf],
                        theta if problem.optimise_theta else None, cov, problem.config,
                        iterations, costs, step)
