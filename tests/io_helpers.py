"""Small synthetic data for the file-I/O tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, quat_normalize
from turbinefit.heatmaps import HeatmapStack
from turbinefit.turbine.model import TurbineParams

H, W = 24, 32


def random_poses(rng: np.random.Generator, n: int) -> SE3:
    q = quat_normalize(rng.normal(size=(n, 4)))
    t = rng.normal(scale=50.0, size=(n, 3))
    return SE3(np.concatenate([q, t], axis=1))


def timestamps(n: int, start: float = 1567000000.123456) -> np.ndarray:
    """Timestamps with six decimals, as a TUM file stores them."""
    return np.array([float(f"{start + 0.25 * k + 1e-6 * k:.6f}") for k in range(n)])


def camera(distortion: bool = True) -> PinholeCamera:
    d = (-0.12, 0.034, 1e-5, -2.5e-4, 0.0012) if distortion else (0.0,) * 5
    return PinholeCamera(W, H, 30.5, 31.25, 15.75, 11.5, 0.0, d)  # type: ignore[arg-type]


def turbine(offset: float = 0.0) -> TurbineParams:
    return TurbineParams(12.5 + offset, -3.25, 80.1, 1.2345678901234567, 4.0, 0.3, 40.7)


def make_flight(n: int = 5, seed: int = 0, optional: bool = True,
                distortion: bool = True) -> Flight:
    rng = np.random.default_rng(seed)
    maps = rng.random((n, 7, H, W), dtype=np.float32)
    return Flight(
        camera=camera(distortion),
        timestamps=timestamps(n),
        world_T_cam=random_poses(rng, n),
        heatmaps=HeatmapStack(maps),
        turbine=turbine(),
        odometry=random_poses(rng, n) if optional else None,
        gt_world_T_cam=random_poses(rng, n) if optional else None,
        gt_turbine=turbine(0.5) if optional else None,
    )


def leftovers(parent: Path) -> list[str]:
    """Hidden temporary entries left in ``parent`` by atomic writes."""
    return sorted(p.name for p in parent.iterdir() if p.name.startswith("."))
