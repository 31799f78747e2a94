"""GNSS error models of inspection drones: what a drone's photo metadata says of its pose.

A drone records with every photo the position of its GNSS receiver (with or without RTK
corrections) and the camera's attitude from its IMU, compass and gimbal. Their errors are
not independent from photo to photo: atmospheric delays, multipath and the RTK solution
drift slowly, and a compass mis-calibrated by a few degrees turns every photo's yaw the
same way. Each model (:class:`GnssModel`) is therefore

* a **position error** per world axis (east, north, up), a first-order Gauss-Markov
  process (an exponentially correlated random process): ``e_k = phi e_{k-1} + sqrt(1 -
  phi^2) sigma w_k``, ``phi = exp(-(t_k - t_{k-1}) / tau)``, ``w_k ~ N(0, 1)``, started
  from its stationary distribution ``e_0 ~ N(0, sigma^2)``: its standard deviation is
  ``sigma`` at every keyframe, and two keyframes ``dt`` apart correlate by ``exp(-dt /
  tau)`` (the same process whatever the keyframes' spacing);
* an **attitude error**: a yaw bias drawn once per flight (the compass / gimbal yaw
  offset, ``N(0, yaw_bias_sigma^2)``) plus a Gauss-Markov wander of each world-frame
  rotation axis; the recorded rotation is ``Exp(delta) R_true`` with ``delta = (e_x, e_y,
  bias + e_z)``.

The magnitudes are those the manufacturers publish for DJI's inspection drones (Matrice
300 RTK, Matrice 350 RTK, Mavic 3 Enterprise; sources in ``docs/mission.md``):

* ``standard`` (GNSS alone): hovering accuracy ``+-1.5 m`` horizontal and ``+-0.5 m``
  vertical (with GNSS; the vertical one held by the barometer), taken as one standard
  deviation per axis; correlation time 300 s (atmospheric and multipath errors of a
  single-frequency receiver change over minutes);
* ``rtk`` (RTK fixed): positioning accuracy ``1 cm + 1 ppm`` horizontal and ``1.5 cm +
  1 ppm`` vertical (RMS), at a baseline of :data:`RTK_BASELINE_KM` to the base station:
  1.5 cm and 2.0 cm; correlation time 60 s;
* both: a yaw bias of standard deviation 2 deg (a compass's heading accuracy; "a few
  degrees" at two sigma) and a wander of 0.3 deg per axis, correlated over 30 s.

:meth:`GnssModel.position_sigma` gives the per-keyframe standard deviations a receiver
reports with each fix (DJI writes them as ``RtkStdLon``, ``RtkStdLat``, ``RtkStdHgt``):
the prior a pose graph may give each keyframe's position.

:class:`GnssReceiver` draws the errors fix by fix (a mission in flight);
:func:`gnss_poses` draws a whole flight (the same numbers for the same generator).
Written here: the Gauss-Markov recursion is two lines, and no GNSS simulator on PyPI
models a drone's recorded poses (they simulate signals or receivers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.geometry.se3 import SE3, quat_exp, quat_multiply

FloatArray = NDArray[np.float64]

#: Baseline [km] from the RTK base station assumed by the ``rtk`` model (its "+ 1 ppm").
RTK_BASELINE_KM = 5.0


@dataclass(frozen=True)
class GnssModel:
    """The errors of a drone's recorded poses (module docstring).

    Attributes:
        name: ``standard`` or ``rtk``.
        horizontal_m, vertical_m: standard deviation of the position error per horizontal
            axis and vertically [m].
        correlation_s: correlation time of the position error [s].
        yaw_bias_deg: standard deviation of the per-flight yaw bias [deg].
        attitude_deg: standard deviation of the attitude wander per axis [deg].
        attitude_correlation_s: its correlation time [s].
    """

    name: str
    horizontal_m: float
    vertical_m: float
    correlation_s: float
    yaw_bias_deg: float = 2.0
    attitude_deg: float = 0.3
    attitude_correlation_s: float = 30.0

    def __post_init__(self) -> None:
        for key in ("horizontal_m", "vertical_m", "yaw_bias_deg", "attitude_deg"):
            v = getattr(self, key)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{key} must be a non-negative number, got {v!r}")
        for key in ("correlation_s", "attitude_correlation_s"):
            v = getattr(self, key)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{key} must be a positive number, got {v!r}")

    def position_sigma(self) -> FloatArray:
        """(3,) standard deviations [m] of the position error along east, north, up."""
        return np.array([self.horizontal_m, self.horizontal_m, self.vertical_m])


#: The models of ``simulate --gnss`` (module docstring).
GNSS_MODELS: dict[str, GnssModel] = {
    "standard": GnssModel("standard", 1.5, 0.5, 300.0),
    "rtk": GnssModel("rtk", 0.010 + 1e-6 * RTK_BASELINE_KM * 1e3,
                     0.015 + 1e-6 * RTK_BASELINE_KM * 1e3, 60.0),
}


def gnss_model(name: str) -> GnssModel:
    """The model :data:`GNSS_MODELS` names ``name``."""
    if name not in GNSS_MODELS:
        raise ValueError(f"unknown GNSS model {name!r}; choose from {', '.join(GNSS_MODELS)}")
    return GNSS_MODELS[name]


@dataclass(frozen=True)
class GnssFix:
    """One recorded pose (:meth:`GnssReceiver.measure`).

    Attributes:
        world_T_cam: the recorded camera pose (position and attitude with their errors).
        position_sigma_m: (3,) standard deviations of its position (east, north, up) [m].
        position_error_m: (3,) its position error (recorded - true) [m].
        rotation_error: (3,) its attitude error, a world-frame rotation vector [rad]
            (recorded = ``Exp(rotation_error)`` true).
    """

    world_T_cam: SE3
    position_sigma_m: FloatArray
    position_error_m: FloatArray
    rotation_error: FloatArray


class GnssReceiver:
    """Draws a flight's pose errors fix by fix (:data:`GNSS_MODELS`; module docstring).

    The yaw bias is drawn when the receiver is made; each :meth:`measure` advances the
    Gauss-Markov processes to its time (which must increase).
    """

    def __init__(self, model: GnssModel, rng: np.random.Generator) -> None:
        self.model = model
        self.rng = rng
        self.yaw_bias = math.radians(model.yaw_bias_deg) * float(rng.standard_normal())
        self._t: float | None = None
        self._pos = np.zeros(3)
        self._rot = np.zeros(3)

    @staticmethod
    def _step(state: FloatArray, sigma: FloatArray, phi: float, w: FloatArray) -> FloatArray:
        return phi * state + math.sqrt(max(1.0 - phi * phi, 0.0)) * sigma * w

    def measure(self, t: float, world_T_cam: SE3) -> GnssFix:
        """The pose recorded at time ``t`` [s] for the true pose ``world_T_cam``."""
        m = self.model
        sig_p = m.position_sigma()
        sig_r = np.full(3, math.radians(m.attitude_deg))
        w = self.rng.standard_normal(6)
        if self._t is None:
            self._pos, self._rot = sig_p * w[:3], sig_r * w[3:]
        else:
            dt = float(t) - self._t
            if not dt > 0.0:
                raise ValueError(f"fix times must increase: {t} after {self._t}")
            self._pos = self._step(self._pos, sig_p, math.exp(-dt / m.correlation_s), w[:3])
            self._rot = self._step(self._rot, sig_r, math.exp(-dt / m.attitude_correlation_s),
                                   w[3:])
        self._t = float(t)
        rot = self._rot + np.array([0.0, 0.0, self.yaw_bias])
        q = quat_multiply(quat_exp(rot), world_T_cam.wxyz)
        q = q / np.linalg.norm(q)
        q = -q if q[0] < 0 else q
        pose = SE3(np.concatenate([q, world_T_cam.translation + self._pos]))
        return GnssFix(pose, sig_p.copy(), self._pos.copy(), rot)


@dataclass(frozen=True)
class GnssPoses:
    """A flight's recorded poses (:func:`gnss_poses`).

    Attributes:
        world_T_cam: (N,) recorded poses.
        position_sigma_m: (N, 3) standard deviations of each position (east, north, up)
            [m], as the receiver reports them with each fix.
        position_error_m: (N, 3) position errors (recorded - true) [m].
        rotation_error: (N, 3) attitude errors, world-frame rotation vectors [rad].
        yaw_bias: the flight's yaw bias [rad].
    """

    world_T_cam: SE3
    position_sigma_m: FloatArray
    position_error_m: FloatArray
    rotation_error: FloatArray
    yaw_bias: float


def gnss_poses(gt: SE3, timestamps: ArrayLike, model: GnssModel,
               rng: np.random.Generator) -> GnssPoses:
    """The poses a drone records along the true poses ``gt`` (N,) at ``timestamps`` (N,)
    [s, increasing], with the errors of ``model`` (a :class:`GnssReceiver` fix by fix)."""
    if len(gt.batch_shape) != 1:
        raise ValueError(f"expected a batch (N,) of poses, got {gt.batch_shape}")
    ts = np.asarray(timestamps, dtype=np.float64).ravel()
    n = gt.batch_shape[0]
    if ts.size != n:
        raise ValueError(f"{ts.size} timestamps for {n} poses")
    rx = GnssReceiver(model, rng)
    fixes = [rx.measure(float(ts[k]), gt[k]) for k in range(n)]
    return GnssPoses(SE3(np.stack([f.world_T_cam.wxyz_xyz for f in fixes])),
                     np.stack([f.position_sigma_m for f in fixes]),
                     np.stack([f.position_error_m for f in fixes]),
                     np.stack([f.rotation_error for f in fixes]), rx.yaw_bias)
