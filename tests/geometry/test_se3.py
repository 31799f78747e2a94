"""Poses and rotations (turbinefit.geometry.se3): group axioms, quaternions against scipy,
log/exp edge cases, retract/local."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from turbinefit.geometry.se3 import (
    SE3,
    matrix_to_quat,
    pose_errors,
    quat_exp,
    quat_log,
    quat_to_matrix,
    so3_exp,
)


def random_poses(rng, n):
    q = rng.normal(size=(n, 4))
    t = rng.normal(scale=10, size=(n, 3))
    return SE3.from_rotation_translation(q, t)


@pytest.mark.parametrize("batch", [(), (5,), (2, 3)])
def test_group_axioms(batch):
    rng = np.random.default_rng(1)
    n = int(np.prod(batch)) if batch else 1
    a = random_poses(rng, n)
    b = random_poses(rng, n)
    c = random_poses(rng, n)
    if batch:
        a, b, c = (SE3(x.wxyz_xyz.reshape(*batch, 7)) for x in (a, b, c))
    else:
        a, b, c = a[0], b[0], c[0]
    ident = (a @ a.inverse()).as_matrix()
    np.testing.assert_allclose(ident, np.broadcast_to(np.eye(4), ident.shape), atol=1e-12)
    np.testing.assert_allclose(((a @ b) @ c).as_matrix(), (a @ (b @ c)).as_matrix(), atol=1e-9)
    np.testing.assert_allclose((a @ b).as_matrix(), a.as_matrix() @ b.as_matrix(), atol=1e-9)
    p = rng.normal(size=(*batch, 3))
    np.testing.assert_allclose(a @ (b @ p), (a @ b) @ p, atol=1e-9)
    assert np.all((a @ b).wxyz[..., 0] >= 0)


def test_quaternion_matches_scipy():
    rng = np.random.default_rng(2)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    R_ref = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()  # scipy is xyzw
    np.testing.assert_allclose(quat_to_matrix(q), R_ref, atol=1e-12)
    q2 = matrix_to_quat(R_ref)
    np.testing.assert_allclose(np.abs(np.sum(q2 * q, axis=-1)), 1.0, atol=1e-12)
    phi = rng.normal(size=(50, 3))
    np.testing.assert_allclose(so3_exp(phi), Rotation.from_rotvec(phi).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(quat_exp(phi)), so3_exp(phi), atol=1e-12)


def test_log_near_pi_and_zero():
    for angle in (0.0, 1e-9, 1e-4, np.pi - 1e-7, np.pi):
        phi = angle * np.array([0.6, 0.0, 0.8])
        back = quat_log(quat_exp(phi))
        if angle > np.pi - 1e-6:
            # at pi the axis sign is ambiguous
            np.testing.assert_allclose(np.abs(back), np.abs(phi), atol=1e-6)
        else:
            np.testing.assert_allclose(back, phi, atol=1e-12)


def test_retract_local_round_trip():
    rng = np.random.default_rng(3)
    a = random_poses(rng, 20)
    d = rng.normal(scale=0.3, size=(20, 6))
    b = a.retract(d)
    np.testing.assert_allclose(a.local(b), d, atol=1e-10)
    # rotation part is applied on the right: R_b = R_a Exp(dphi)
    np.testing.assert_allclose(b.rotation_matrix(), a.rotation_matrix() @ so3_exp(d[:, 3:]),
                               atol=1e-12)
    dpos, dang = pose_errors(b, a)
    np.testing.assert_allclose(dpos, np.linalg.norm(d[:, :3], axis=-1), atol=1e-12)
    np.testing.assert_allclose(dang, np.linalg.norm(d[:, 3:], axis=-1), atol=1e-9)


def test_zero_quaternion_rejected():
    with pytest.raises(ValueError):
        SE3.from_rotation_translation(np.zeros(4), np.zeros(3))
