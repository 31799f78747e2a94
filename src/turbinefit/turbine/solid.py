"""The plausible solid turbine round the skeletal model, and its triangle mesh.

The skeleton of :func:`~turbinefit.turbine.model.model_points` has no thickness. The photo
renderer (:mod:`turbinefit.sim.images`) and the mesh that ``fit`` and ``track`` write
(:mod:`turbinefit.io.mesh`) both dress it the same way, with the proportions defined here:

* a tower tapering from radius h / 30 at the base to h / 45 at the top, reaching up into
  the nacelle;
* a box nacelle (height ~0.06 b, width ~the height) along the (tilted) shaft through the
  hub, from just behind the spinner to 1.9-2.7 nacelle lengths (at most 16 m) behind the
  tower axis;
* an ellipsoid spinner at the hub (semi-axes 0.055 b along the shaft, 0.04 b across);
* three blades with elliptic cross-sections (:func:`blade_profile`: round root, chord
  0.08 b at 22 % span tapering to 0.015 b at the tip), the chord in the rotor plane at
  zero pitch, twisted by up to 14 degrees towards the root (:func:`blade_twist`).

World frame, metres, z up (as :mod:`turbinefit.turbine.model`). :func:`solid_mesh`
triangulates the solid into closed meshes, one per part.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineGeometry, model_points

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]

#: Range of the nacelle's overhang behind the tower axis, in nacelle lengths.
NACELLE_REAR = (1.9, 2.7)
#: Range of the nacelle's height, in blade lengths.
NACELLE_HEIGHT = (0.052, 0.068)
#: Range of the nacelle's width, in nacelle heights.
NACELLE_WIDTH = (0.85, 1.1)
#: The middle of each range: the nacelle of a turbine whose nacelle is not known
#: ``(rear overhang / nacelle_length, height / blade_length, width / height)``.
TYPICAL_NACELLE: tuple[float, float, float] = (
    0.5 * sum(NACELLE_REAR), 0.5 * sum(NACELLE_HEIGHT), 0.5 * sum(NACELLE_WIDTH))
#: The longest nacelle overhang behind the tower axis [m].
NACELLE_REAR_MAX = 16.0


class TurbineSolid:
    """The solid shape of one turbine round its skeleton (world metres): a tapered tower,
    a nacelle box along the shaft, an ellipsoid spinner and three blades (cross-sections:
    :func:`blade_profile`).

    Built from ``theta`` (7,) by :func:`~turbinefit.turbine.model.model_points` with
    ``geometry``; the nacelle's proportions are ``nacelle`` = (rear overhang / nacelle
    length, height / blade length, width / height).

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

    def __init__(self, theta: ArrayLike, geometry: TurbineGeometry = PAPER_GEOMETRY,
                 nacelle: tuple[float, float, float] = TYPICAL_NACELLE,
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
        rear, hfrac, wfrac = nacelle
        self.nac_h = hfrac * self.b
        self.nac_w = wfrac * self.nac_h
        rr = min(rear * max(r, 2.0), NACELLE_REAR_MAX)
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

    def chord_axis(self, blade: int) -> FloatArray:
        """Unit chord direction of blade ``blade`` (0, 1, 2) at zero pitch and twist: in
        the rotor plane, perpendicular to the blade (``shaft x blade``)."""
        e = unit_vector(self.tips[blade] - self.hub)
        c0 = np.cross(self.shaft, e)
        nc = float(np.linalg.norm(c0))
        return c0 / nc if nc > 1e-9 else _perp(e)


#: The blades' widest chord, in blade lengths (at 22 % span, :func:`blade_profile`).
BLADE_MAX_CHORD = 0.08
#: The blades' twist at the root [rad] (:func:`twist_fraction` of it further out).
ROOT_TWIST = math.radians(14.0)


def blade_profile(u: F32, b: float) -> tuple[F32, F32]:
    """Half chord A and half thickness B [m] (float32, shaped like ``u``) of a blade of
    length ``b`` [m] at span fractions ``u`` (float32, hub 0, tip 1): round root (radius
    0.022 b), widest (chord 0.08 b) at 22 %, tip chord 0.015 b."""
    rr = np.float32(0.022 * b)
    a_max = np.float32(0.5 * BLADE_MAX_CHORD * b)
    tip = np.float32(0.0075 * b)
    t = np.clip((u - 0.03) * (1.0 / (0.22 - 0.03)), 0.0, 1.0)
    ramp = t * t * (3.0 - 2.0 * t)  # smoothstep from 3 % to 22 % span
    outer = tip + (a_max - tip) * np.clip((1.0 - u) * np.float32(1 / 0.78), 0.0, 1.0) ** 1.15
    inner = u < 0.22
    A = np.where(inner, rr + (a_max - rr) * ramp, outer)
    B = np.where(inner, rr + (np.float32(0.011 * b) - rr) * ramp, 0.27 * outer)
    return A.astype(np.float32), B.astype(np.float32)


def twist_fraction(u: F32) -> F32:
    """The share of the root's twist (:data:`ROOT_TWIST`) at span fractions ``u``: 1 up to
    20 % span, falling to 0 at the tip as ``((1 - u) / 0.8) ** 1.5``."""
    return np.clip((1.0 - u) * np.float32(1 / 0.8), 0.0, 1.0) ** 1.5


def blade_twist(u: F32, pitch: float) -> F32:
    """Angle [rad] (float32, shaped like ``u``) of the chord from the rotor plane at span
    fractions ``u`` (float32): ``pitch`` plus a twist of 14 degrees up to 20 % span that
    falls to 0 at the tip (:func:`twist_fraction`). The chord turns from ``shaft x blade``
    towards ``blade x (shaft x blade)``."""
    return np.float32(pitch) + np.float32(ROOT_TWIST) * twist_fraction(u)



def blade_silhouette_half_width(solid: TurbineSolid, blade: NDArray[np.int_], u: FloatArray,
                                across: FloatArray, pitch: float
                                ) -> tuple[FloatArray, FloatArray]:
    """Half the width [m] a blade's elliptic section shows across unit directions
    ``across`` (..., 3) (perpendicular to the blade; the line of sight crossed with the
    blade's axis): the section's support ``h = sqrt((A chord.n)^2 + (B thick.n)^2)``,
    with the chord and thickness axes of :func:`solid_mesh` at ``pitch`` [rad]; and
    ``dh / dpitch`` [m/rad]. ``blade`` (...) is 0, 1 or 2, ``u`` (...) the span fraction."""
    blade = np.asarray(blade, dtype=np.int64)
    u32 = np.asarray(u, dtype=np.float32)
    n = np.asarray(across, dtype=np.float64)
    A32, B32 = blade_profile(u32, solid.b)
    A, B = A32.astype(np.float64), B32.astype(np.float64)
    e = solid.tips - solid.hub
    e /= np.maximum(np.linalg.norm(e, axis=-1, keepdims=True), 1e-12)
    c0 = np.stack([solid.chord_axis(i) for i in range(3)])
    chord, thick = section_axes(e[blade], c0[blade],
                                blade_twist(u32, pitch).astype(np.float64))
    cn = np.sum(chord * n, axis=-1)
    tn = np.sum(thick * n, axis=-1)
    h = np.sqrt((A * cn) ** 2 + (B * tn) ** 2)
    # d chord / d beta = thick, d thick / d beta = -chord
    dh = (A * A - B * B) * cn * tn / np.maximum(h, 1e-12)
    return h, dh


def section_axes(e: FloatArray, c0: FloatArray, beta: FloatArray
                 ) -> tuple[FloatArray, FloatArray]:
    """Unit chord and thickness axes (..., 3) of a blade section of unit axis ``e``
    whose chord at zero pitch and twist is ``c0`` (:meth:`TurbineSolid.chord_axis`),
    turned by ``beta`` (...) [rad] (:func:`blade_twist`) towards ``e x c0``; ``chord x
    thick = e``."""
    cb, sb = np.cos(beta)[..., None], np.sin(beta)[..., None]
    chord = cb * c0 + sb * np.cross(e, c0)
    return chord, np.cross(e, chord)

@dataclass(frozen=True)
class SolidPart:
    """One closed part of a :class:`TurbineSolid` as a triangle mesh.

    Attributes:
        name: ``tower``, ``nacelle``, ``spinner`` or ``blade_1`` .. ``blade_3`` (the blades
            of ``tip_1`` .. ``tip_3`` of :data:`~turbinefit.turbine.model.POINT_NAMES`).
        vertices: (n, 3) world metres.
        faces: (m, 3) vertex indices, counter-clockwise seen from outside.
    """

    name: str
    vertices: FloatArray
    faces: NDArray[np.int64]


#: Vertices round each ring of the tower, the spinner and the blades.
RING_VERTICES = {"tower": 32, "spinner": 24, "blade": 16}
#: Rings along a blade (denser towards the tip, where the chord changes fastest).
BLADE_RINGS = 28
#: Rings of the spinner between its poles.
SPINNER_RINGS = 10


def solid_mesh(solid: TurbineSolid, blade_pitch: float = 0.0,
               ring_step: float | None = None) -> list[SolidPart]:
    """The parts of ``solid`` as closed triangle meshes (world metres): tower, nacelle,
    spinner, blade_1, blade_2, blade_3; blades at ``blade_pitch`` [rad] (0: the chord in
    the rotor plane, as in operation) and twisted as :func:`blade_twist`. ``ring_step``
    [m]: rings at most about that far apart along the tower and the blades (for colours
    that vary along them; the tower's surface is the same, the blades' finer), None: the
    tower's two ends and :data:`BLADE_RINGS` a blade."""
    parts = []
    top = np.array([solid.base[0], solid.base[1], solid.tower_top_z])
    ex, ey = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    k = 2 if ring_step is None else max(2, math.ceil((top[2] - solid.base[2]) / ring_step) + 1)
    s = np.linspace(0.0, 1.0, k)[:, None]
    radii = solid.r0 + (solid.r1 - solid.r0) * s[:, 0]
    parts.append(SolidPart("tower", *_closed_tube(
        solid.base + s * (top - solid.base), np.tile(ex, (k, 1)), np.tile(ey, (k, 1)),
        radii, radii, RING_VERTICES["tower"], solid.base, top)))
    parts.append(SolidPart("nacelle", *_box(solid.nac_centre, solid.nac_half,
                                            np.stack([solid.shaft, solid.side, solid.up]))))
    # spinner: rings of the ellipsoid between its poles on the shaft
    a = np.linspace(-0.5 * math.pi, 0.5 * math.pi, SPINNER_RINGS + 2)[1:-1]
    k = a.size
    cent = solid.spin_centre + (solid.spin_len * np.sin(a))[:, None] * solid.shaft
    rad = solid.spin_r * np.cos(a)
    parts.append(SolidPart("spinner", *_closed_tube(
        cent, np.tile(solid.side, (k, 1)), np.tile(solid.up, (k, 1)), rad, rad,
        RING_VERTICES["spinner"], solid.spin_centre - solid.spin_len * solid.shaft,
        solid.spin_centre + solid.spin_len * solid.shaft)))
    rings = BLADE_RINGS if ring_step is None else max(BLADE_RINGS,
                                                       math.ceil(1.3 * solid.b / ring_step) + 1)
    u = (1.0 - (1.0 - np.linspace(0.0, 1.0, rings)) ** 1.3).astype(np.float32)
    half_chord, half_thick = blade_profile(u, solid.b)
    beta = blade_twist(u, blade_pitch).astype(np.float64)
    for i, tip in enumerate(solid.tips):
        e = unit_vector(tip - solid.hub)
        chord, thick = section_axes(e, solid.chord_axis(i), beta)  # faces outward
        cent = solid.hub + u.astype(np.float64)[:, None] * (tip - solid.hub)
        parts.append(SolidPart(f"blade_{i + 1}", *_closed_tube(
            cent, chord, thick, half_chord.astype(np.float64), half_thick.astype(np.float64),
            RING_VERTICES["blade"], cent[0], cent[-1])))
    return parts


def unit_vector(v: FloatArray) -> FloatArray:
    """``v`` (3,) scaled to length 1 (a zero vector stays zero)."""
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _perp(e: FloatArray) -> FloatArray:
    """A unit vector perpendicular to unit e."""
    a = np.array([0.0, 0.0, 1.0]) if abs(e[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    return unit_vector(np.cross(e, a))


def _closed_tube(centres: FloatArray, ax: FloatArray, ay: FloatArray, rx: FloatArray,
                 ry: FloatArray, n: int, start: FloatArray, end: FloatArray
                 ) -> tuple[FloatArray, NDArray[np.int64]]:
    """A closed tube of k elliptic rings (centres (k, 3), per ring the axes ax, ay (k, 3)
    with ``ax x ay`` along the tube, radii rx, ry (k,)), n vertices a ring, closed by fans
    to the points ``start`` and ``end``. Returns (vertices (k n + 2, 3), faces)."""
    k = len(centres)
    phi = 2.0 * math.pi * np.arange(n) / n
    ring = (centres[:, None] + (rx[:, None] * np.cos(phi))[..., None] * ax[:, None]
            + (ry[:, None] * np.sin(phi))[..., None] * ay[:, None])
    verts = np.concatenate([ring.reshape(-1, 3), start[None], end[None]])
    j = np.arange(n)
    jn = (j + 1) % n
    r = np.arange(k - 1)[:, None] * n
    a, b, c, d = r + j, r + jn, r + n + jn, r + n + j
    side = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 1).reshape(-1, 3)
    s, t = k * n, k * n + 1
    last = (k - 1) * n
    caps = [np.stack([np.full(n, s), jn, j], -1), np.stack([np.full(n, t), last + j, last + jn], -1)]
    return verts, np.concatenate([side, *caps]).astype(np.int64)


#: The box's corners (signs along its three axes) and its faces, outward.
_BOX_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                      dtype=np.float64)
_BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
                      dtype=np.int64)


def _box(centre: FloatArray, half: FloatArray, axes: FloatArray
         ) -> tuple[FloatArray, NDArray[np.int64]]:
    """A box round ``centre`` with half sizes ``half`` (3,) along the rows of ``axes``
    (3, 3), a right-handed orthonormal frame."""
    return centre + (_BOX_SIGNS * half) @ axes, _BOX_FACES.copy()
