"""A flight: everything the fit needs, in memory (no file I/O here; see turbinefit.io)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.edges import PhotoStack
from turbinefit.costs.relative_motion import RelativeMotions
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.turbine.model import TurbineParams


@dataclass
class Flight:
    """One recorded (or simulated) inspection flight.

    Attributes:
        camera: intrinsics of the heat-maps' pixel grid.
        timestamps: (N,) keyframe times [s], strictly increasing.
        world_T_cam: (N,) initial camera-to-world pose of each keyframe (GPS/IMU).
        heatmaps: the N keyframes' heat-maps, (7, H, W) each, H, W = camera size.
        turbine: initial turbine parameters.
        odometry: (N,) poses whose consecutive relative poses are the pairwise
            measurements; None = use the relative poses of ``world_T_cam``.
        gt_world_T_cam: (N,) ground-truth poses, if known.
        gt_turbine: ground-truth turbine, if known.
        position_sigma: (N, 3) standard deviations [m] of the positions of
            ``world_T_cam`` along the world axes (RTK), or None: then no absolute position
            prior (:mod:`turbinefit.costs.position_prior`).
        motions: (N,) relative motions between consecutive photos measured from their
            tie points (entry k: from keyframe k-1 to k), or None
            (:mod:`turbinefit.costs.relative_motion`).
        photos: (N,) the keyframes' grey photos for the edge term, or None
            (:mod:`turbinefit.costs.edges`).
    """

    camera: PinholeCamera
    timestamps: NDArray[np.float64]
    world_T_cam: SE3
    heatmaps: HeatmapStack
    turbine: TurbineParams
    odometry: SE3 | None = None
    gt_world_T_cam: SE3 | None = None
    gt_turbine: TurbineParams | None = None
    position_sigma: NDArray[np.float64] | None = None
    motions: RelativeMotions | None = None
    photos: PhotoStack | None = None

    def __post_init__(self) -> None:
        n = len(self.timestamps)
        if self.world_T_cam.batch_shape != (n,):
            raise ValueError(f"{n} timestamps but poses of shape {self.world_T_cam.batch_shape}")
        if len(self.heatmaps) != n:
            raise ValueError(f"{n} timestamps but {len(self.heatmaps)} heat-maps")
        if (self.heatmaps.height, self.heatmaps.width) != (self.camera.height, self.camera.width):
            raise ValueError(
                f"heat-maps are {self.heatmaps.width}x{self.heatmaps.height} but the camera is "
                f"{self.camera.width}x{self.camera.height}")
        s = self.position_sigma
        if s is not None and (s.shape != (n, 3) or not np.all(np.isfinite(s))
                              or not np.all(s > 0)):
            raise ValueError(f"position_sigma must be ({n}, 3) positive and finite, got shape "
                             f"{s.shape}")
        if self.photos is not None and len(self.photos) != n:
            raise ValueError(f"{n} timestamps but {len(self.photos)} photos")
        if self.motions is not None and len(self.motions) != n:
            raise ValueError(f"{n} timestamps but {len(self.motions)} relative motions")
        for name in ("odometry", "gt_world_T_cam"):
            v = getattr(self, name)
            if v is not None and v.batch_shape != (n,):
                raise ValueError(f"{name} has shape {v.batch_shape}, expected ({n},)")

    @property
    def num_keyframes(self) -> int:
        return len(self.timestamps)

    @property
    def has_ground_truth(self) -> bool:
        return self.gt_world_T_cam is not None and self.gt_turbine is not None

    def measurement_poses(self) -> SE3:
        """Poses whose consecutive relative poses are the pairwise measurements."""
        return self.odometry if self.odometry is not None else self.world_T_cam
