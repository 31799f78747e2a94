"""What the tracker accepts of an arriving keyframe: each input checked before anything
changes, and :class:`KeyframeError` naming the keyframe and what is wrong with it.

A keyframe brings its timestamp, measured pose and heat-maps, and, given for every
keyframe of a flight or for none (the first decides), its odometry pose, the position
standard deviations of its GNSS fix (RTK), its grey photo (the edge and width terms) and
its tie-point motion from the keyframe before.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.edges import PhotoStack
from turbinefit.costs.relative_motion import RelativeMotions
from turbinefit.errors import TurbinefitError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import NUM_CHANNELS
from turbinefit.solver.window import TrackWindow

FloatArray = NDArray[np.float64]


class KeyframeError(TurbinefitError, ValueError):
    """An input keyframe is unusable (out of order, wrong shape, not finite); ``index``
    is its number in arrival order. The tracker's state is unchanged."""

    def __init__(self, index: int, message: str) -> None:
        super().__init__(f"keyframe {index}: {message}")
        self.index = index
        self.reason = message


def check_keyframe(k: int, timestamp: float, last_timestamp: float | None, world_T_cam: SE3,
                   heatmaps: NDArray[np.floating], odometry: SE3 | None,
                   has_odometry: bool | None, camera: PinholeCamera,
                   map_dtype: type[np.floating] | None
                   ) -> tuple[NDArray[np.floating], type[np.floating]]:
    """Keyframe ``k``'s heat-maps, contiguous and of the flight's storage (``map_dtype``:
    float16 or float32, the first keyframe's; None: this is the first), and that storage;
    its timestamp after ``last_timestamp``, its pose and odometry pose one finite SE3
    each, the odometry given as the keyframes before had it (``has_odometry``), the
    heat-maps (7, H, W) of ``camera`` and finite."""
    if has_odometry is not None and (odometry is not None) != has_odometry:
        raise KeyframeError(k, "odometry pose given, but not for the keyframes before"
                            if odometry is not None else
                            "no odometry pose, but the keyframes before had one")
    if odometry is not None and (odometry.batch_shape != ()
                                 or not np.all(np.isfinite(odometry.wxyz_xyz))):
        raise KeyframeError(k, "odometry pose must be one finite SE3")
    if not math.isfinite(timestamp):
        raise KeyframeError(k, "timestamp is not finite")
    if last_timestamp is not None and timestamp <= last_timestamp:
        raise KeyframeError(k, f"timestamp {float(timestamp)!r} is not after the previous "
                            f"one ({float(last_timestamp)!r})")
    if world_T_cam.batch_shape != () or not np.all(np.isfinite(world_T_cam.wxyz_xyz)):
        raise KeyframeError(k, "pose must be one finite SE3")
    maps = np.asarray(heatmaps)
    shape = (NUM_CHANNELS, camera.height, camera.width)
    if maps.shape != shape:
        raise KeyframeError(k, f"heat-maps have shape {maps.shape}, expected {shape}")
    dtype: type[np.floating] = map_dtype or (
        np.float16 if maps.dtype == np.float16 else np.float32)
    if maps.dtype != dtype or not maps.flags.c_contiguous:
        maps = np.ascontiguousarray(maps, dtype=dtype)
    if not math.isfinite(float(maps.sum(dtype=np.float64))):  # float64: cannot overflow
        raise KeyframeError(k, "heat-maps contain NaN or inf")
    return maps, dtype


def check_photo(k: int, photo: NDArray[np.generic] | None, window: TrackWindow | None,
                camera: PinholeCamera) -> PhotoStack | None:
    """Keyframe ``k``'s grey photo as a stack of one, checked: given as the keyframes of
    ``window`` had one, (H, W) of the heat-maps' aspect (``camera``) and of the window's
    photos' size, finite. Photos under
    :data:`~turbinefit.solver.photo_terms.MIN_EDGE_SCALE` times the maps' size are
    accepted and not read."""
    _as_before(k, "photo", photo is not None,
               None if window is None else window.data.photos is not None)
    if photo is None:
        return None
    img = np.asarray(photo)
    if img.ndim != 2 or img.shape[0] * camera.width != img.shape[1] * camera.height:
        raise KeyframeError(k, f"photo must be grey (H, W) of the heat-maps' aspect "
                            f"({camera.width} x {camera.height}), got shape {img.shape}")
    scale = img.shape[1] / camera.width
    if window is not None and window.data.photos is not None \
            and scale != window.data.photos.scale:
        raise KeyframeError(k, f"photo is {img.shape[1]} px wide; the keyframes before "
                            f"were {window.data.photos.scale * camera.width:g}")
    if img.dtype != np.uint8:
        img = img.astype(np.float32)
        if not np.all(np.isfinite(img)):
            raise KeyframeError(k, "photo contains NaN or inf")
    return PhotoStack(img[None], scale)


def check_position_sigma(k: int, position_sigma: NDArray[np.floating] | None,
                         window: TrackWindow | None) -> FloatArray | None:
    """Keyframe ``k``'s position standard deviations (3,), checked: given as the
    keyframes of ``window`` had them, positive and finite."""
    _as_before(k, "position_sigma", position_sigma is not None,
               None if window is None else window.data.position_sigma is not None)
    if position_sigma is None:
        return None
    s = np.asarray(position_sigma, dtype=np.float64)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or not np.all(s > 0):
        raise KeyframeError(k, "position_sigma must be 3 positive finite numbers")
    return s


def _as_before(k: int, what: str, given: bool, before: bool | None) -> None:
    """Keyframe ``k``'s ``what`` is given as the keyframes before had it (``before``;
    None: there were none)."""
    if before is not None and given != before:
        raise KeyframeError(k, f"{what} given, but not for the keyframes before" if given
                            else f"no {what}, but the keyframes before had one")


def check_motion(k: int, motion: RelativeMotions | None) -> RelativeMotions | None:
    """Keyframe ``k``'s tie-point motion, checked to be one entry."""
    if motion is not None and len(motion) != 1:
        raise KeyframeError(k, f"motion must hold one entry, got {len(motion)}")
    return motion
