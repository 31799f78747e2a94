"""Tie points between consecutive photos (turbinefit.tiepoints): the relative rotation and
direction of motion of a synthetic two-plane scene photographed twice, recovered to a
fraction of a degree with an information matrix that says how well; photos with no
texture (sky only, overexposed) give no measurement instead of a wrong one."""

import numpy as np
import pytest

from turbinefit.costs.relative_motion import relative_motion_residuals
from turbinefit.costs.robust import RobustLoss
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, matrix_to_quat, so3_exp

cv2 = pytest.importorskip("cv2")
from turbinefit.tiepoints import (  # noqa: E402
    MotionMeter,
    TiePointOptions,
    measure_motions,
    photo_features,
    relative_motion,
)

W, H = 640, 480
CAM = PinholeCamera(W, H, 500.0, 500.0, 319.5, 239.5)


def _texture(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = rng.uniform(0, 255, (H // 4, W // 4)).astype(np.float32)
    t = cv2.resize(t, (W, H), interpolation=cv2.INTER_CUBIC)
    return np.clip(cv2.GaussianBlur(t, (0, 0), 1.0), 0, 255).astype(np.uint8)


def _two_views(R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Photo 1 of a far plane (z = 60 m) with a near plane (z = 15 m) over its left half,
    and photo 2 of the camera moved by ``X_2 = R X_1 + t``, by plane-induced homographies."""
    K = CAM.K
    far, near = _texture(1), _texture(2)
    mask = np.zeros((H, W), np.uint8)
    mask[:, : W // 2] = 255
    img1 = np.where(mask > 0, near, far).astype(np.uint8)
    n = np.array([0.0, 0.0, 1.0])
    out = []
    for tex, depth, m in ((far, 60.0, None), (near, 15.0, mask)):
        Hm = K @ (R + np.outer(t, n) / depth) @ np.linalg.inv(K)
        out.append((cv2.warpPerspective(tex, Hm, (W, H), flags=cv2.INTER_CUBIC),
                    None if m is None else cv2.warpPerspective(m, Hm, (W, H))))
    (far2, _), (near2, m2) = out
    assert m2 is not None
    img2 = np.where(m2 > 127, near2, far2).astype(np.uint8)
    return img1, img2


def test_recovers_rotation_and_direction_of_motion() -> None:
    R = so3_exp(np.radians([0.5, -1.5, 0.3]))
    c = np.array([1.2, 0.1, 0.3])  # camera 2's centre in camera 1's frame [m]
    t = -R @ c
    img1, img2 = _two_views(R, t)
    m = relative_motion(photo_features(img1, CAM), photo_features(img2, CAM), CAM)
    assert m is not None and m.inliers > 100
    want_q = matrix_to_quat(R.T)
    err = np.degrees(2 * np.arcsin(min(1.0, np.linalg.norm(
        (SE3.from_rotation_translation(m.i_q_j, np.zeros(3)).inverse()
         @ SE3.from_rotation_translation(want_q, np.zeros(3))).wxyz[1:]))))
    assert err < 0.1
    cos = float(m.i_dir_j @ (c / np.linalg.norm(c)))
    assert np.degrees(np.arccos(min(1.0, cos))) < 3.0
    # the information says how well: the truth is within a few standard deviations
    world_T_1 = SE3.identity()
    world_T_2 = SE3.from_rotation_translation(want_q, c)
    r, _, _, _ = relative_motion_residuals(
        SE3(world_T_1.wxyz_xyz[None]), SE3(world_T_2.wxyz_xyz[None]), m.i_q_j[None],
        m.i_dir_j[None], m.sqrt_info[None], RobustLoss(), False)
    assert float(np.sum(r * r)) < 50.0


@pytest.mark.parametrize("level", [0, 128, 255])
def test_photos_without_texture_give_no_measurement(level: int) -> None:
    flat = np.full((H, W, 3), level, np.uint8)
    textured = _two_views(np.eye(3), np.array([-1.0, 0.0, 0.0]))[0]
    assert relative_motion(photo_features(flat, CAM), photo_features(flat, CAM), CAM) is None
    assert relative_motion(photo_features(textured, CAM), photo_features(flat, CAM), CAM) is None


def test_measure_motions_one_entry_per_photo() -> None:
    img1, img2 = _two_views(so3_exp(np.radians([0.0, 1.0, 0.0])), np.array([-1.0, 0.0, 0.0]))
    flat = np.full((H, W), 200, np.uint8)
    photos = [img1, img2, flat, img1]
    motions = measure_motions(lambda k: photos[k], len(photos), CAM,
                              TiePointOptions(max_width=W))
    assert len(motions) == 4
    assert motions.valid.tolist() == [False, True, False, False]
    assert np.all(np.isfinite(motions.sqrt_info))
    assert MotionMeter(CAM).add(img1) is None
