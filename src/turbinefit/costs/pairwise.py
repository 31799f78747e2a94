"""The paper's pairwise (relative-pose) term between keyframes i and j.

With poses ``world_T_cam`` = (R, t) (camera-to-world, quaternion q)::

    t_ij = F_i^T (t_j - t_i),   q_ij = q_i^-1 * q_j
    e    = [ t^_ij - t_ij ;  2 Vec(q^_ij * q_ij^-1) ]       (hat = GPS/IMU measurement)
    r    = sqrt(lambda) * L e,   C = L^T L

``F_i`` is the frame the relative translation is expressed in. The paper's is the
estimate's own attitude, ``F_i = R_i`` (``frame="estimated"``): right for body-frame
odometry (visual-inertial, wheel), whose step errors do not depend on the attitude error.
For GPS/IMU poses it is wrong: GPS measures positions in the world, and the measured
step ``t^_ij = R^_i^T (t^_j - t^_i)`` was rotated into the frame by the IMU's *drifting*
attitude ``R^_i``, so comparing it in the corrected attitude ``R_i`` charges every step
its attitude error times its length, correlated along the whole flight. With
``frame="measured"``, ``F_i = R^_i``: the world-frame steps are compared, the attitude is
left to the rotation part and the images. The cost still uses the same information
matrix C (per body axis of the measured keyframe); only the translation part changes.

``C`` is the information matrix (1/m^2 on translation, 1/rad^2 on rotation); the default
is diagonal, ``diag(1/sigma_t^2 I3, 1/sigma_r^2 I3)``, with sigma_t growing with the
length of the measured step (see ``FitConfig.pair_sigma_t_per_m``). The quaternion ``q^_ij * q_ij^-1`` is
taken with a non-negative scalar part. Jacobians are w.r.t. the local update of
:meth:`turbinefit.geometry.se3.SE3.retract` of each pose.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.se3 import SE3, quat_conjugate, quat_multiply, skew

FloatArray = NDArray[np.float64]


def relative_poses(world_T_i: SE3, world_T_j: SE3) -> SE3:
    """``i_T_j = world_T_i^-1 world_T_j``."""
    return world_T_i.inverse() @ world_T_j


def pairwise_residuals(
    world_T_i: SE3, world_T_j: SE3, measured_i_T_j: SE3, sqrt_info: FloatArray,
    with_jacobian: bool = True, world_R_frame: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
    """Residuals (E, 6) and Jacobians (E, 6, 6) w.r.t. the local updates of pose i and j.

    ``sqrt_info`` is L (6, 6), shared, or one per edge (E, 6, 6). ``world_R_frame``
    (E, 3, 3) is the fixed frame ``F_i`` of the translation part (the measured attitudes,
    see the module docstring); None uses the estimate's ``R_i`` (the paper's)."""
    Ri = world_T_i.rotation_matrix()
    Rf = Ri if world_R_frame is None else world_R_frame
    t_ij = np.einsum("eji,ej->ei", Rf, world_T_j.translation - world_T_i.translation)
    q_ij = quat_multiply(quat_conjugate(world_T_i.wxyz), world_T_j.wxyz)
    e_q = quat_multiply(measured_i_T_j.wxyz, quat_conjugate(q_ij))
    e_q = np.where(e_q[..., :1] < 0.0, -e_q, e_q)
    e = np.concatenate([measured_i_T_j.translation - t_ij, 2.0 * e_q[..., 1:]], axis=-1)
    if sqrt_info.ndim == 2:
        sqrt_info = np.broadcast_to(sqrt_info, (e.shape[0], 6, 6))
    r = np.einsum("eij,ej->ei", sqrt_info, e)
    if not with_jacobian:
        return r, None, None
    E = e.shape[0]
    Ji = np.zeros((E, 6, 6))
    Jj = np.zeros((E, 6, 6))
    RiT = np.swapaxes(Ri, -1, -2)
    RfT = np.swapaxes(Rf, -1, -2)
    Ji[:, :3, :3] = RfT
    if world_R_frame is None:
        Ji[:, :3, 3:] = -skew(t_ij)
    Jj[:, :3, :3] = -RfT
    M = e_q[:, 0, None, None] * np.eye(3) + skew(e_q[:, 1:])
    Ji[:, 3:, 3:] = M
    R_ij = RiT @ world_T_j.rotation_matrix()
    Jj[:, 3:, 3:] = -M @ R_ij
    return r, sqrt_info @ Ji, sqrt_info @ Jj
