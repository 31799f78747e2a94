"""Accuracy of an estimate against ground truth (no alignment: the gauge is fixed by the
first keyframe, so estimates live in the ground truth's world frame)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from turbinefit.geometry.se3 import SE3, pose_errors, quat_conjugate, quat_log, quat_multiply
from turbinefit.turbine.model import (
    PAPER_GEOMETRY,
    TurbineGeometry,
    TurbineParams,
    model_point_error,
    param_errors,
)


@dataclass(frozen=True)
class Accuracy:
    """Errors of poses and turbine against ground truth.

    Attributes:
        position_error_m: mean keyframe position error [m].
        orientation_error_deg: mean keyframe orientation error [deg].
        max_position_error_m, max_orientation_error_deg: worst keyframe.
        model_point_error_m: mean 3-D distance of the six model points [m] (tips matched
            modulo the blade symmetry).
        param_errors: signed error of each turbine parameter (metres; angles in degrees,
            wrapped modulo their periods).
    """

    position_error_m: float
    orientation_error_deg: float
    max_position_error_m: float
    max_orientation_error_deg: float
    model_point_error_m: float
    param_errors: dict[str, float]

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def accuracy(
    world_T_cam: SE3, turbine: TurbineParams, gt_world_T_cam: SE3, gt_turbine: TurbineParams,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> Accuracy:
    """Errors of (poses, turbine) against ground truth."""
    dpos, dang = pose_errors(world_T_cam, gt_world_T_cam)
    dang_deg = np.degrees(dang)
    perr = param_errors(turbine, gt_turbine)
    pdict = {
        name: float(math.degrees(v) if ang else v)
        for name, v, ang in zip(TurbineParams.NAMES, perr, TurbineParams.ANGULAR, strict=True)
    }
    return Accuracy(
        position_error_m=float(dpos.mean()), orientation_error_deg=float(dang_deg.mean()),
        max_position_error_m=float(dpos.max()), max_orientation_error_deg=float(dang_deg.max()),
        model_point_error_m=model_point_error(turbine, gt_turbine, geometry),
        param_errors=pdict,
    )


def roll_errors_deg(estimate: SE3, reference: SE3) -> np.ndarray:
    """Per-keyframe rotation error about the camera's optical axis (z) [deg], signed: the
    z component of ``Log(R_ref^T R_est)``."""
    dq = quat_multiply(quat_conjugate(reference.wxyz), estimate.wxyz)
    return np.degrees(quat_log(dq)[..., 2])


def line_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares line ``y = a x + b`` through finite pairs; ``(nan, nan)`` with fewer
    than two or with no spread in ``x`` (relative 1e-9)."""
    x = np.asarray(x, dtype=np.float64).ravel()
    y = np.asarray(y, dtype=np.float64).ravel()
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 2:
        return math.nan, math.nan
    dx = x - x.mean()
    var = float(dx @ dx)
    if var <= (1e-9 * max(1.0, float(np.abs(x).max()))) ** 2 * x.size:
        return math.nan, math.nan
    a = float(dx @ (y - y.mean())) / var
    return a, float(y.mean() - a * x.mean())
