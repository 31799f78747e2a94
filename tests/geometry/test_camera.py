"""The pinhole camera (turbinefit.geometry.camera): projection and its Jacobian, points
behind the camera, validation, scaling."""

import numpy as np
import pytest
from support import CAMERA

from turbinefit.geometry.camera import PinholeCamera


def test_projection_matches_opencv_model_and_jacobian():
    cam = PinholeCamera(640, 480, 500.0, 510.0, 320.0, 240.0, 0.5,
                        (-0.2, 0.05, 0.001, -0.002, 0.01))
    rng = np.random.default_rng(4)
    p = np.c_[rng.uniform(-2, 2, (100, 2)), rng.uniform(3, 10, 100)]
    uv, valid, J = cam.project(p, with_jacobian=True)
    # reference: the OpenCV plumb_bob equations written out independently
    k1, k2, p1, p2, k3 = cam.distortion
    x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    r2 = x * x + y * y
    rad = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    np.testing.assert_allclose(uv[:, 0], 500 * xd + 0.5 * yd + 320, atol=1e-9)
    np.testing.assert_allclose(uv[:, 1], 510 * yd + 240, atol=1e-9)
    eps = 1e-6
    for i in range(3):
        dp = np.zeros(3)
        dp[i] = eps
        num = (cam.project(p + dp)[0] - cam.project(p - dp)[0]) / (2 * eps)
        np.testing.assert_allclose(J[:, :, i], num, rtol=1e-5, atol=1e-4)
    assert valid.dtype == bool


def test_points_behind_camera_are_invalid_and_finite():
    p = np.array([[0.0, 0.0, -5.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1e-9], [1e6, 0, 1.0],
                  [0.0, 0.0, 10.0]])
    uv, valid, J = CAMERA.project(p, with_jacobian=True)
    assert np.all(np.isfinite(uv)) and np.all(np.isfinite(J))
    assert valid.tolist() == [False, False, False, False, True]
    np.testing.assert_allclose(uv[-1], [159.5, 119.5])


def test_camera_rejects_bad_focal_length():
    with pytest.raises(ValueError, match="focal"):
        PinholeCamera(320, 240, 0.0, 228.0, 160, 120)
    with pytest.raises(ValueError, match="focal"):
        PinholeCamera(320, 240, 228.0, -1.0, 160, 120)


def test_scaled_camera_keeps_pixel_centres():
    cam = CAMERA.scaled(2.0)
    p = np.array([[0.3, -0.2, 5.0]])
    uv1 = CAMERA.project(p)[0]
    uv2 = cam.project(p)[0]
    np.testing.assert_allclose((uv2 + 0.5) / 2 - 0.5, uv1, atol=1e-9)


def test_projection_at_a_reduced_size_is_the_full_size_projection_scaled():
    # heat-maps smaller than the photo: pixel centres aligned, (u + 0.5) w / W - 0.5
    cam = PinholeCamera(5280, 3956, 3770.0, 3772.0, 2641.3, 1975.2, 0.3,
                        (-0.12, 0.03, 0.001, -0.002, 0.0))
    rng = np.random.default_rng(7)
    p = np.c_[rng.uniform(-2, 2, (200, 2)), rng.uniform(3, 10, 200)]
    uv_full, _, J_full = cam.project_unbounded(p, with_jacobian=True)
    for w, h in ((320, 240), (160, 120), (5280 // 3, 3956 // 3)):
        small = cam.scaled_to(w, h)
        assert small == cam.resized(w, h)
        uv, _, J = small.project_unbounded(p, with_jacobian=True)
        s = np.array([w / 5280, h / 3956])
        np.testing.assert_allclose(uv, (uv_full + 0.5) * s - 0.5, rtol=0, atol=1e-9)
        np.testing.assert_allclose(J, J_full * s[:, None], rtol=1e-12, atol=1e-12)
    assert cam.scaled_to(5280, 3956) is cam


@pytest.mark.parametrize("size", [(320, 320), (100, 240), (5281, 3957), (0, 1)])
def test_scaled_to_refuses_other_aspect_ratios_and_larger_sizes(size):
    cam = PinholeCamera(640, 480, 500.0, 500.0, 319.5, 239.5)
    with pytest.raises(ValueError, match=f"{size[0]}x{size[1]}"):
        cam.scaled_to(*size)
    assert cam.scaled_to(320, 241).height == 241  # within a pixel of the aspect ratio
