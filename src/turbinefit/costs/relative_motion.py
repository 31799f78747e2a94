"""The tie-point term: the relative motion between consecutive photos, as measured from
the photos themselves (an essential matrix of matched features), against the estimate.

Two calibrated photos determine the relative rotation ``q^_ij`` of the second camera in
the first's frame and the *direction* ``d^`` (unit, in camera i's frame) of the second
camera's centre seen from the first, not the length of the step (the scale comes from
the pairwise term's GPS/IMU or odometry step). With poses ``world_T_cam`` = (R, t)
(quaternion q)::

    t_ij = R_i^T (t_j - t_i),   u = t_ij / |t_ij|,   q_ij = q_i^-1 * q_j
    e    = [ 2 Vec(q^_ij * q_ij^-1) ;  B^T u ]        (5 values)
    r    = sqrt(lambda) * L e,   C = L^T L            (C: 5x5 information)

``B`` (3, 2) is an orthonormal basis of the plane perpendicular to ``d^``, so the last two
values are the sines of the direction error along two axes. The information ``C`` comes
with each measurement (:class:`RelativeMotions`), from the epipolar errors of its
inliers (``turbinefit.tiepoints``): a far scene leaves the direction uncertain and the
rotation certain, and ``C`` says so. Each edge's squared whitened norm ``s = |r|^2``
goes through a Cauchy loss (``1/2 rho(s)``, scaled by ``sqrt(rho'(s))``, Ceres' corrector
with alpha = 0, as the image terms), so that a wrong essential matrix that passed the
checks pulls little. Jacobians are w.r.t. the local update of
:meth:`turbinefit.geometry.se3.SE3.retract` (``t + delta[:3]``, ``R Exp(delta[3:])``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.robust import RobustLoss
from turbinefit.geometry.se3 import SE3, quat_conjugate, quat_multiply, skew

FloatArray = NDArray[np.float64]

#: Number of residuals of one relative-motion edge (rotation 3, direction 2).
MOTION_DIM = 5


def perpendicular_basis(d: FloatArray) -> FloatArray:
    """(E, 3, 2) orthonormal bases of the planes perpendicular to the unit vectors d (E, 3)."""
    a = np.where(np.abs(d[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]),
                 np.array([[0.0, 1.0, 0.0]]))
    b1 = np.cross(d, a)
    b1 /= np.linalg.norm(b1, axis=-1, keepdims=True)
    b2 = np.cross(d, b1)
    return np.stack([b1, b2], axis=-1)


@dataclass(frozen=True)
class RelativeMotions:
    """Measured relative motions between consecutive keyframes, one per keyframe: entry
    ``k`` is the motion from keyframe ``k - 1`` to ``k`` (entry 0 and every entry whose
    ``valid`` is False carry no measurement).

    Attributes:
        i_q_j: (N, 4) rotation of camera k in camera k-1's frame (wxyz).
        i_dir_j: (N, 3) unit direction of camera k's centre in camera k-1's frame.
        sqrt_info: (N, 5, 5) square-root information ``L`` (``C = L^T L``) of
            (rotation [rad], direction [sine of the angle along ``B``'s two axes]).
        valid: (N,) whether entry k holds a measurement.
        inliers: (N,) tie points that agreed with it (0 where none).
    """

    i_q_j: FloatArray
    i_dir_j: FloatArray
    sqrt_info: FloatArray
    valid: NDArray[np.bool_]
    inliers: NDArray[np.int64]

    def __post_init__(self) -> None:
        n = self.valid.shape[0]
        shapes = {"i_q_j": (n, 4), "i_dir_j": (n, 3), "sqrt_info": (n, 5, 5),
                  "inliers": (n,)}
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"{name} has shape {getattr(self, name).shape}, expected {shape}")
        v = self.valid
        for name in ("i_q_j", "i_dir_j", "sqrt_info"):
            if not np.all(np.isfinite(getattr(self, name)[v])):
                raise ValueError(f"{name} must be finite where valid")

    @staticmethod
    def none(n: int) -> RelativeMotions:
        """``n`` entries, none valid."""
        q = np.zeros((n, 4))
        q[:, 0] = 1.0
        d = np.zeros((n, 3))
        d[:, 2] = 1.0
        return RelativeMotions(q, d, np.zeros((n, 5, 5)), np.zeros(n, dtype=bool),
                               np.zeros(n, dtype=np.int64))

    def __len__(self) -> int:
        return int(self.valid.shape[0])

    def take(self, keyframes: NDArray[np.int_]) -> RelativeMotions:
        """The entries of ``keyframes`` (time order): an entry stays valid only where its
        predecessor in ``keyframes`` is the keyframe right before it (the measurement is
        of consecutive photos), and the first is never valid."""
        idx = np.asarray(keyframes, dtype=np.int64)
        valid = self.valid[idx].copy()
        if idx.size:
            valid[0] = False
            valid[1:] &= np.diff(idx) == 1
        return RelativeMotions(self.i_q_j[idx].copy(), self.i_dir_j[idx].copy(),
                               self.sqrt_info[idx].copy(), valid, self.inliers[idx].copy())

    def append(self, other: RelativeMotions) -> RelativeMotions:
        """These entries followed by ``other``'s."""
        return RelativeMotions(np.concatenate([self.i_q_j, other.i_q_j]),
                               np.concatenate([self.i_dir_j, other.i_dir_j]),
                               np.concatenate([self.sqrt_info, other.sqrt_info]),
                               np.concatenate([self.valid, other.valid]),
                               np.concatenate([self.inliers, other.inliers]))


def relative_motion_residuals(
    world_T_i: SE3, world_T_j: SE3, i_q_j: FloatArray, i_dir_j: FloatArray,
    sqrt_info: FloatArray, loss: RobustLoss, with_jacobian: bool = True,
) -> tuple[FloatArray, FloatArray, FloatArray | None, FloatArray | None]:
    """Robustified residuals of E edges (module docstring).

    Returns ``(r, rho, Ji, Jj)``: residuals (E, 5) and Jacobians (E, 5, 6) w.r.t. the
    local updates of pose i and j, both scaled by ``sqrt(rho'(s))``, and ``rho(s)`` (E,)
    (the cost is ``1/2 sum rho``). Edges whose step has no length get zero residuals."""
    Ri = world_T_i.rotation_matrix()
    RiT = np.swapaxes(Ri, -1, -2)
    t_ij = np.einsum("eji,ej->ei", Ri, world_T_j.translation - world_T_i.translation)
    length = np.linalg.norm(t_ij, axis=-1, keepdims=True)
    moved = length[:, 0] > 1e-9
    u = t_ij / np.maximum(length, 1e-9)
    d = i_dir_j / np.maximum(np.linalg.norm(i_dir_j, axis=-1, keepdims=True), 1e-12)
    B = perpendicular_basis(d)
    q_ij = quat_multiply(quat_conjugate(world_T_i.wxyz), world_T_j.wxyz)
    e_q = quat_multiply(i_q_j, quat_conjugate(q_ij))
    e_q = np.where(e_q[..., :1] < 0.0, -e_q, e_q)
    e = np.concatenate([2.0 * e_q[..., 1:], np.einsum("eka,ek->ea", B, u)], axis=-1)
    e[~moved] = 0.0
    r = np.einsum("eij,ej->ei", sqrt_info, e)
    rho, drho = loss.evaluate(np.sum(r * r, axis=-1))
    w = np.sqrt(drho)
    r = r * w[:, None]
    if not with_jacobian:
        return r, rho, None, None
    n = e.shape[0]
    Ji = np.zeros((n, MOTION_DIM, 6))
    Jj = np.zeros((n, MOTION_DIM, 6))
    M = e_q[:, 0, None, None] * np.eye(3) + skew(e_q[:, 1:])
    Ji[:, :3, 3:] = M
    Jj[:, :3, 3:] = -M @ (RiT @ world_T_j.rotation_matrix())
    # du/dt_ij = (I - u u^T) / |t_ij|; dt_ij/d(t_i, r_i, t_j) = (-R_i^T, [t_ij]x, R_i^T)
    P = (np.eye(3) - u[:, :, None] * u[:, None, :]) / np.maximum(length[:, :, None], 1e-9)
    BtP = np.swapaxes(B, 1, 2) @ P
    Ji[:, 3:, :3] = -BtP @ RiT
    Ji[:, 3:, 3:] = BtP @ skew(t_ij)
    Jj[:, 3:, :3] = BtP @ RiT
    Ji[~moved] = 0.0
    Jj[~moved] = 0.0
    scale = w[:, None, None] * sqrt_info
    return r, rho, scale @ Ji, scale @ Jj
