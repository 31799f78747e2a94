"""The verdict on a fit or a track: ``ok``, ``doubtful`` or ``failed``, with its reasons.

A fit always returns numbers; whether to trust them is decided here, from signals measured
on the result (pure computation: no files, no printing):

* **evidence**: the share of keyframes whose heat-maps hold evidence, i.e. at least one
  correspondence is found around the projected model (a peak of at least
  ``corr_threshold``), and no channel is above ``corr_threshold`` over more than
  :data:`MAX_EVIDENCE_AREA` of the image (a map that is high everywhere - all ones, a
  constant 0.3 - says nothing about where anything is);
* **inliers**: of the model points and line samples projected into keyframes with
  evidence, the share with a correspondence (point search in a ``corr_radius`` disc, line
  search along the normal) within :data:`INLIER_WIDTH_SHARE` of the heat-maps' width;
* **reprojection**: the median distance [px] from projection to correspondence, as a
  share of the heat-maps' width (the same error means more on a coarse map);
* **poses**: how far the poses moved from their initial (GPS/IMU) values, against the
  random walk the pairwise sigmas allow (the largest ``|t_k - t_k^0| / sqrt(sum of the
  edges' 3-D translation variances up to k)``), and the pairwise term's chi-square per
  degree of freedom at the end;
* **bounds**: theta's lengths inside the plausible range of real turbines
  (:data:`~turbinefit.turbine.model.THETA_LOWER` / ``THETA_UPPER``, which the solver keeps
  it in: ending on a bound means the data pushed it out), blade tips above the ground;
* **conditioning**: theta's standard deviations from its covariance, the inverse of the
  final normal equations' Schur complement on theta (:func:`theta_covariance`), taken
  over the information of the flight alone: the tracker's start-up prior on theta is a
  regulariser, not evidence, and is left out (a direction of theta no image fixes must
  show, not be capped at the prior's sigma). A Schur complement that is not positive
  definite leaves some direction of theta unfixed: an infinite standard deviation, so
  ``failed``;
* **convergence**: how far theta is from the optimum of the data's cost, in its standard
  deviations: the length ``sqrt(dt^T S dt)`` of the undamped Gauss-Newton step ``dt``
  left at the estimate, ``S`` theta's information (:func:`theta_uncertainty`). A
  covariance describes the error of an estimate at that optimum only: the batch fit ends
  there, the tracker's last update may not (five iterations per keyframe), nor an
  estimate its start-up prior still holds away from what the images say;
* **finite**: no NaN or infinity anywhere, and the solver took at least one step.

Each threshold below was set from the signals of simulated flights
(``python benchmarks/bench_verdict.py``, see docs/method.md#the-verdict): the ``ok`` side
is passed by every flight of the studies' default sweeps whose final position error is
under 0.5 m, the ``failed`` side by evidence-free heat-maps and broken inputs.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.pairwise import pairwise_residuals, relative_poses
from turbinefit.costs.projection import project_points
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps.stack import GRID_ROWS
from turbinefit.solver.config import FitConfig
from turbinefit.solver.linalg import arrow_theta, inverse_spd
from turbinefit.solver.problem import (
    Correspondences,
    FitProblem,
    Linearization,
    ProblemData,
    pair_sqrt_information,
)
from turbinefit.turbine.model import THETA_LOWER, THETA_UPPER, TurbineParams

FloatArray = NDArray[np.float64]
Verdict = Literal["ok", "doubtful", "failed"]

# Thresholds: (doubtful beyond, failed beyond). Measured on the default simulated flights
# of every study plus a sweep beyond the fit's basin (python benchmarks/bench_verdict.py
# --flights 6 --keyframes 60, 126 fits): flights under 0.5 m of final position error
# reached at most pose shift 1.1 sigma, pairwise chi-square 0.42, reprojection 0.08 % of
# the width, inlier share down to 0.89; those over 2 m at least 2.1 sigma and 0.88 (the
# image signals overlap: a fit can match its heat-maps well and still sit metres off).
# The doubtful limits sit about twice beyond the good flights' worst; the failed limits
# where no fit of the studies came.

#: A channel above ``corr_threshold`` over more than this share of the image holds no
#: evidence (a line channel of a close view covers a few per cent).
MAX_EVIDENCE_AREA = 0.25
#: A correspondence within this share of the heat-maps' width of its projection is an
#: inlier (6.4 px on 320 px maps).
INLIER_WIDTH_SHARE = 0.02
#: Rows of the grid on which :data:`MAX_EVIDENCE_AREA` is estimated (x about 40 columns):
#: the heat-maps' coarse grid (:meth:`~turbinefit.heatmaps.HeatmapStack.coarse_grid`).
AREA_GRID_ROWS = GRID_ROWS
#: Heat-maps narrower than this [px] cannot place a turbine.
MIN_HEATMAP_WIDTH = 32
#: (doubtful below, failed below) the share of keyframes with evidence (good fits: 1.0).
EVIDENCE_SHARE = (0.5, 0.2)
#: (doubtful below, failed below) the inlier share of the image terms (good fits: >= 0.89,
#: from photos 0.97).
INLIER_SHARE = (0.6, 0.3)
#: (doubtful above, failed above) the median reprojection error / heat-map width (good
#: fits: <= 0.0008 on simulated maps, 0.0012 from photos).
REPROJECTION_SHARE = (0.005, 0.02)
#: (doubtful above, failed above) the largest pose move in random-walk sigmas (good fits:
#: <= 1.1; bad: >= 2.1).
POSE_SHIFT_SIGMAS = (2.0, 10.0)
#: (doubtful above, failed above) the pairwise chi-square per degree of freedom (good
#: fits: <= 0.42; bad: >= 0.88).
PAIRWISE_CHI2 = (0.8, 25.0)
#: (doubtful above, failed above) the standard deviation of a length of theta [m] (good
#: fits: <= 1.3, the base; bad fits are not less certain: conditioning only catches an
#: estimate the data do not constrain).
LENGTH_STD_M = (3.0, 10.0)
#: (doubtful above, failed above) the standard deviation of an angle of theta [deg]
#: (good fits: <= 0.3).
ANGLE_STD_DEG = (3.0, 10.0)
#: (doubtful above, failed above) theta's distance from the optimum of the data's cost,
#: in its standard deviations (good fits: <= 0.8, good tracks <= 0.5; one-keyframe tracks
#: from a turbine 5x further off than the simulator's default: 4.6-7.4 on three of eight
#: flights, with errors of 5.2-8.5 sigma; python benchmarks/bench_verdict.py --track).
THETA_STEP_SIGMAS = (3.0, 10.0)
#: A length this close to a bound [m] is on it.
BOUND_TOLERANCE_M = 1e-6


@dataclass(frozen=True)
class ImageEvidence:
    """Per-keyframe agreement of the model with the heat-maps.

    Attributes:
        evidence: (N,) whether the keyframe's heat-maps hold evidence.
        in_view: (N,) model points and line samples projected into the image.
        found: (N,) of those, how many found a correspondence.
        inliers: (N,) of those, how many within :data:`INLIER_WIDTH_SHARE` of the width.
        distances_px: distances projection -> correspondence of every correspondence
            found in a keyframe with evidence [px].
        width_px: the heat-maps' width [px].
    """

    evidence: NDArray[np.bool_]
    in_view: NDArray[np.int64]
    found: NDArray[np.int64]
    inliers: NDArray[np.int64]
    distances_px: FloatArray
    width_px: int

    @staticmethod
    def concat(parts: list[ImageEvidence]) -> ImageEvidence:
        """The evidence of several keyframe sets (e.g. a tracker's, one per keyframe)."""
        return ImageEvidence(
            np.concatenate([p.evidence for p in parts]),
            np.concatenate([p.in_view for p in parts]),
            np.concatenate([p.found for p in parts]),
            np.concatenate([p.inliers for p in parts]),
            np.concatenate([p.distances_px for p in parts]),
            parts[0].width_px if parts else 0)


def _area_share(data: ProblemData, keyframes: NDArray[np.int_], threshold: float) -> FloatArray:
    """(N,) per keyframe the largest share of the image any channel is >= threshold over,
    estimated on the heat-maps' coarse grid of :data:`AREA_GRID_ROWS` rows by about 40
    columns (a share, not a peak: the grid may step over a peak but not over an area; the
    value check of heat-map files keeps it, so no map is read again here)."""
    out = np.empty(len(keyframes))
    for start in range(0, len(keyframes), 128):  # a few MB at a time
        grid = data.heatmaps.coarse_grid(keyframes[start:start + 128])
        out[start:start + grid.shape[0]] = np.max(np.mean(grid >= threshold, axis=(2, 3)),
                                                  axis=1)
    return out


def image_evidence(data: ProblemData, world_T_cam: SE3, theta: FloatArray, config: FitConfig,
                   keyframes: NDArray[np.int_] | None = None,
                   corr: Correspondences | None = None) -> ImageEvidence:
    """Search correspondences of every model point and line sample at the estimate
    ``(world_T_cam, theta)`` of ``keyframes`` (default: all) and count them. ``corr``:
    the correspondences a fit with point and line correspondences and visible-part
    sampling (``config``) already found there (the search is then skipped)."""
    reuse = (corr is not None and config.points == "corr" and config.lines == "corr"
             and config.line_sampling == "visible")
    cfg = dataclasses.replace(config, points="corr", lines="corr", line_sampling="visible")
    prob = FitProblem(data, cfg, keyframes)
    kf = prob.keyframes
    if not reuse or corr is None:
        corr = prob.find_correspondences(world_T_cam, theta)
    pts, lns = prob.model(theta, False, corr.line_fractions)
    cam = data.camera
    width = cam.width
    in_view = np.zeros(kf.size, dtype=np.int64)
    found = np.zeros(kf.size, dtype=np.int64)
    inliers = np.zeros(kf.size, dtype=np.int64)
    dists: list[FloatArray] = []
    for world_p, target, ok in ((pts.A, corr.point_target, corr.point_found),
                                (lns.points(), corr.line_target, corr.line_found)):
        assert target is not None and ok is not None
        pr = project_points(cam, world_T_cam, world_p, None, with_jacobian=False)
        d = np.linalg.norm(target - pr.uv, axis=-1)
        ok = ok & pr.inside
        in_view += pr.inside.sum(axis=1)
        found += ok.sum(axis=1)
        inliers += (ok & (d <= INLIER_WIDTH_SHARE * width)).sum(axis=1)
        dists.append(np.where(ok, d, np.nan))
    evidence = (found > 0) & (_area_share(data, kf, config.corr_threshold) <= MAX_EVIDENCE_AREA)
    all_d = np.concatenate(dists, axis=1)[evidence]
    return ImageEvidence(evidence, in_view, found, inliers, all_d[np.isfinite(all_d)],
                         width)


def theta_uncertainty(lin: Linearization) -> tuple[FloatArray | None, float | None]:
    """theta's (7, 7) covariance from undamped normal equations ``lin`` (with Jacobian),
    the inverse of the Schur complement ``S`` of the poses, and the length in standard
    deviations of the Gauss-Newton step ``dt = -S^-1 r`` left at the estimate,
    ``sqrt(dt^T S dt) = sqrt(r^T S^-1 r)`` (``r``: the gradient with the poses
    eliminated); (None, None) if ``S`` is not positive definite (a direction of theta
    without information) or not finite, or the turbine is fixed.

    The one rule for the batch fit and the tracker: ``lin`` holds the information of the
    data (image terms, pairwise edges, the gauge, and for the tracker the prior its
    marginalised keyframes left), never a regulariser such as the tracker's start-up
    prior on theta."""
    if (lin.D is None or lin.B is None or lin.C is None or lin.E is None or lin.g_p is None
            or lin.g_t is None):
        return None, None
    try:
        S, r = arrow_theta(lin.D, lin.B, lin.C, lin.E, lin.g_p, lin.g_t)
        cov = inverse_spd(S)
    except np.linalg.LinAlgError:
        return None, None
    step = float(r @ cov @ r)
    return cov, math.sqrt(max(step, 0.0)) if math.isfinite(step) else None


def theta_covariance(lin: Linearization) -> FloatArray | None:
    """theta's covariance of :func:`theta_uncertainty`."""
    return theta_uncertainty(lin)[0]


def pose_signals(measurements: SE3, initial: SE3, final: SE3, config: FitConfig
                 ) -> tuple[float, float | None, float | None]:
    """How far the poses moved: the largest move [m], the largest move in random-walk
    sigmas of the pairwise term (None for one keyframe) and the pairwise chi-square per
    degree of freedom at ``final`` (None for one keyframe). ``measurements``: the poses
    whose steps are the pairwise measurements; ``config`` with ``pair_frame`` resolved."""
    move = np.linalg.norm(final.translation - initial.translation, axis=-1)
    n = move.size
    if n < 2:
        return float(move.max(initial=0.0)), None, None
    rel = relative_poses(measurements[:-1], measurements[1:])
    L = pair_sqrt_information(config, rel)  # includes sqrt(lambda_pair)
    info = np.swapaxes(L, 1, 2) @ L
    var = np.trace(np.linalg.inv(info)[:, :3, :3], axis1=1, axis2=2)  # 3-D variance / edge
    walk = np.concatenate([[0.0], np.cumsum(var)])
    if config.gauge == "gps":
        walk = walk + 3.0 * config.gps_sigma**2
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(walk > 0, move / np.sqrt(np.maximum(walk, 1e-300)),
                         np.where(move > 1e-9, np.inf, 0.0))
    frames = (measurements[:-1].rotation_matrix() if config.pair_frame == "measured"
              else None)
    r, _, _ = pairwise_residuals(final[:-1], final[1:], rel, L, False, frames)
    chi2 = float(np.sum(r * r)) / (6.0 * (n - 1))
    return float(move.max()), float(ratio.max()), chi2


@dataclass(frozen=True)
class Signals:
    """What the verdict is decided from (see the module docstring); None: undefined
    (e.g. no correspondence found, one keyframe, turbine fixed)."""

    keyframes: int
    heatmap_width_px: int
    evidence_share: float
    inlier_share: float | None
    reprojection_px: float | None
    pose_shift_m: float
    pose_shift_sigmas: float | None
    pairwise_chi2: float | None
    theta: TurbineParams | None
    theta_std: FloatArray | None
    iterations: int
    finite: bool
    theta_step_sigmas: float | None = None

    @property
    def reprojection_share(self) -> float | None:
        """The median reprojection error as a share of the heat-maps' width."""
        if self.reprojection_px is None or self.heatmap_width_px <= 0:
            return None
        return self.reprojection_px / self.heatmap_width_px

    def theta_std_dict(self) -> dict[str, float | None] | None:
        """theta's standard deviations by name (metres, radians); None if unknown."""
        if self.theta_std is None:
            return None
        return {n: _finite_or_none(v) for n, v in zip(TurbineParams.NAMES, self.theta_std,
                                                       strict=True)}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: non-finite values are None."""
        return {
            "keyframes": self.keyframes,
            "heatmap_width_px": self.heatmap_width_px,
            "evidence_share": _finite_or_none(self.evidence_share),
            "inlier_share": _finite_or_none(self.inlier_share),
            "reprojection_px": _finite_or_none(self.reprojection_px),
            "reprojection_share_of_width": _finite_or_none(self.reprojection_share),
            "pose_shift_m": _finite_or_none(self.pose_shift_m),
            "pose_shift_sigmas": _finite_or_none(self.pose_shift_sigmas),
            "pairwise_chi2": _finite_or_none(self.pairwise_chi2),
            "theta_std": self.theta_std_dict(),
            "theta_step_sigmas": _finite_or_none(self.theta_step_sigmas),
            "iterations": self.iterations,
            "finite": self.finite,
        }


def _finite_or_none(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def measure(image: ImageEvidence, initial: SE3, final: SE3, measurements: SE3,
            theta: FloatArray | None, theta_cov: FloatArray | None, config: FitConfig,
            iterations: int, extra_values: tuple[float, ...] = (),
            theta_step_sigmas: float | None = None) -> Signals:
    """The signals of an estimate (``final`` poses and ``theta``, None with the turbine
    fixed) whose image agreement is ``image``; ``extra_values``: other numbers of the
    result that must be finite (costs); ``theta_cov`` and ``theta_step_sigmas`` from
    :func:`theta_uncertainty`."""
    finite = bool(np.all(np.isfinite(final.wxyz_xyz))) and all(
        math.isfinite(v) for v in extra_values)
    if theta is not None:
        finite = finite and bool(np.all(np.isfinite(theta)))
    if theta_cov is not None:
        finite = finite and bool(np.all(np.isfinite(theta_cov)))
    n = int(image.evidence.size)
    with_ev = image.evidence
    in_view = int(image.in_view[with_ev].sum())
    inlier = float(image.inliers[with_ev].sum()) / in_view if in_view else None
    reproj = float(np.median(image.distances_px)) if image.distances_px.size else None
    if finite:
        shift_m, shift_sig, chi2 = pose_signals(measurements, initial, final, config)
    else:
        shift_m, shift_sig, chi2 = math.inf, None, None
    std = None
    if theta_cov is not None:
        std = np.sqrt(np.maximum(np.diag(theta_cov), 0.0))
    turbine = None
    if theta is not None and finite:
        turbine = TurbineParams.from_vector(theta)
    return Signals(n, image.width_px, float(with_ev.mean()) if n else 0.0, inlier, reproj,
                   shift_m, shift_sig, chi2, turbine, std, iterations, finite,
                   theta_step_sigmas if std is not None else None)


def _grade(value: float | None, limits: tuple[float, float], above: bool) -> int:
    """0 ok, 1 doubtful, 2 failed (None: ok: nothing measured)."""
    if value is None:
        return 0
    doubt, fail = limits
    if above:
        return 2 if value > fail else 1 if value > doubt else 0
    return 2 if value < fail else 1 if value < doubt else 0


def judge(s: Signals) -> tuple[Verdict, list[str]]:
    """The verdict on signals ``s`` and its reasons (empty for ``ok``)."""
    fails: list[str] = []
    doubts: list[str] = []

    def add(grade: int, why: str) -> None:
        if grade == 2:
            fails.append(why)
        elif grade == 1:
            doubts.append(why)

    if not s.finite:
        fails.append("non-finite numbers in the result")
    if s.iterations == 0:
        fails.append("the solver took no step")
    if s.heatmap_width_px < MIN_HEATMAP_WIDTH:
        fails.append(f"heat-maps {s.heatmap_width_px} px wide (below {MIN_HEATMAP_WIDTH})")
    add(_grade(s.evidence_share, EVIDENCE_SHARE, above=False),
        f"{100 * s.evidence_share:.0f} % of keyframes have heat-map evidence")
    if s.evidence_share > 0:
        add(_grade(s.inlier_share, INLIER_SHARE, above=False),
            f"{100 * (s.inlier_share or 0.0):.0f} % of the image terms are inliers")
        rs = s.reprojection_share
        add(_grade(rs, REPROJECTION_SHARE, above=True),
            f"median reprojection error {s.reprojection_px or 0.0:.2f} px "
            f"({100 * (rs or 0.0):.1f} % of the heat-maps' width)")
    add(_grade(s.pose_shift_sigmas, POSE_SHIFT_SIGMAS, above=True),
        f"poses moved up to {s.pose_shift_m:.2f} m ({s.pose_shift_sigmas or 0.0:.1f} sigma "
        "of the pairwise term)")
    add(_grade(s.pairwise_chi2, PAIRWISE_CHI2, above=True),
        f"pairwise chi-square {s.pairwise_chi2 or 0.0:.1f} per degree of freedom")
    if s.theta is not None:
        v = s.theta.to_vector()
        for i, name in enumerate(TurbineParams.NAMES):
            lo, hi = THETA_LOWER[i], THETA_UPPER[i]
            if v[i] <= lo + BOUND_TOLERANCE_M or v[i] >= hi - BOUND_TOLERANCE_M:
                fails.append(f"{name} {v[i]:.6g} m on or beyond its bound [{lo:g}, {hi:g}] m")
        if s.theta.tower_height - s.theta.blade_length <= 0:
            fails.append(f"blade ({s.theta.blade_length:.2f} m) longer than the tower "
                         f"({s.theta.tower_height:.2f} m): its tips hit the ground")
    if s.theta_std is not None:
        for i, name in enumerate(TurbineParams.NAMES):
            angular = TurbineParams.ANGULAR[i]
            sd = math.degrees(s.theta_std[i]) if angular else float(s.theta_std[i])
            unit = "deg" if angular else "m"
            add(_grade(sd, ANGLE_STD_DEG if angular else LENGTH_STD_M, above=True),
                f"{name} standard deviation {sd:.2f} {unit}")
        add(_grade(s.theta_step_sigmas, THETA_STEP_SIGMAS, above=True),
            f"theta {s.theta_step_sigmas or 0.0:.1f} sigma from the optimum of the data's cost "
            "(not converged, or held off it by a prior)")
    elif s.theta is not None and s.finite:
        fails.append("theta's covariance is singular: the data leave a direction of theta "
                     "unfixed")
    if fails:
        return "failed", fails + doubts
    if doubts:
        return "doubtful", doubts
    return "ok", []
