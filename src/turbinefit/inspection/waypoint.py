"""A point of an inspection path (:class:`Waypoint`: a camera position and its view, the
part and side photographed) and the small geometry the planner's parts share: a view's
direction, a vector turned about an axis, a polyline's length."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from turbinefit.inspection.surface import FloatArray


@dataclass
class Waypoint:
    """One point of the path.

    Attributes:
        position: camera position (3,) [m, world].
        yaw: azimuth of the view from the world x axis, counter-clockwise from above [rad].
        pitch: elevation of the view, positive up [rad] (the gimbal's pitch).
        part: index into :data:`~turbinefit.inspection.surface.PARTS` of the part a photo is
            taken of, -1 for a transit point (no photo).
        side: the side (blade) or face (tower) photographed, -1 for transit.
        span: span of the station [m] (NaN for transit).
    """

    position: FloatArray
    yaw: float
    pitch: float
    part: int = -1
    side: int = -1
    span: float = math.nan

    @property
    def photo(self) -> bool:
        return self.part >= 0



def rotate(v: FloatArray, axis: FloatArray, angle: float) -> FloatArray:
    """v rotated about unit ``axis`` by ``angle`` (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * float(axis @ v) * (1.0 - c)



def path_length(p: FloatArray) -> float:
    """Length of the polyline ``p`` (n, 3) [m]."""
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


def view_dir(w: Waypoint) -> FloatArray:
    """Unit direction of ``w``'s view."""
    cp = math.cos(w.pitch)
    return np.array([cp * math.cos(w.yaw), cp * math.sin(w.yaw), math.sin(w.pitch)])

