"""The fitted turbine as surfaces an inspection refers to: named blades, their chord frames
and sides, the tower's faces, and ray casting (which part, span and side a ray meets).

**Blade names.** Blades are named A, B, C by their rotor angle as seen from upwind (in
front of the hub, looking at it), measured clockwise from 12 o'clock: A is the blade in
``[0, 120)`` deg, B in ``[120, 240)``, C in ``[240, 360)``. In the model's terms blade
``i`` (:func:`~turbinefit.turbine.model.model_points`, rotor angle
``phi_i = phi + 2 pi i / 3`` counter-clockwise seen from upwind) has the clockwise angle
``-phi_i mod 2 pi``. A blade within a few degrees of 12 o'clock sits on the boundary: the
fit's blade-rotation error can swap the names (:func:`name_margin_deg` says how far the
nearest blade is from it).

**Sides.** The rotor turns clockwise seen from upwind (the usual sense). A blade is a flat
section in the rotor plane (pitch 0) unless a pitch is given: its leading edge points
along the rotation (``e x shaft`` for a blade along unit ``e``, the shaft pointing upwind
from the tower to the hub), its pressure side faces upwind. A positive pitch turns the
leading edge upwind (towards feather). The side a camera sees at a point of the blade
comes from the direction to the camera, projected on the plane across the blade: within
45 deg of the leading edge direction it is the ``leading_edge``, of the upwind normal the
``pressure_side``, and so on round (``trailing_edge``, ``suction_side``). The tower's
faces are named the same way round its axis, from the heading, as seen from upwind:
``front`` (towards the rotor), ``right``, ``back``, ``left``.

**Shape**: the solid of :mod:`turbinefit.turbine.solid` (the proportions the photo
renderer draws and ``turbine.glb`` shows: tapered tower, nacelle box, spinner, blades of
elliptic sections), with the nacelle of a typical turbine and, as :class:`SurfaceShape`
says, flat blades unless a pitch or twist is given. The renderer twists its blades
(:data:`~turbinefit.turbine.solid.ROOT_TWIST` at the root) and turns pitch and twist the
other way round the blade axis from this module's convention (as for a rotor turning
anticlockwise): its pitch ``p`` and twist ``T`` are ``-p`` and ``-T`` here.

**Ray casting** (:meth:`TurbineSurface.cast_rays`): tower and blades are tubes met where
the ray passes nearest their axis (the renderer's construction): a hit if the ray's
distance from the axis is within the half-width of the section seen along the ray, at an
axis coordinate inside the tube (blade tips rounded, parts thinner than a pixel a pixel
wide); the spinner is an ellipsoid and the nacelle a box, met exactly. The nearest hit
wins, so a blade behind the tower or another blade is hidden. Span is the entry point's
axis coordinate: metres from the hub centre along the blade (the model's blade line
starts there; a real blade's root flange is about the hub's radius further out), and
metres above the ground on the tower.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.solver.init import normalized_rays
from turbinefit.turbine.model import (
    BLADE_PERIOD,
    PAPER_GEOMETRY,
    TurbineGeometry,
    TurbineParams,
    model_points,
)
from turbinefit.turbine.solid import (
    BLADE_MAX_CHORD,
    TYPICAL_NACELLE,
    TurbineSolid,
    blade_profile,
    twist_fraction,
    unit_vector,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

BLADE_NAMES = ("A", "B", "C")
#: Parts, in the order of their codes in :class:`RayHits` (-1: nothing).
PARTS = ("blade_A", "blade_B", "blade_C", "tower", "nacelle", "hub")
TOWER, NACELLE, HUB = 3, 4, 5
#: Blade sides, in the order of their sectors round the blade (from the leading edge
#: towards the upwind normal).
BLADE_SIDES = ("leading_edge", "pressure_side", "trailing_edge", "suction_side")
#: Tower faces, in the order of their sectors round the axis (from the heading towards
#: the right seen from upwind).
TOWER_FACES = ("front", "right", "back", "left")


@dataclass(frozen=True)
class SurfaceShape:
    """What the fit does not know of the solid round the skeleton (its proportions are
    :mod:`turbinefit.turbine.solid`'s, the photo renderer's and ``turbine.glb``'s).

    Attributes:
        blade_pitch: blade pitch [rad] (0: the chord in the rotor plane; positive turns the
            leading edge upwind).
        blade_twist: twist at the root [rad], the same sense as the pitch, fading outboard
            as :func:`~turbinefit.turbine.solid.twist_fraction` (0: a flat blade; the
            renderer's blades: ``-ROOT_TWIST``, see the module docstring).
        nacelle: the nacelle's proportions (:class:`~turbinefit.turbine.solid.TurbineSolid`).
    """

    blade_pitch: float = 0.0
    blade_twist: float = 0.0
    nacelle: tuple[float, float, float] = TYPICAL_NACELLE


@dataclass(frozen=True)
class Blade:
    """One named blade: its axis from the hub and its chord frame (world, unit vectors).

    Attributes:
        name: ``A``, ``B`` or ``C``.
        model_index: the blade's index in the model (tip ``model_points()[3 + i]``).
        clock_deg: rotor angle seen from upwind, clockwise from 12 o'clock [deg].
        root, axis, length: hub centre, unit direction hub -> tip, blade length [m].
        chord, normal: the leading edge direction and the pressure side's normal (upwind),
            across the axis, after the pitch.
    """

    name: str
    model_index: int
    clock_deg: float
    root: FloatArray
    axis: FloatArray
    length: float
    chord: FloatArray
    normal: FloatArray


def blade_clock_angles(turbine: TurbineParams) -> FloatArray:
    """Clockwise angle from 12 o'clock seen from upwind [deg, 0..360) of model blades 0-2."""
    flip = math.pi if turbine.blade_length < 0 else 0.0  # tips on the other side of the hub
    phi = turbine.blade_rotation + flip + BLADE_PERIOD * np.arange(3)
    return np.degrees((-phi) % (2.0 * math.pi)) % 360.0


def blade_names(turbine: TurbineParams) -> list[str]:
    """The name (``A``, ``B``, ``C``) of model blades 0, 1, 2 (see the module docstring)."""
    return [BLADE_NAMES[int(c // 120.0) % 3] for c in blade_clock_angles(turbine)]


def name_margin_deg(turbine: TurbineParams) -> float:
    """How far [deg] the blade nearest 12 o'clock is from it: names are stable against a
    blade-rotation error smaller than this."""
    c = blade_clock_angles(turbine)
    return float(np.min(np.minimum(c, 360.0 - c)))


def sector(angle: ArrayLike) -> IntArray:
    """The quarter (0-3) an angle [rad] falls in: 0 within 45 deg of 0, 1 round 90 deg,
    2 round 180 deg, 3 round 270 deg."""
    a = np.asarray(angle, dtype=np.float64)
    return (np.floor((a + 0.25 * math.pi) / (0.5 * math.pi)).astype(np.int64)) % 4


class TurbineSurface:
    """The fitted turbine's solid (:class:`SurfaceShape` round ``model_points``), with named
    blades, side classification and ray casting (see the module docstring).

    Attributes:
        turbine, geometry, shape: what it was built from.
        blades: the three :class:`Blade` in the order A, B, C.
        base, top, hub: tower base, tower top and hub centre (3,) [m].
        shaft: unit shaft direction (tower top -> hub, upwind, tilted).
        tower_right: unit horizontal direction to the right of the heading seen from upwind.
    """

    def __init__(self, turbine: TurbineParams, geometry: TurbineGeometry = PAPER_GEOMETRY,
                 shape: SurfaceShape | None = None) -> None:
        self.turbine = turbine.canonical()
        self.geometry = geometry
        self.shape = shape or SurfaceShape()
        sh = self.shape
        p, _ = model_points(self.turbine.to_vector(), geometry)
        self.base, self.top, self.hub = p[0], p[1], p[2]
        w, tau = self.turbine.heading, geometry.shaft_tilt
        self.shaft = np.array([math.cos(w) * math.cos(tau), math.sin(w) * math.cos(tau),
                               math.sin(tau)])
        self.heading_dir = np.array([math.cos(w), math.sin(w), 0.0])
        self.tower_right = np.array([-math.sin(w), math.cos(w), 0.0])
        self.h = max(float(self.top[2] - self.base[2]), 1.0)
        self.b = max(self.turbine.blade_length, 0.5)
        clocks = blade_clock_angles(self.turbine)
        names = blade_names(self.turbine)
        cb, sb = math.cos(sh.blade_pitch), math.sin(sh.blade_pitch)
        blades = []
        for i in range(3):
            e = unit_vector(p[3 + i] - self.hub)
            le0 = unit_vector(np.cross(e, self.shaft))
            up = unit_vector(np.cross(le0, e))  # the shaft's part across the blade (upwind)
            blades.append(Blade(names[i], i, float(clocks[i]), self.hub.copy(), e,
                                float(np.linalg.norm(p[3 + i] - self.hub)),
                                cb * le0 + sb * up, cb * up - sb * le0))
        self.blades: tuple[Blade, ...] = tuple(sorted(blades, key=lambda bl: bl.name))
        solid = self.solid = TurbineSolid(self.turbine.to_vector(), geometry, sh.nacelle)
        self.up, self.side = solid.up, solid.side
        self.nacelle_centre, self.nacelle_half = solid.nac_centre, solid.nac_half
        self.spinner_centre = solid.spin_centre
        self.spinner_radii = np.array([solid.spin_len, solid.spin_r, solid.spin_r])

    # -- sections ------------------------------------------------------------------------
    def tower_radius(self, z: ArrayLike) -> FloatArray:
        """Tower radius [m] at heights ``z`` above its base."""
        u = np.clip(np.asarray(z, dtype=np.float64) / self.h, 0.0, 1.0)
        return self.solid.r0 + (self.solid.r1 - self.solid.r0) * u

    def blade_section(self, span: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Half chord and half thickness [m] at ``span`` metres from the hub
        (:func:`~turbinefit.turbine.solid.blade_profile`)."""
        u = np.asarray(span, dtype=np.float32) / np.float32(self.b)
        A, B = blade_profile(u, self.b)
        return A.astype(np.float64), B.astype(np.float64)

    def twist(self, span: ArrayLike) -> FloatArray:
        """The blades' twist [rad] at ``span`` metres from the hub (added to the pitch)."""
        u = np.asarray(span, dtype=np.float32) / np.float32(self.b)
        return self.shape.blade_twist * twist_fraction(u).astype(np.float64)

    def blade_side(self, blade: int, to_camera: FloatArray, span: ArrayLike = 0.0) -> IntArray:
        """Index into :data:`BLADE_SIDES` of the side seen along directions ``to_camera``
        (..., 3) (from the blade towards the camera) on blade ``blade`` (0 = A) at ``span``
        metres from the hub (which matters only with a twist)."""
        bl = self.blades[blade]
        angle = np.arctan2(to_camera @ bl.normal, to_camera @ bl.chord)
        return sector(angle - self.twist(span) if self.shape.blade_twist else angle)

    def chord_position(self, blade: int, world_p: ArrayLike) -> FloatArray:
        """Where points ``world_p`` (..., 3) [m] on blade ``blade`` (0 = A) lie along their
        section's chord line: -1 at the trailing edge, 0 mid-chord, 1 at the leading edge
        (the projection on the chord, pitch and twist included, over the half chord;
        clipped to [-1, 1])."""
        bl = self.blades[blade]
        v = np.asarray(world_p, dtype=np.float64) - bl.root
        s = v @ bl.axis
        tw = self.twist(s)
        along = np.cos(tw) * (v @ bl.chord) + np.sin(tw) * (v @ bl.normal)
        A, _ = self.blade_section(s)
        return np.clip(along / np.maximum(A, 1e-9), -1.0, 1.0)

    def tower_face(self, to_camera: FloatArray) -> IntArray:
        """Index into :data:`TOWER_FACES` of the tower face seen along ``to_camera`` (..., 3)."""
        return sector(np.arctan2(to_camera @ self.tower_right, to_camera @ self.heading_dir))

    def max_radius(self) -> float:
        """The largest distance [m] of the solid from the rotor's or tower's axis."""
        return float(max(self.solid.r0, self.max_half_chord(), self.solid.spin_r))

    def max_half_chord(self) -> float:
        """Half the blades' widest chord [m]."""
        return 0.5 * BLADE_MAX_CHORD * self.b

    # -- ray casting ---------------------------------------------------------------------
    def _tube(self, o: FloatArray, d: FloatArray, a: FloatArray, e: FloatArray, L: float,
              blade: Blade | None, pixel: float) -> tuple[FloatArray, FloatArray]:
        """Entry distance along rays ``o + t d`` (N, 3) into the tube round ``a + s e``,
        s in [0, L] (inf: missed), and the entry point's axis coordinate s."""
        w = o - a
        b_ = d @ e
        dw = np.einsum("ij,ij->i", d, w)
        ew = w @ e
        den = np.maximum(1.0 - b_ * b_, 1e-9)
        s = (ew - b_ * dw) / den
        t = (b_ * ew - dw) / den
        lat = w + t[:, None] * d - s[:, None] * e
        x2 = np.einsum("ij,ij->i", lat, lat)
        if blade is None:
            A = B = self.tower_radius(s)
            hw = A
            chord = A
            beyond = np.zeros_like(s)  # flat tower ends
        else:
            A, B = self.blade_section(s)
            isq = 1.0 / np.sqrt(den)
            mc0, mn0 = d @ blade.chord, d @ blade.normal
            tw = self.twist(s)
            ct, st = np.cos(tw), np.sin(tw)
            mc = (ct * mc0 + st * mn0) * isq
            mn = (ct * mn0 - st * mc0) * isq
            hw = np.sqrt((mc * B) ** 2 + (mn * A) ** 2)
            chord = A * B / np.maximum(hw, 1e-12)  # half the section's chord along the ray
            beyond = np.maximum(s - L, 0.0) * np.sqrt(den)  # round tip
        # a part thinner than a pixel shows in the pixels its axis crosses
        hw = np.maximum(hw, 0.5 * pixel * np.maximum(t, 0.0))
        hit = (x2 + beyond * beyond <= hw * hw) & (s >= 0.0) & (t > 0.0)
        hit &= s <= (L if blade is None else L + hw / np.sqrt(den))
        depth = t - chord * np.sqrt(np.maximum(1.0 - x2 / np.maximum(hw * hw, 1e-24), 0.0)) \
            / np.sqrt(den)
        s_entry = np.clip(s + (depth - t) * b_, 0.0, L)  # axis coordinate of the entry point
        return np.where(hit & (depth > 0.0), depth, np.inf), s_entry

    def _spinner(self, o: FloatArray, d: FloatArray) -> FloatArray:
        E = np.stack([self.shaft, self.side, self.up]) / self.spinner_radii[:, None]
        op = (o - self.spinner_centre) @ E.T
        dp = d @ E.T
        a = np.einsum("ij,ij->i", dp, dp)
        b = np.einsum("ij,ij->i", op, dp)
        c = np.einsum("ij,ij->i", op, op) - 1.0
        disc = b * b - a * c
        t = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
        return np.where((disc >= 0.0) & (t > 0.0), t, np.inf)

    def _nacelle(self, o: FloatArray, d: FloatArray) -> FloatArray:
        E = np.stack([self.shaft, self.side, self.up])
        oc = (o - self.nacelle_centre) @ E.T
        dl = d @ E.T
        dl = np.where(np.abs(dl) < 1e-12, 1e-12, dl)
        t1 = (-self.nacelle_half - oc) / dl
        t2 = (self.nacelle_half - oc) / dl
        tn = np.minimum(t1, t2).max(axis=1)
        tf = np.maximum(t1, t2).min(axis=1)
        return np.where((tn <= tf) & (tn > 0.0), tn, np.inf)

    def cast_rays(self, origins: ArrayLike, directions: ArrayLike, pixel: float = 0.0
                  ) -> RayHits:
        """The nearest part each ray meets (world rays ``origins + t directions``, (N, 3),
        directions of unit length). ``pixel``: the angle of a pixel [rad] (1 / focal length
        in pixels) when the rays are a photo's: a blade or tower thinner than a pixel is
        then met within half a pixel of its axis, as a photo shows it."""
        o = np.broadcast_to(np.asarray(origins, dtype=np.float64), np.shape(directions))
        o = o.reshape(-1, 3)
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        n = d.shape[0]
        depth = np.full((6, n), np.inf)
        spans = np.full((6, n), np.nan)
        for i, bl in enumerate(self.blades):
            depth[i], spans[i] = self._tube(o, d, bl.root, bl.axis, bl.length, bl, pixel)
        depth[TOWER], s = self._tube(o, d, self.base, np.array([0.0, 0.0, 1.0]), self.h, None,
                                     pixel)
        spans[TOWER] = s + self.base[2]
        depth[NACELLE] = self._nacelle(o, d)
        depth[HUB] = self._spinner(o, d)
        part = np.argmin(depth, axis=0)
        best = depth[part, np.arange(n)]
        hit = np.isfinite(best)
        part = np.where(hit, part, -1)
        span = np.where(hit & (part <= TOWER), spans[np.maximum(part, 0), np.arange(n)], np.nan)
        side = np.full(n, -1, dtype=np.int64)
        to_cam = -d
        for i in range(3):
            m = part == i
            if np.any(m):
                side[m] = self.blade_side(i, to_cam[m], spans[i, m])
        m = part == TOWER
        if np.any(m):
            side[m] = self.tower_face(to_cam[m])
        return RayHits(part.astype(np.int64), span, side, np.where(hit, best, np.nan))


@dataclass
class RayHits:
    """What rays meet (:meth:`TurbineSurface.cast_rays`), per ray.

    Attributes:
        part: index into :data:`PARTS`, -1 for nothing.
        span: blade span [m from the hub centre] or tower height [m above the ground]
            of the hit (NaN on the nacelle, the hub or nothing).
        side: index into :data:`BLADE_SIDES` on a blade, :data:`TOWER_FACES` on the
            tower, else -1.
        distance: distance along the ray [m] (NaN: nothing).
    """

    part: IntArray
    span: FloatArray
    side: IntArray
    distance: FloatArray


@dataclass(frozen=True)
class PixelHit:
    """Where one pixel's ray meets the turbine (:func:`lookup_pixel`).

    Attributes:
        part: ``blade_A``, ``blade_B``, ``blade_C``, ``tower``, ``nacelle`` or ``hub``.
        blade: ``A``, ``B``, ``C`` on a blade, else None.
        span_m: metres from the hub centre along the blade, or above the ground on the
            tower (None on the nacelle and hub).
        side: one of :data:`BLADE_SIDES` on a blade, :data:`TOWER_FACES` on the tower,
            else None.
        distance_m: camera to the hit [m].
        world_point: the hit (3,) [m, world].
    """

    part: str
    blade: str | None
    span_m: float | None
    side: str | None
    distance_m: float
    world_point: tuple[float, float, float]


def lookup_pixel(surface: TurbineSurface, camera: PinholeCamera, world_T_cam: SE3,
                 u: float, v: float) -> PixelHit | None:
    """Which part, span and side of the turbine pixel ``(u, v)`` of the photo taken from
    ``world_T_cam`` shows (None: none). ``camera`` is the photo's (its size and
    distortion); pixel (0, 0) is the centre of the top-left pixel."""
    hits, points = lookup_pixels(surface, camera, world_T_cam, np.array([[u, v]], float))
    k = int(hits.part[0])
    if k < 0:
        return None
    name = PARTS[k]
    span = None if k > TOWER else float(hits.span[0])
    side = None
    if k < TOWER:
        side = BLADE_SIDES[int(hits.side[0])]
    elif k == TOWER:
        side = TOWER_FACES[int(hits.side[0])]
    x, y, z = (float(c) for c in points[0])
    return PixelHit(name, name[-1] if k < TOWER else None, span, side,
                    float(hits.distance[0]), (x, y, z))


def lookup_pixels(surface: TurbineSurface, camera: PinholeCamera, world_T_cam: SE3,
                  uv: ArrayLike) -> tuple[RayHits, FloatArray]:
    """:func:`lookup_pixel` of many pixels ``uv`` (N, 2) of one photo, as arrays: the
    :class:`RayHits` and the world points hit (N, 3) (NaN where nothing is)."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    rays = normalized_rays(camera, uv) @ world_T_cam.rotation_matrix().T
    origin = world_T_cam.translation
    hits = surface.cast_rays(origin[None, :], rays, 1.0 / math.sqrt(camera.fx * camera.fy))
    return hits, origin + hits.distance[:, None] * rays


@dataclass(frozen=True)
class BoxLocation:
    """Where a box drawn on a photo (a damage mark) lies on the turbine (:func:`locate_box`).

    Attributes:
        part: the part most of the box's sample pixels show (``blade_A`` ... ``hub``), or
            None if none shows the turbine.
        side: the side or face most of that part's samples show (None on nacelle and hub).
        span_m: median span of that part's samples [m from the hub centre, or above the
            ground]; span_from_m, span_to_m: their least and greatest (None on nacelle,
            hub).
        distance_m: median camera distance of those samples [m].
        on_part: fraction of the box's samples on that part (the rest: other parts or
            background).
        chord: on a blade, the median position of those samples along the chord line
            (:meth:`TurbineSurface.chord_position`: -1 trailing edge .. 1 leading edge);
            else None.
        world_p: the surface point [m, world] of that part's sample at the median span (at
            the median distance on the nacelle and hub), or None.
    """

    part: str | None
    side: str | None
    span_m: float | None
    span_from_m: float | None
    span_to_m: float | None
    distance_m: float | None
    on_part: float
    chord: float | None = None
    world_p: tuple[float, float, float] | None = None


#: Sample pixels a side of a box in :func:`locate_box` (at most; one per pixel).
BOX_SAMPLES = 9


def locate_box(surface: TurbineSurface, camera: PinholeCamera, world_T_cam: SE3,
               box: tuple[float, float, float, float]) -> BoxLocation:
    """The part, side and span range a box (left, top, right, bottom; pixel edges, as
    labelling tools draw them) on the photo taken from ``world_T_cam`` covers: a grid of up
    to :data:`BOX_SAMPLES` x :data:`BOX_SAMPLES` pixel centres inside it looked up
    (:func:`lookup_pixels`), the part most of them hit, and that part's samples' side (the
    most frequent), median span, span range, distance and, on a blade, chord position."""
    x0, y0, x1, y1 = box
    nu = max(1, min(BOX_SAMPLES, math.ceil(x1 - x0)))
    nv = max(1, min(BOX_SAMPLES, math.ceil(y1 - y0)))
    us = x0 + (np.arange(nu) + 0.5) * (x1 - x0) / nu - 0.5  # pixel centres: edges - 0.5
    vs = y0 + (np.arange(nv) + 0.5) * (y1 - y0) / nv - 0.5
    uv = np.stack(np.meshgrid(us, vs), -1).reshape(-1, 2)
    hits, points = lookup_pixels(surface, camera, world_T_cam, uv)
    seen = hits.part[hits.part >= 0]
    if seen.size == 0:
        return BoxLocation(None, None, None, None, None, None, 0.0)
    k = int(np.bincount(seen).argmax())
    on = hits.part == k
    side = None
    if k <= TOWER:
        names = BLADE_SIDES if k < TOWER else TOWER_FACES
        side = names[int(np.bincount(hits.side[on]).argmax())]
    spans = hits.span[on]
    has_span = k <= TOWER
    chord = None
    if k < TOWER:
        chord = float(np.median(surface.chord_position(k, points[on])))
    key = spans if has_span else hits.distance[on]
    p = points[on][int(np.argmin(np.abs(key - np.median(key))))]
    return BoxLocation(PARTS[k], side,
                       float(np.median(spans)) if has_span else None,
                       float(spans.min()) if has_span else None,
                       float(spans.max()) if has_span else None,
                       float(np.median(hits.distance[on])), float(on.mean()), chord,
                       (float(p[0]), float(p[1]), float(p[2])))
