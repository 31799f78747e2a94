"""Projection of the turbine model into every keyframe, with Jacobians w.r.t. the
keyframe's local pose update and the turbine parameters.

For a keyframe ``world_T_cam = (R, t)`` and a world point ``world_p(theta)``::

    cam_p = R^T (world_p - t),    uv = project(cam_p)

With the local update of :meth:`turbinefit.geometry.se3.SE3.retract`
(``t + dt``, ``R Exp(dphi)``) the derivatives are::

    d cam_p / d dt    = -R^T
    d cam_p / d dphi  = [cam_p]x
    d cam_p / d theta = R^T d world_p / d theta
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit import _native
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3

FloatArray = NDArray[np.float64]


@dataclass
class Projection:
    """Model points projected into N keyframes.

    Attributes:
        uv: (N, M, 2) pixels.
        front: (N, M) in front of the camera and inside the trusted distortion range.
        inside: (N, M) front and inside the image.
        J: (N, M, 2, 13) d uv / d (dt [m], dphi [rad], theta), or None.
    """

    uv: FloatArray
    front: NDArray[np.bool_]
    inside: NDArray[np.bool_]
    J: FloatArray | None


def project_points(
    camera: PinholeCamera,
    world_T_cam: SE3,
    world_p: FloatArray,
    J_theta: FloatArray | None,
    with_jacobian: bool = True,
    blend: tuple[FloatArray, FloatArray, FloatArray] | None = None,
) -> Projection:
    """Project world points (M, 3) (Jacobian (M, 3, 7)) into every keyframe of ``world_T_cam``;
    per-keyframe points (N, M, 3) (Jacobian (N, M, 3, 7)) are accepted too.

    ``blend = (Ja, Jb, f)`` gives per-keyframe Jacobians of points on segments,
    ``(1 - f) Ja + f Jb`` with shared Ja, Jb (M, 3, 7) and fractions f (N, M), without
    forming them (``J_theta`` is then ignored): much faster than (N, M, 3, 7) products."""
    if not with_jacobian and _native.available() and world_T_cam.wxyz_xyz.ndim == 2:
        uv, front, inside = _native.project(world_T_cam.wxyz_xyz, camera.kernel_params(),
                                            camera.width, camera.height, world_p)
        return Projection(uv=uv, front=front, inside=inside, J=None)
    R = world_T_cam.rotation_matrix()  # (N, 3, 3)
    t = world_T_cam.translation  # (N, 3)
    wp = world_p if world_p.ndim == 3 else world_p[None, :, :]
    cam_p = (wp - t[:, None, :]) @ R  # row-vector form of R^T (p - t)
    uv, front, Juv = camera.project_unbounded(cam_p, with_jacobian=with_jacobian)
    inside = front & camera.in_image(uv)
    J = None
    if with_jacobian and Juv is not None:
        N, M = uv.shape[:2]
        J = np.empty((N, M, 2, 13))
        # A = Juv R^T, as one (N, 2M, 3) x (N, 3, 3) product
        A = (Juv.reshape(N, 2 * M, 3) @ np.swapaxes(R, -1, -2)).reshape(N, M, 2, 3)
        J[..., 0:3] = -A
        J[..., 3:6] = np.cross(Juv, cam_p[:, :, None, :])
        if blend is not None:
            Ja, Jb, f = blend
            AJa = _times_shared(A, Ja)
            AJb = _times_shared(A, Jb)
            J[..., 6:13] = AJa + f[..., None, None] * (AJb - AJa)
        elif J_theta is not None and J_theta.ndim == 3:
            J[..., 6:13] = _times_shared(A, J_theta)
        elif J_theta is not None:
            J[..., 6:13] = A @ J_theta
        else:
            J[..., 6:13] = 0.0
    return Projection(uv=uv, front=front, inside=inside, J=J)


def _times_shared(A: FloatArray, Js: FloatArray) -> FloatArray:
    """``A[n, m] @ Js[m]`` for A (N, M, 2, 3), Js (M, 3, 7), as M large products."""
    N, M = A.shape[:2]
    out = np.swapaxes(A, 0, 1).reshape(M, 2 * N, 3) @ Js  # (M, 2N, 7)
    return np.swapaxes(out.reshape(M, N, 2, 7), 0, 1)
