"""Correspondence rounds: the outer loop around Levenberg-Marquardt.

A round runs LM with the correspondences (and visible-part line samples) held fixed, then
searches again at the new estimate; the rounds end when a search changes almost nothing
(:data:`CONVERGED_FLIPS`, :data:`CONVERGED_SHIFT_PX`) or after the given number. The batch
fit (:mod:`turbinefit.solver.fit`, one call per stage) and the tracker
(:mod:`turbinefit.solver.tracker`, one call per window update and stage) share it; they
differ only in what is left in the returned linearisation (``finish``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.se3 import SE3
from turbinefit.solver.lm import IterationRecord, levenberg_marquardt
from turbinefit.solver.problem import Correspondences, FitProblem, Linearization

FloatArray = NDArray[np.float64]

#: A new search has converged when fewer than this fraction of the found-flags (and of the
#: visible-part line samples) changed ...
CONVERGED_FLIPS = 0.005
#: ... and the targets found by both searches moved by less than this on average [px at
#: 320: times the problem's ``pixel_scale`` in the maps' pixels].
CONVERGED_SHIFT_PX = 0.25

Finish = Literal["cost", "jacobian", "skip"]
"""What the rounds leave in the returned linearisation:

* ``cost``: search after the last round too, and measure the cost (no Jacobian) with the
  final correspondences (the batch fit's last stage: its final cost);
* ``jacobian``: no search after the last round; on convergence the normal equations with
  the final correspondences (the tracker: covariances and marginalisation follow);
* ``skip``: no search after the last round, nothing re-linearised on convergence (a
  warm-up stage: the next stage searches for its own correspondences).
"""


@dataclass
class RoundsOutcome:
    """What :func:`run_rounds` returns: the estimate, its linearisation (see
    :data:`Finish`), LM iterations over all rounds, why the last LM run stopped, the
    rounds run, and the correspondences the linearisation was made with."""

    poses: SE3
    theta: FloatArray
    linearization: Linearization
    iterations: int
    termination: str
    rounds: int
    correspondences: Correspondences


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


def initial_correspondences(problem: FitProblem, poses: SE3,
                            theta: FloatArray) -> Correspondences:
    """The problem's correspondences at ``(poses, theta)`` (none if it needs none)."""
    return (problem.find_correspondences(poses, theta) if problem.needs_correspondences
            else Correspondences())


def run_rounds(
    problem: FitProblem,
    poses: SE3,
    theta: FloatArray,
    rounds: int,
    iterations: int,
    *,
    corr: Correspondences | None = None,
    finish: Finish = "jacobian",
    first_round: int = 0,
    history: list[IterationRecord] | None = None,
    callback: Callable[[IterationRecord], None] | None = None,
    stage: str = "refine",
) -> RoundsOutcome:
    """Up to ``rounds`` rounds of at most ``iterations`` LM iterations from
    ``(poses, theta)``.

    ``corr``: the correspondences at the start (default: searched here). Rounds are
    numbered from ``first_round + 1`` in ``history``. The damping starts at the config's
    ``initial_damping`` and carries over from round to round (never below it)."""
    if corr is None:
        corr = initial_correspondences(problem, poses, theta)
    lin = problem.linearize(poses, theta, corr)
    mu0 = problem.config.initial_damping
    mu = mu0
    total = 0
    termination = "max_iterations"
    done_rounds = 0
    for r in range(rounds):
        done_rounds += 1
        out = levenberg_marquardt(problem, poses, theta, corr, lin,
                                  round_index=first_round + done_rounds, mu=mu,
                                  max_iterations=iterations, history=history,
                                  callback=callback, stage=stage)
        poses, theta, lin = out.poses, out.theta, out.linearization
        mu = max(out.mu, mu0)
        total += out.iterations
        termination = out.termination
        last = r == rounds - 1
        if not problem.needs_correspondences or (last and finish != "cost"):
            break
        new = problem.find_correspondences(poses, theta)
        flips, shift = corr_change(corr, new)
        corr = new
        done = last or (flips < CONVERGED_FLIPS
                        and shift < CONVERGED_SHIFT_PX * problem.config.scale)
        if done and finish == "skip":
            break
        lin = problem.linearize(poses, theta, corr,
                                with_jacobian=not (done and finish == "cost"))
        if done:
            break
    return RoundsOutcome(poses, theta, lin, total, termination, done_rounds, corr)
