"""Rotations and rigid transforms: the one pose type of the package.

Conventions (fixed for the whole package, see ``docs/method.md``):

* Quaternions are **wxyz** everywhere inside turbinefit (Hamilton convention, active
  rotation). TUM files store xyzw; the conversion happens only in :mod:`turbinefit.io`.
* A pose ``a_T_b`` maps points from frame *b* into frame *a*: ``a_p = a_T_b @ b_p``,
  and ``a_T_b @ b_T_c == a_T_c``. Keyframe poses are ``world_T_cam`` (camera-to-world).
* The optimiser's local update (:meth:`SE3.retract`) perturbs a pose on the right in
  rotation and additively in translation (the convention of Ceres' quaternion manifold
  combined with a Euclidean translation)::

      R <- R @ Exp(delta[3:6]),   t <- t + delta[0:3]

  so ``delta = (dt_x, dt_y, dt_z, dphi_x, dphi_y, dphi_z)`` in metres and radians, with the
  rotation part expressed in the camera (body) frame.

Written by hand (rather than using e.g. ``scipy.spatial.transform``) because the solver
needs batched wxyz storage, the exact retraction above and its inverse, and tight control
of allocation in vectorised hot paths; scipy's ``Rotation`` is used in tests as an
independent reference.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

_EPS = 1e-12


def skew(v: ArrayLike) -> FloatArray:
    """Cross-product matrices ``[v]x`` of shape (..., 3, 3) such that ``[v]x @ w == v x w``."""
    v = np.asarray(v, dtype=np.float64)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def quat_normalize(q: ArrayLike) -> FloatArray:
    """Unit quaternions (wxyz) with a non-negative scalar part."""
    a = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    if np.any(n < _EPS) or not np.all(np.isfinite(a)):
        raise ValueError("cannot normalise a zero or non-finite quaternion")
    a = a / n
    return np.where(a[..., :1] < 0.0, -a, a)


def quat_multiply(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Hamilton product ``a * b`` of wxyz quaternions, broadcasting over leading axes."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_conjugate(q: ArrayLike) -> FloatArray:
    """Conjugate (the inverse of a unit quaternion), wxyz."""
    q = np.asarray(q, dtype=np.float64)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_to_matrix(q: ArrayLike) -> FloatArray:
    """Rotation matrices (..., 3, 3) of unit wxyz quaternions (..., 4)."""
    q = np.asarray(q, dtype=np.float64)
    w, x, y, z = np.moveaxis(q, -1, 0)
    out = np.empty((*q.shape[:-1], 3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def matrix_to_quat(R: ArrayLike) -> FloatArray:
    """Unit wxyz quaternions (w >= 0) of rotation matrices (..., 3, 3) (Shepperd's method)."""
    R = np.asarray(R, dtype=np.float64)
    m = R.reshape(-1, 3, 3)
    q = np.empty((m.shape[0], 4))
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    diag = np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=-1)
    case = np.argmax(diag, axis=-1)
    for c in range(4):
        sel = case == c
        if not np.any(sel):
            continue
        s = m[sel]
        if c == 0:
            r = np.sqrt(1.0 + tr[sel]) * 2.0
            q[sel] = np.stack(
                [0.25 * r, (s[:, 2, 1] - s[:, 1, 2]) / r, (s[:, 0, 2] - s[:, 2, 0]) / r,
                 (s[:, 1, 0] - s[:, 0, 1]) / r], axis=-1)
        elif c == 1:
            r = np.sqrt(1.0 + s[:, 0, 0] - s[:, 1, 1] - s[:, 2, 2]) * 2.0
            q[sel] = np.stack(
                [(s[:, 2, 1] - s[:, 1, 2]) / r, 0.25 * r, (s[:, 0, 1] + s[:, 1, 0]) / r,
                 (s[:, 0, 2] + s[:, 2, 0]) / r], axis=-1)
        elif c == 2:
            r = np.sqrt(1.0 + s[:, 1, 1] - s[:, 0, 0] - s[:, 2, 2]) * 2.0
            q[sel] = np.stack(
                [(s[:, 0, 2] - s[:, 2, 0]) / r, (s[:, 0, 1] + s[:, 1, 0]) / r, 0.25 * r,
                 (s[:, 1, 2] + s[:, 2, 1]) / r], axis=-1)
        else:
            r = np.sqrt(1.0 + s[:, 2, 2] - s[:, 0, 0] - s[:, 1, 1]) * 2.0
            q[sel] = np.stack(
                [(s[:, 1, 0] - s[:, 0, 1]) / r, (s[:, 0, 2] + s[:, 2, 0]) / r,
                 (s[:, 1, 2] + s[:, 2, 1]) / r, 0.25 * r], axis=-1)
    q = quat_normalize(q)
    return q.reshape(*R.shape[:-2], 4)


def so3_exp(phi: ArrayLike) -> FloatArray:
    """Rotation matrices ``Exp(phi)`` (..., 3, 3) of rotation vectors ``phi`` (..., 3) [rad]."""
    phi = np.asarray(phi, dtype=np.float64)
    theta2 = np.sum(phi * phi, axis=-1)[..., None, None]
    theta = np.sqrt(theta2)
    small = theta2 < 1e-10
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    K = skew(phi)
    return np.eye(3) + a * K + b * (K @ K)


def so3_log(R: ArrayLike) -> FloatArray:
    """Rotation vectors (..., 3) [rad] of rotation matrices, via quaternions (stable near pi)."""
    q = matrix_to_quat(R)
    return quat_log(q)


def quat_log(q: ArrayLike) -> FloatArray:
    """Rotation vectors (..., 3) of unit wxyz quaternions; angle in [0, pi]."""
    q = np.asarray(q, dtype=np.float64)
    q = np.where(q[..., :1] < 0.0, -q, q)
    w = np.clip(q[..., 0], -1.0, 1.0)
    v = q[..., 1:]
    n = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(n, w)
    scale = np.where(n < 1e-12, 2.0 / np.maximum(w, 1e-300), angle / np.maximum(n, 1e-300))
    return v * scale[..., None]


def quat_exp(phi: ArrayLike) -> FloatArray:
    """Unit wxyz quaternions of rotation vectors ``phi`` (..., 3) [rad]."""
    phi = np.asarray(phi, dtype=np.float64)
    angle = np.linalg.norm(phi, axis=-1)
    half = 0.5 * angle
    small = angle < 1e-8
    s = np.where(small, 0.5 - angle * angle / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([np.cos(half)[..., None], phi * s[..., None]], axis=-1)


@dataclass(frozen=True)
class SE3:
    """A batch of rigid transforms ``a_T_b`` stored as ``wxyz_xyz`` of shape (..., 7).

    The quaternion is unit, wxyz, with w >= 0; the translation is in metres. ``T @ p``
    applies the transform to points (..., 3); ``T1 @ T2`` composes.
    """

    wxyz_xyz: FloatArray

    # ---- construction -------------------------------------------------------------
    @staticmethod
    def identity(batch: tuple[int, ...] = ()) -> SE3:
        out = np.zeros((*batch, 7))
        out[..., 0] = 1.0
        return SE3(out)

    @staticmethod
    def from_rotation_translation(R_or_wxyz: ArrayLike, t: ArrayLike) -> SE3:
        """From rotation matrices (..., 3, 3) or wxyz quaternions (..., 4) and translations."""
        r = np.asarray(R_or_wxyz, dtype=np.float64)
        t = np.asarray(t, dtype=np.float64)
        q = matrix_to_quat(r) if r.shape[-2:] == (3, 3) else quat_normalize(r)
        batch = np.broadcast_shapes(q.shape[:-1], t.shape[:-1])
        return SE3(np.concatenate(
            [np.broadcast_to(q, (*batch, 4)), np.broadcast_to(t, (*batch, 3))], axis=-1))

    @staticmethod
    def from_matrix(M: ArrayLike) -> SE3:
        """From homogeneous matrices (..., 4, 4)."""
        M = np.asarray(M, dtype=np.float64)
        return SE3.from_rotation_translation(M[..., :3, :3], M[..., :3, 3])

    # ---- accessors ------------------------------------------------------------------
    @property
    def batch_shape(self) -> tuple[int, ...]:
        return tuple(self.wxyz_xyz.shape[:-1])

    def __len__(self) -> int:
        return self.wxyz_xyz.shape[0]

    def __getitem__(self, idx: int | slice | NDArray[np.int_] | NDArray[np.bool_]) -> SE3:
        return SE3(self.wxyz_xyz[idx])

    @property
    def wxyz(self) -> FloatArray:
        return self.wxyz_xyz[..., :4]

    @property
    def translation(self) -> FloatArray:
        return self.wxyz_xyz[..., 4:]

    def rotation_matrix(self) -> FloatArray:
        return quat_to_matrix(self.wxyz)

    def as_matrix(self) -> FloatArray:
        out = np.zeros((*self.batch_shape, 4, 4))
        out[..., :3, :3] = self.rotation_matrix()
        out[..., :3, 3] = self.translation
        out[..., 3, 3] = 1.0
        return out

    # ---- group operations -----------------------------------------------------------
    def inverse(self) -> SE3:
        qi = quat_conjugate(self.wxyz)
        t = -np.einsum("...ij,...j->...i", quat_to_matrix(qi), self.translation)
        return SE3(np.concatenate([qi, t], axis=-1))

    def apply(self, p: ArrayLike) -> FloatArray:
        """Transform points ``b_p`` (..., 3) to ``a_p``; broadcasts batch against points."""
        p = np.asarray(p, dtype=np.float64)
        R = self.rotation_matrix()
        return np.einsum("...ij,...j->...i", R, p) + self.translation

    def compose(self, other: SE3) -> SE3:
        q = quat_multiply(self.wxyz, other.wxyz)
        t = self.apply(other.translation)
        q = np.where(q[..., :1] < 0.0, -q, q)
        return SE3(np.concatenate([q, t], axis=-1))

    @overload
    def __matmul__(self, other: SE3) -> SE3: ...
    @overload
    def __matmul__(self, other: NDArray[np.float64]) -> FloatArray: ...
    def __matmul__(self, other: SE3 | NDArray[np.float64]) -> SE3 | FloatArray:
        if isinstance(other, SE3):
            return self.compose(other)
        return self.apply(other)

    # ---- manifold ---------------------------------------------------------------
    def retract(self, delta: ArrayLike) -> SE3:
        """Local update ``t + delta[:3]``, ``R Exp(delta[3:])`` (see module docstring)."""
        delta = np.asarray(delta, dtype=np.float64)
        q = quat_multiply(self.wxyz, quat_exp(delta[..., 3:]))
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
        q = np.where(q[..., :1] < 0.0, -q, q)
        return SE3(np.concatenate([q, self.translation + delta[..., :3]], axis=-1))

    def local(self, other: SE3) -> FloatArray:
        """Inverse of :meth:`retract`: ``delta`` such that ``self.retract(delta) == other``."""
        dq = quat_multiply(quat_conjugate(self.wxyz), other.wxyz)
        return np.concatenate([other.translation - self.translation, quat_log(dq)], axis=-1)


def pose_errors(estimate: SE3, reference: SE3) -> tuple[FloatArray, FloatArray]:
    """Per-pose position error [m] and orientation error [rad] of ``estimate`` against
    ``reference`` (both ``world_T_cam`` batches of the same shape)."""
    dpos = np.linalg.norm(estimate.translation - reference.translation, axis=-1)
    dq = quat_multiply(quat_conjugate(reference.wxyz), estimate.wxyz)
    dang = np.linalg.norm(quat_log(dq), axis=-1)
    return dpos, dang


def world_T_cam_from_angles(position: ArrayLike, yaw: ArrayLike, pitch: ArrayLike,
                            roll: ArrayLike) -> SE3:
    """``world_T_cam`` of cameras at ``position`` (..., 3) [m] looking along azimuth ``yaw``
    and elevation ``pitch``, rolled by ``roll`` about the view (all [rad], broadcast over the
    leading dims).

    World frame: z up; ``yaw`` is the view direction's azimuth from the world x axis,
    counter-clockwise seen from above; ``pitch`` its elevation above the horizontal
    (positive looks up). Camera frame: OpenCV, z along the view; before the roll, x is
    horizontal (to the right of the view) and y = z x x points down (as far as the pitch
    lets it); ``roll`` then turns x towards y about z. Poses at the same angles are
    bit-identical whether passed one by one or batched.
    """
    yaw_, pitch_ = np.broadcast_arrays(np.asarray(yaw, dtype=np.float64),
                                       np.asarray(pitch, dtype=np.float64))
    roll_ = np.asarray(roll, dtype=np.float64)
    cp, sp = np.cos(pitch_), np.sin(pitch_)
    cy, sy = np.cos(yaw_), np.sin(yaw_)
    z = np.stack([cp * cy, cp * sy, sp], -1)
    x = np.stack([sy, -cy, np.zeros_like(sy)], -1)
    y = np.cross(z, x)
    cr, sr = np.cos(roll_)[..., None], np.sin(roll_)[..., None]
    x_r, y_r, z = np.broadcast_arrays(cr * x + sr * y, -sr * x + cr * y, z)
    R = np.stack([x_r, y_r, z], axis=-1)
    return SE3.from_rotation_translation(R, position)
