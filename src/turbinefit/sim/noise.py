"""Errors of the initial estimates: GPS/IMU-like pose drift and a mis-measured turbine.

Poses are ``world_T_cam`` (camera-to-world; world metres, z up). Turbine parameters are
:class:`~turbinefit.turbine.model.TurbineParams` (metres and radians).

The paper (Sec. IV-A) "sequentially added noise to the position and orientations" of its
pseudo ground-truth pose graphs to mimic GPS/IMU drift, and Gaussian noise with a
different sigma per parameter to the turbine; it gives no values. Ours:

* :func:`drift_poses` - a random walk in the world frame starting at zero drift:
  ``t_k <- t_k + D_k``, ``R_k <- Exp(Phi_k) R_k`` with ``D_k = D_{k-1} + d_k``,
  ``Exp(Phi_k) = Exp(phi_k) Exp(Phi_{k-1})``, ``D_0 = 0``, ``Phi_0 = 0``, and i.i.d.
  Gaussian steps ``d_k``, ``phi_k`` (``k = 1 .. N-1``) whose per-axis sigma is
  ``total / sqrt(3 (N - 1))``, so that the RMS of the 3-D drift at the last keyframe is
  ``total`` for every N (position in metres, rotation angle in degrees).
* :func:`perturb_turbine` - independent Gaussian noise per parameter, default sigma
  :data:`DEFAULT_TURBINE_SIGMA`.
* :func:`body_odometry` - body-frame odometry (visual-inertial, wheel): each relative
  motion ``gt_k^-1 gt_{k+1}`` measured in the camera's frame with independent noise,
  translation ``+ n_t``, ``n_t ~ N(0, s_t^2 I3)``, ``s_t = sqrt(floor^2 + (f |step|)^2)``,
  rotation ``Exp(n_r) q``, ``n_r ~ N(0, s_r^2 I3)`` (defaults :data:`VIO_SIGMA_T_M`,
  :data:`VIO_SIGMA_T_PER_M`, :data:`VIO_SIGMA_R_DEG`), then chained from the first
  ground-truth pose: the odometry's own world frame drifts away (a rotation error of
  one step turns every later step). :class:`OdometrySensor` measures the same steps one
  at a time, as they are flown (a mission in the loop).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.geometry.se3 import SE3, quat_exp, quat_multiply
from turbinefit.turbine.model import TurbineParams

FloatArray = NDArray[np.float64]

#: Default sigma of :func:`perturb_turbine`: base x, base y, tower height [m], heading
#: [rad], nacelle length [m], blade rotation [rad], blade length [m]
#: = (1 m, 1 m, 2 m, 5 deg, 0.5 m, 5 deg, 2 m).
DEFAULT_TURBINE_SIGMA: tuple[float, ...] = (
    1.0, 1.0, 2.0, math.radians(5.0), 0.5, math.radians(5.0), 2.0,
)


#: Per-edge noise of :func:`body_odometry` (standard deviations per axis): a translation
#: floor [m], a fraction of the step's length [m/m] and a rotation [deg]. On the
#: simulator's 200-keyframe inspection (steps of 4-8 m, 1.3 km) they leave the chained
#: odometry 1.5 m and 0.8 deg off the truth on average over the flight (seeds 0-7), about
#: the GPS/IMU drift of the default scenario (1.4 m, 1.2 deg).
VIO_SIGMA_T_M = 0.02
VIO_SIGMA_T_PER_M = 0.01
VIO_SIGMA_R_DEG = 0.05


def drift_walk(n: int, rng: np.random.Generator, total: float) -> FloatArray:
    """Random walk (n, 3) starting at 0 whose last value has RMS norm ``total``."""
    out = np.zeros((n, 3))
    if n > 1 and total > 0:
        sigma = total / math.sqrt(3.0 * (n - 1))
        out[1:] = np.cumsum(rng.normal(0.0, sigma, (n - 1, 3)), axis=0)
    return out


def drift_poses(
    gt: SE3,
    rng: np.random.Generator,
    pos_sigma_total: float = 2.0,
    rot_sigma_total_deg: float = 2.0,
) -> SE3:
    """Poses ``gt`` (N,) with sequential GPS/IMU-like drift (see the module docstring).

    Args:
        gt: ground-truth ``world_T_cam`` (N,).
        rng: random source (position steps are drawn before rotation steps).
        pos_sigma_total: RMS of the 3-D position drift at the last keyframe [m].
        rot_sigma_total_deg: RMS of the rotation drift angle at the last keyframe [deg].

    Returns:
        Drifted ``world_T_cam`` (N,); keyframe 0 is unchanged.
    """
    if len(gt.batch_shape) != 1:
        raise ValueError(f"expected a batch (N,) of poses, got {gt.batch_shape}")
    if pos_sigma_total < 0 or rot_sigma_total_deg < 0:
        raise ValueError("drift magnitudes must be non-negative")
    n = gt.batch_shape[0]
    dpos = drift_walk(n, rng, pos_sigma_total)
    wxyz = gt.wxyz.copy()
    if n > 1 and rot_sigma_total_deg > 0:
        sigma = math.radians(rot_sigma_total_deg) / math.sqrt(3.0 * (n - 1))
        dq = quat_exp(rng.normal(0.0, sigma, (n - 1, 3)))
        # accumulate Exp(phi_k) on the left: Q_k = Exp(phi_k) Q_{k-1}, Q_0 = identity
        q = np.empty((n - 1, 4))
        acc = np.array([1.0, 0.0, 0.0, 0.0])
        for k in range(n - 1):
            acc = quat_multiply(dq[k], acc)
            acc /= np.linalg.norm(acc)
            q[k] = acc
        r = quat_multiply(q, gt.wxyz[1:])
        r /= np.linalg.norm(r, axis=-1, keepdims=True)
        wxyz[1:] = np.where(r[:, :1] < 0.0, -r, r)
    return SE3(np.concatenate([wxyz, gt.translation + dpos], axis=-1))


def body_odometry(
    gt: SE3,
    rng: np.random.Generator,
    scale: float = 1.0,
    sigma_t_m: float = VIO_SIGMA_T_M,
    sigma_t_per_m: float = VIO_SIGMA_T_PER_M,
    sigma_r_deg: float = VIO_SIGMA_R_DEG,
) -> SE3:
    """Body-frame odometry of the ground truth ``gt`` (N,), chained from ``gt[0]`` (see
    the module docstring); every sigma is multiplied by ``scale`` (0 = exact steps).

    Translation noise is drawn before rotation noise. Returns ``world_T_cam`` (N,) in the
    odometry's own (drifting) world frame; keyframe 0 is ``gt[0]``."""
    if len(gt.batch_shape) != 1:
        raise ValueError(f"expected a batch (N,) of poses, got {gt.batch_shape}")
    if not (math.isfinite(scale) and scale >= 0):
        raise ValueError(f"odometry noise scale must be a non-negative number, got {scale}")
    n = gt.batch_shape[0]
    if n < 2:
        return SE3(gt.wxyz_xyz.copy())
    rel = gt[:-1].inverse() @ gt[1:]
    step = np.linalg.norm(rel.translation, axis=-1)
    sig_t = scale * np.sqrt(sigma_t_m**2 + (sigma_t_per_m * step) ** 2)
    t = rel.translation + rng.normal(0.0, 1.0, (n - 1, 3)) * sig_t[:, None]
    q = quat_multiply(quat_exp(rng.normal(0.0, scale * math.radians(sigma_r_deg), (n - 1, 3))),
                      rel.wxyz)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    steps = SE3(np.concatenate([q, t], axis=-1))
    out = np.empty((n, 7))
    acc = gt[0]
    out[0] = acc.wxyz_xyz
    for k in range(n - 1):
        acc = acc @ steps[k]
        w = acc.wxyz / np.linalg.norm(acc.wxyz)
        acc = SE3(np.concatenate([w if w[0] >= 0 else -w, acc.translation]))
        out[k + 1] = acc.wxyz_xyz
    return SE3(out)


class OdometrySensor:
    """Body-frame odometry measured step by step (:func:`body_odometry`'s noise model): each
    :meth:`measure` of a true pose returns the odometry's pose, chained from the first
    true pose measured."""

    def __init__(self, rng: np.random.Generator, scale: float = 1.0) -> None:
        if not (math.isfinite(scale) and scale >= 0):
            raise ValueError(f"odometry noise scale must be a non-negative number, got {scale}")
        self.rng = rng
        self.scale = scale
        self._true: SE3 | None = None
        self._odo: SE3 | None = None

    def measure(self, true: SE3) -> SE3:
        """The odometry's pose at the true pose ``true`` (one pose)."""
        if self._true is None or self._odo is None:
            self._true, self._odo = true, SE3(true.wxyz_xyz.copy())
            return self._odo
        rel = self._true.inverse() @ true
        step = float(np.linalg.norm(rel.translation))
        sig_t = self.scale * math.hypot(VIO_SIGMA_T_M, VIO_SIGMA_T_PER_M * step)
        t = rel.translation + self.rng.normal(0.0, 1.0, 3) * sig_t
        q = quat_multiply(quat_exp(self.rng.normal(
            0.0, self.scale * math.radians(VIO_SIGMA_R_DEG), 3)), rel.wxyz)
        acc = self._odo @ SE3(np.concatenate([q / np.linalg.norm(q), t]))
        w = acc.wxyz / np.linalg.norm(acc.wxyz)
        self._true = true
        self._odo = SE3(np.concatenate([w if w[0] >= 0 else -w, acc.translation]))
        return self._odo


def perturb_turbine(
    theta: TurbineParams,
    sigma: ArrayLike = DEFAULT_TURBINE_SIGMA,
    rng: np.random.Generator | None = None,
) -> TurbineParams:
    """``theta`` plus independent Gaussian noise of standard deviation ``sigma`` (7,)
    [m and rad, in the order of :attr:`TurbineParams.NAMES`], returned canonical
    (heading in [0, 2 pi), blade rotation in [0, 2 pi / 3))."""
    if rng is None:
        raise ValueError("perturb_turbine needs an rng")
    s = np.asarray(sigma, dtype=np.float64).ravel()
    if s.size != 7 or np.any(s < 0) or not np.all(np.isfinite(s)):
        raise ValueError(f"sigma must be 7 non-negative numbers, got {sigma!r}")
    v = theta.to_vector() + rng.normal(0.0, 1.0, 7) * s
    return TurbineParams.from_vector(v).canonical()
