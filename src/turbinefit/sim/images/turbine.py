"""The solid turbine the image renderer draws round the skeletal model: the shape of
:mod:`turbinefit.turbine.solid` (tapered tower, nacelle box, spinner, blades) with the
nacelle of the scene (:class:`TurbineSolid`), and the segments a camera must keep clear of
(:func:`solid_segments`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from turbinefit.sim.images.arrays import FloatArray
from turbinefit.sim.images.scene import Scene
from turbinefit.turbine import solid
from turbinefit.turbine.model import TurbineGeometry, TurbineParams, model_points, skeleton_segments
from turbinefit.turbine.solid import NACELLE_REAR, NACELLE_REAR_MAX
from turbinefit.turbine.solid import blade_profile as blade_profile


class TurbineSolid(solid.TurbineSolid):
    """:class:`turbinefit.turbine.solid.TurbineSolid` with the nacelle proportions of
    ``scene`` (``scene.nacelle``) and the tower door at ``door_az``."""

    def __init__(self, theta: ArrayLike, geometry: TurbineGeometry, scene: Scene,
                 door_az: float = 0.0) -> None:
        super().__init__(theta, geometry, scene.nacelle, door_az)


def solid_segments(turbine: TurbineParams, geometry: TurbineGeometry) -> FloatArray:
    """Skeleton segments plus the nacelle's axis from its rear end (which the skeleton
    lacks: the nacelle overhangs behind the tower) to the hub."""
    segs = skeleton_segments(turbine, geometry)
    p, _ = model_points(turbine.to_vector(), geometry)
    w, tau = turbine.heading, geometry.shaft_tilt
    shaft = np.array([math.cos(w) * math.cos(tau), math.sin(w) * math.cos(tau), math.sin(tau)])
    r = abs(turbine.nacelle_length)
    rear = min(NACELLE_REAR[1] * max(r, 2.0), NACELLE_REAR_MAX)
    return np.concatenate([segs, np.stack([p[2] - (r + rear) * shaft, p[2]])[None]])
