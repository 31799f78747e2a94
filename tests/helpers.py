"""Small shared test utilities: look-at poses, smooth synthetic heat-maps, numerical
derivatives on the pose manifold."""

from __future__ import annotations

import numpy as np

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3

CAMERA = PinholeCamera(320, 240, 228.0, 228.0, 159.5, 119.5)


def look_at(eye: np.ndarray, target: np.ndarray) -> SE3:
    """world_T_cam of OpenCV cameras at ``eye`` (N, 3) looking at ``target`` (N, 3), y down."""
    eye = np.atleast_2d(eye).astype(float)
    target = np.atleast_2d(target).astype(float)
    z = target - eye
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    up = np.array([0.0, 0.0, 1.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=-1)
    return SE3.from_rotation_translation(R, eye)


def smooth_heatmaps(n: int, h: int = 240, w: int = 320, seed: int = 0) -> np.ndarray:
    """(n, 7, h, w) float32 sums of wide Gaussian bumps in (0.05, 0.95): smooth, no clamping."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    out = np.empty((n, 7, h, w), dtype=np.float32)
    for k in range(n):
        for c in range(7):
            acc = np.zeros((h, w))
            for _ in range(4):
                cu, cv = rng.uniform(0, w), rng.uniform(0, h)
                s = rng.uniform(20, 50)
                acc += rng.uniform(0.2, 1.0) * np.exp(-((u - cu) ** 2 + (v - cv) ** 2) / (2 * s * s))
            out[k, c] = 0.05 + 0.9 * acc / acc.max()
    return out


def orbit_poses(n: int, radius: float = 120.0, height: float = 60.0,
                centre: tuple[float, float, float] = (0.0, 0.0, 70.0)) -> SE3:
    ang = np.linspace(0, 1.2, n)
    eye = np.stack([radius * np.cos(ang), radius * np.sin(ang), np.full(n, height)], -1)
    return look_at(eye, np.tile(np.array(centre), (n, 1)))
