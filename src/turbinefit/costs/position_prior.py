"""Absolute position priors: each keyframe's camera position held near a measured one with
per-axis standard deviations (an RTK receiver's, ``keyframes_sigma.csv``).

With pose ``world_T_cam`` = (R, t), measured position ``t^`` and standard deviations
``sigma`` (3,) along the world axes::

    r = (t - t^) / sigma            (3 residuals per keyframe)

so that ``1/2 |r|^2`` is the negative log-likelihood of a Gaussian position measurement with
covariance ``diag(sigma^2)``. The Jacobian w.r.t. the local update of
:meth:`turbinefit.geometry.se3.SE3.retract` (``t + delta[:3]``, ``R Exp(delta[3:])``) is
``[diag(1 / sigma) | 0]``: the translation update is in the world frame and the rotation
does not move the camera's position. The measured position is taken as the camera's (DJI
records the camera's position on its RTK drones; a lever arm between antenna and camera
is not modelled).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.se3 import SE3

FloatArray = NDArray[np.float64]


def position_prior_residuals(world_T_cam: SE3, measured: FloatArray, sigma: FloatArray,
                             with_jacobian: bool = True
                             ) -> tuple[FloatArray, FloatArray | None]:
    """Whitened residuals (N, 3) of the position priors of poses ``world_T_cam`` (N,) about
    ``measured`` (N, 3) [m] with standard deviations ``sigma`` (N, 3) [m, > 0], and their
    Jacobians (N, 3, 6) w.r.t. each pose's local update (None without ``with_jacobian``)."""
    inv = 1.0 / np.asarray(sigma, dtype=np.float64)
    r = (world_T_cam.translation - np.asarray(measured, dtype=np.float64)) * inv
    if not with_jacobian:
        return r, None
    J = np.zeros((*r.shape, 6))
    idx = np.arange(3)
    J[:, idx, idx] = inv
    return r, J
