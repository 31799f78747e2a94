"""The solid turbine the image renderer draws round the skeletal model: tapered tower,
nacelle box, spinner and blades (:class:`TurbineSolid`, :func:`blade_profile`), and the
segments a camera must keep clear of (:func:`solid_segments`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from turbinefit.sim.images.arrays import F32, FloatArray, smoothstep
from turbinefit.sim.images.scene import NACELLE_REAR, Scene
from turbinefit.turbine.model import TurbineGeometry, TurbineParams, model_points, skeleton_segments

_NACELLE_REAR_MAX = 16.0  # [m]


class TurbineSolid:
    """The solid shape of one turbine as the renderer draws it round its skeleton (world
    metres): a tapered tower, a nacelle box along the shaft, an ellipsoid spinner and three
    blades (cross-sections: :func:`blade_profile`).

    Built from ``theta`` (7,) by :func:`~turbinefit.turbine.model.model_points` with
    ``geometry``; the nacelle's proportions come from ``scene.nacelle``.

    Attributes:
        base, top, hub: skeleton points (3,) of the tower base, tower top and hub.
        tips: the blade tips (3, 3).
        h, b: tower height and blade length (at least 1 m and 0.5 m).
        r0, r1: tower radius at the base (h / 30) and at the top (h / 45).
        shaft, up, side: the nacelle's unit axes: along the shaft towards the rotor,
            up (tilted with the shaft) and ``up x shaft``.
        nac_h, nac_w: nacelle height and width.
        nac_centre, nac_half: the nacelle box's centre (3,) and half sizes along
            (shaft, side, up).
        nac_rear: centre of the nacelle's rear face.
        tower_top_z: height where the tower ends (it reaches up into the nacelle).
        spin_len, spin_r: the spinner's semi-axis along the shaft and its radius.
        spin_centre: the spinner's centre.
        centre: centre of the skeleton's bounding box.
        door_az: azimuth of the tower door round the tower axis, from the world x axis
            counter-clockwise [rad].
    """

    def __init__(self, theta: ArrayLike, geometry: TurbineGeometry, scene: Scene,
                 door_az: float = 0.0) -> None:
        th = np.asarray(theta, dtype=np.float64).ravel()
        p, _ = model_points(th, geometry)
        self.door_az = door_az
        self.base, self.top, self.hub = p[0], p[1], p[2]
        self.tips = p[3:]
        h, w, r, b = float(th[2]), float(th[3]), abs(float(th[4])), abs(float(th[6]))
        self.h, self.b = max(h, 1.0), max(b, 0.5)
        self.r0 = self.h / 30.0
        self.r1 = self.h / 45.0
        tau = geometry.shaft_tilt
        self.shaft = np.array([math.cos(w) * math.cos(tau), math.sin(w) * math.cos(tau),
                               math.sin(tau)])
        self.up = np.array([-math.cos(w) * math.sin(tau), -math.sin(w) * math.sin(tau),
                            math.cos(tau)])
        self.side = np.cross(self.up, self.shaft)
        rear, hfrac, wfrac = scene.nacelle
        self.nac_h = hfrac * self.b
        self.nac_w = wfrac * self.nac_h
        rr = min(rear * max(r, 2.0), _NACELLE_REAR_MAX)
        front = -0.15 * r
        back = -(r + rr)
        # the nacelle's axis runs along the shaft through the hub; it starts rr behind the
        # tower axis and ends just behind the spinner
        self.nac_centre = self.hub + 0.5 * (front + back) * self.shaft
        self.nac_half = np.array([0.5 * (front - back), 0.5 * self.nac_w, 0.5 * self.nac_h])
        self.nac_rear = self.hub + back * self.shaft
        # the tower reaches up into the nacelle even if the hub sits high above the tower top
        bottom = self.hub[2] - 0.5 * self.nac_h
        self.tower_top_z = max(float(self.top[2]), bottom + 0.3)
        self.spin_len = 0.055 * self.b
        self.spin_r = 0.04 * self.b
        self.spin_centre = self.hub + 0.25 * self.spin_len * self.shaft
        self.centre = 0.5 * (p.min(axis=0) + p.max(axis=0))


def blade_profile(u: F32, b: float) -> tuple[F32, F32]:
    """Half chord A and half thickness B [m] (float32, shaped like ``u``) of the renderer's
    blade of length ``b`` [m] at span fractions ``u`` (float32, hub 0, tip 1): round root
    (radius 0.022 b), widest (chord 0.08 b) at 22 %, tip chord 0.015 b."""
    rr = np.float32(0.022 * b)
    a_max = np.float32(0.04 * b)
    tip = np.float32(0.0075 * b)
    ramp = smoothstep(0.03, 0.22, u)
    outer = tip + (a_max - tip) * np.clip((1.0 - u) * np.float32(1 / 0.78), 0.0, 1.0) ** 1.15
    inner = u < 0.22
    A = np.where(inner, rr + (a_max - rr) * ramp, outer)
    B = np.where(inner, rr + (np.float32(0.011 * b) - rr) * ramp, 0.27 * outer)
    return A.astype(np.float32), B.astype(np.float32)


def solid_segments(turbine: TurbineParams, geometry: TurbineGeometry) -> FloatArray:
    """Skeleton segments plus the nacelle's axis from its rear end (which the skeleton
    lacks: the nacelle overhangs behind the tower) to the hub."""
    segs = skeleton_segments(turbine, geometry)
    p, _ = model_points(turbine.to_vector(), geometry)
    w, tau = turbine.heading, geometry.shaft_tilt
    shaft = np.array([math.cos(w) * math.cos(tau), math.sin(w) * math.cos(tau), math.sin(tau)])
    r = abs(turbine.nacelle_length)
    rear = min(NACELLE_REAR[1] * max(r, 2.0), _NACELLE_REAR_MAX)
    return np.concatenate([segs, np.stack([p[2] - (r + rear) * shaft, p[2]])[None]])
