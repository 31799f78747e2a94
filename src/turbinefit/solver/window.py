"""Keyframe data for the solver without a whole flight, and the tracker's sliding window.

:class:`Keyframes` holds what :class:`~turbinefit.solver.problem.FitProblem` reads of a
flight (:class:`~turbinefit.solver.problem.ProblemData`): the camera, the keyframes'
timestamps, measured poses and heat-maps, and optionally odometry (body-frame odometry
poses whose steps are the pairwise measurements).
:class:`TrackWindow` is the tracker's window: those data of its keyframes plus their
arrival numbers, current estimates and whether their heat-maps show anything.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.edges import PhotoStack
from turbinefit.costs.relative_motion import RelativeMotions
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Keyframes:
    """The data of N keyframes a :class:`~turbinefit.solver.problem.FitProblem` is built on.

    Attributes:
        camera: intrinsics of the heat-maps' pixel grid.
        timestamps: (N,) keyframe times [s].
        world_T_cam: (N,) measured (GPS/IMU) camera-to-world poses.
        heatmaps: the keyframes' heat-maps, (7, H, W) each.
        odometry: (N,) poses whose consecutive relative poses are the pairwise
            measurements; None: those of ``world_T_cam``.
        position_sigma: (N, 3) standard deviations [m] of the positions of
            ``world_T_cam`` (absolute position priors), or None.
        motions: (N,) relative motions measured by tie points (entry k: from keyframe
            k-1 to k), or None.
        photos: (N,) grey photos for the edge term, or None.
    """

    camera: PinholeCamera
    timestamps: FloatArray
    world_T_cam: SE3
    heatmaps: HeatmapStack
    odometry: SE3 | None = None
    position_sigma: FloatArray | None = None
    motions: RelativeMotions | None = None
    photos: PhotoStack | None = None

    @property
    def num_keyframes(self) -> int:
        return len(self.timestamps)

    def measurement_poses(self) -> SE3:
        """Poses whose consecutive relative poses are the pairwise measurements."""
        return self.odometry if self.odometry is not None else self.world_T_cam


@dataclass(frozen=True)
class TrackWindow:
    """The tracker's sliding window, oldest keyframe first.

    Attributes:
        index: (n,) arrival number of each keyframe.
        data: their camera, timestamps, measured poses and heat-maps (referenced, not
            copied).
        world_T_cam: (n,) their current estimates.
        evidence: (n,) whether each keyframe's heat-maps show anything.
    """

    index: NDArray[np.int64]
    data: Keyframes
    world_T_cam: SE3
    evidence: NDArray[np.bool_]

    def __len__(self) -> int:
        return int(self.index.size)

    @staticmethod
    def first(camera: PinholeCamera, index: int, timestamp: float, measured: SE3,
              heatmaps: NDArray[np.floating], world_T_cam: SE3, evidence: bool,
              odometry: SE3 | None = None,
              position_sigma: FloatArray | None = None,
              motion: RelativeMotions | None = None,
              photo: PhotoStack | None = None) -> TrackWindow:
        """A window of one keyframe: its measured pose, heat-maps, estimate and, if the
        flight has them, its odometry pose, position standard deviations (3,), its
        relative motion from the keyframe before (one entry) and its grey photo (a stack
        of one)."""
        data = Keyframes(camera, np.array([timestamp], dtype=np.float64),
                         SE3(measured.wxyz_xyz[None].copy()), HeatmapStack([heatmaps]),
                         None if odometry is None else SE3(odometry.wxyz_xyz[None].copy()),
                         None if position_sigma is None
                         else np.asarray(position_sigma, dtype=np.float64).reshape(1, 3),
                         motion, photo)
        return TrackWindow(np.array([index], dtype=np.int64), data,
                           SE3(world_T_cam.wxyz_xyz[None].copy()), np.array([evidence]))

    def append(self, index: int, timestamp: float, measured: SE3,
               heatmaps: NDArray[np.floating], world_T_cam: SE3, evidence: bool,
               odometry: SE3 | None = None,
               position_sigma: FloatArray | None = None,
               motion: RelativeMotions | None = None,
               photo: PhotoStack | None = None) -> TrackWindow:
        """The window with one more keyframe at its end (``odometry``,
        ``position_sigma`` and ``photo``, a stack of one, given exactly when the window's
        keyframes have them;
        ``motion``: its relative motion from the window's last keyframe, one entry, or
        None for none)."""
        d = self.data
        if (odometry is None) != (d.odometry is None):
            raise ValueError("odometry must be given for every keyframe of a window or none")
        if (position_sigma is None) != (d.position_sigma is None):
            raise ValueError("position_sigma must be given for every keyframe of a window "
                             "or none")
        if (photo is None) != (d.photos is None):
            raise ValueError("photos must be given for every keyframe of a window or none")
        maps = [d.heatmaps[k] for k in range(len(d.heatmaps))] + [heatmaps]
        data = Keyframes(d.camera, np.append(d.timestamps, timestamp),
                         _append(d.world_T_cam, measured), HeatmapStack(maps),
                         None if d.odometry is None or odometry is None
                         else _append(d.odometry, odometry),
                         None if d.position_sigma is None or position_sigma is None
                         else np.vstack([d.position_sigma,
                                         np.asarray(position_sigma, np.float64).reshape(1, 3)]),
                         _append_motion(d.motions, motion, len(self)),
                         None if d.photos is None or photo is None
                         else PhotoStack(np.concatenate([d.photos.images, photo.images]),
                                         d.photos.scale))
        return TrackWindow(np.append(self.index, index), data,
                           _append(self.world_T_cam, world_T_cam),
                           np.append(self.evidence, evidence))

    def drop_oldest(self) -> TrackWindow:
        """The window without its first keyframe (which must not be the only one)."""
        d = self.data
        data = Keyframes(d.camera, d.timestamps[1:], d.world_T_cam[1:],
                         d.heatmaps.subset(np.arange(1, len(d.heatmaps))),
                         None if d.odometry is None else d.odometry[1:],
                         None if d.position_sigma is None else d.position_sigma[1:],
                         None if d.motions is None
                         else d.motions.take(np.arange(1, len(d.motions))),
                         None if d.photos is None else d.photos.take(np.arange(1, len(d.photos))))
        return TrackWindow(self.index[1:], data, self.world_T_cam[1:], self.evidence[1:])

    def with_estimate(self, world_T_cam: SE3) -> TrackWindow:
        """The window with new estimates (n,)."""
        return TrackWindow(self.index, self.data, world_T_cam, self.evidence)


def _append(batch: SE3, pose: SE3) -> SE3:
    return SE3(np.concatenate([batch.wxyz_xyz, pose.wxyz_xyz[None]]))


def _append_motion(motions: RelativeMotions | None, motion: RelativeMotions | None,
                   n: int) -> RelativeMotions | None:
    """The window's ``n`` motions with one more entry (None: none measured)."""
    if motions is None and motion is None:
        return None
    return ((motions or RelativeMotions.none(n))
            .append(motion or RelativeMotions.none(1)))
