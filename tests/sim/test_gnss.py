"""GNSS error models: the published magnitudes, the correlation in time, the yaw bias, and
the same numbers fix by fix as for a whole flight."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import orbit_poses

from turbinefit.geometry.se3 import SE3
from turbinefit.sim.gnss import GNSS_MODELS, GnssReceiver, gnss_model, gnss_poses


def _errors(model: str, seeds: range, n: int = 60, dt: float = 2.0) -> np.ndarray:
    gt = orbit_poses(n)
    t = dt * np.arange(n)
    return np.stack([gnss_poses(gt, t, gnss_model(model), np.random.default_rng(s))
                     .position_error_m for s in seeds])


@pytest.mark.parametrize("model", ["standard", "rtk"])
def test_position_errors_have_the_published_sigmas(model: str) -> None:
    e = _errors(model, range(300))  # (seeds, keyframes, 3)
    sigma = GNSS_MODELS[model].position_sigma()
    rms = np.sqrt(np.mean(e ** 2, axis=(0, 1)))
    np.testing.assert_allclose(rms, sigma, rtol=0.12)  # 300 flights, correlated in time
    # stationary: the first and the last keyframe spread alike
    np.testing.assert_allclose(e[:, 0].std(axis=0), e[:, -1].std(axis=0), rtol=0.3)


def test_errors_are_correlated_in_time() -> None:
    e = _errors("standard", range(200), n=40, dt=2.0)[..., 0]
    r = np.corrcoef(e[:, 10], e[:, 11])[0, 1]  # 2 s apart, tau 300 s: 0.993
    far = np.corrcoef(e[:, 0], e[:, -1])[0, 1]  # 78 s apart: 0.77
    assert r > 0.97 and far < r - 0.1


def test_yaw_bias_turns_every_pose_about_the_vertical() -> None:
    gt = orbit_poses(20)
    biases = []
    for s in range(200):
        fixes = gnss_poses(gt, np.arange(20.0), gnss_model("rtk"), np.random.default_rng(s))
        biases.append(fixes.yaw_bias)
        z = fixes.rotation_error[:, 2]
        assert np.allclose(z.mean(), fixes.yaw_bias, atol=math.radians(1.0))
        rel = fixes.world_T_cam.rotation_matrix() @ np.swapaxes(gt.rotation_matrix(), -1, -2)
        yaw = np.arctan2(rel[:, 1, 0], rel[:, 0, 0])
        np.testing.assert_allclose(yaw, z, atol=math.radians(0.1))
    assert math.degrees(float(np.std(biases))) == pytest.approx(2.0, rel=0.2)


def test_fix_by_fix_is_the_whole_flight() -> None:
    gt = orbit_poses(8)
    t = np.array([0.0, 1.0, 2.5, 3.0, 10.0, 11.0, 30.0, 31.0])
    whole = gnss_poses(gt, t, gnss_model("standard"), np.random.default_rng(7))
    rx = GnssReceiver(gnss_model("standard"), np.random.default_rng(7))
    fixes = [rx.measure(t[k], gt[k]) for k in range(8)]
    np.testing.assert_array_equal(np.stack([f.world_T_cam.wxyz_xyz for f in fixes]),
                                  whole.world_T_cam.wxyz_xyz)
    np.testing.assert_array_equal(whole.position_sigma_m, np.tile([1.5, 1.5, 0.5], (8, 1)))
    with pytest.raises(ValueError, match="increase"):
        rx.measure(31.0, gt[0])


def test_bad_models_and_inputs() -> None:
    with pytest.raises(ValueError, match="unknown GNSS model"):
        gnss_model("galileo")
    with pytest.raises(ValueError, match="timestamps"):
        gnss_poses(orbit_poses(3), [0.0, 1.0], gnss_model("rtk"), np.random.default_rng(0))
    with pytest.raises(ValueError, match="batch"):
        gnss_poses(SE3.identity(), [0.0], gnss_model("rtk"), np.random.default_rng(0))
