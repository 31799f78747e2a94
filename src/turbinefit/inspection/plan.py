"""Camera waypoints that cover each blade's four sides and the tower at a stand-off, ordered
into one path that keeps clear of the rotor (the turbine stopped at its fitted blade
rotation).

**Stations.** Each side of each blade (:data:`~turbinefit.inspection.surface.BLADE_SIDES`)
and each face of the tower is photographed from stations along its span: the camera
looks across the part's axis, straight at the side (along the side's normal, turned with
the section's pitch and twist; the blade flat in the rotor plane unless they are given),
from ``standoff`` metres off the modelled surface. Stations are spaced so that
neighbouring photos share ``overlap`` of the footprint along the part (the image's short
side, at the stand-off), from the spinner's edge (the ground) to the tip (the nacelle).
Where the straight view is blocked or would bring the camera within the stand-off of the
rotor (the hub and the other blades), or beyond the gimbal's upward pitch, the view turns
about the part's axis by up to 40 deg (still inside the side's 90 deg sector; the centre
ray must meet the part on that side); a station no turn clears is left out and counted.
A stand-off at which more than half the stations of a blade side are blocked by the
rotor "meets the rotor" (an error).

**Views added (the root).** Near the hub the straight views come within the stand-off of
the spinner, the other blades or (downwind) the nacelle and tower, so the root, 3-8 m
from the hub, would go unseen. The stations' photos are judged as the coverage judges
them (:func:`~turbinefit.inspection.coverage.sample_views` on samples along each blade
side): where a side's samples are not shown at the resolution asked for (without one,
:data:`FILL_GSD_FACTOR` times the stand-off's), views aimed at them are added greedily,
each the one showing most of what is left (the nearest of equals): turned about the
blade's axis, tilted along it (a camera further out looking back at the root, or nearer
the hub looking out) and from the stand-off out to the distance of that resolution
(:class:`_Filler`), each keeping the same clearances and gimbal pitch, its centre ray
meeting the side. With the gimbal limited they also see part of a blade's lower edge
that no straight view within the gimbal's pitch shows. ``Plan.covered`` is the share of
each blade side the photos planned show.

**Clearance.** The camera keeps ``standoff`` from every blade and the spinner along the
whole path, and ``tower_clearance`` (a quarter of the stand-off, at least
:data:`MIN_TOWER_CLEARANCE`, unless given) from the tower and the nacelle (which the
suction sides' stations need to come near), and stays above ``min_altitude``; the
planner's own distances (closed-form bounds per shape, checked every quarter metre) keep
:func:`check_margin` more, and the finished path is checked by :func:`check_plan` with
the independent distances of :mod:`turbinefit.inspection.clearance` (a plan failing it
is refused). Consecutive waypoints are joined by the shortest clear route of: straight,
round the blade (two stations of one blade), round the tower (two of the tower), through
transit planes parallel to the rotor (one upwind of the spinner, one downwind of the
nacelle), crossing between them through the gap between blades that points highest;
each also from points backed away from the stations against their views
(:data:`BACK_OFF`: leaving a station just at the stand-off from a pitched blade along
the shaft first comes nearer its edge). A station no clear route reaches is left out
and counted.

**Order.** Upwind first (for each blade A, B, C: leading edge, pressure side, trailing
edge), then downwind (each blade's suction side), then the tower's faces (back, left,
front, right), each sweep (its stations in the order of the camera's position along the
part) run in the direction that starts nearest the end of the previous one.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import world_T_cam_from_angles
from turbinefit.inspection.clearance import (
    LEG_STEP,
    ROTOR,
    STRUCTURE,
    PathClearance,
    SolidSamples,
    path_clearance,
    solid_samples,
)
from turbinefit.inspection.coverage import part_samples, sample_views
from turbinefit.inspection.surface import (
    BLADE_SIDES,
    PARTS,
    TOWER,
    FloatArray,
    IntArray,
    TurbineSurface,
)

#: Turns of the view about the part's axis tried at a station, in order [deg].
TURNS_DEG = (0.0, 15.0, -15.0, 30.0, -30.0, 40.0, -40.0)
#: Views added where the stations leave a blade side uncovered (:class:`_Filler`): turns
#: about the blade's axis [deg], tilts along it [deg] (positive: the camera further out
#: than the span it looks at), distances tried between the stand-off and the resolution's
#: (evenly), samples aimed at per round, rounds, the most views added per side, and the
#: sample spacing along the blade [m].
FILL_TURNS_DEG = (0.0, 15.0, -15.0, 30.0, -30.0, 40.0, -40.0)
FILL_TILTS_DEG = (0.0, 10.0, -10.0, 20.0, -20.0, 30.0, -30.0, 40.0, 50.0)
FILL_DISTANCES = 4
FILL_TARGETS = 10
FILL_ROUNDS = 2
FILL_MAX = 12
FILL_STEP = 0.25
#: Without a resolution asked for, the added views keep within this factor of the
#: resolution at the stand-off.
FILL_GSD_FACTOR = 1.25
#: Sides in the order they are flown (indices into BLADE_SIDES) upwind, then downwind.
UPWIND_SIDES = (0, 1, 2)
DOWNWIND_SIDES = (3,)
#: Tower faces in the order they are flown (indices into TOWER_FACES).
TOWER_ORDER = (2, 3, 0, 1)
#: How fast the blades' sections grow along the span at most (metres of half chord per
#: metre of span, :func:`~turbinefit.turbine.solid.blade_profile`: 0.14 at the root's
#: ramp), for the planner's distances from a blade.
SECTION_SLOPE = 0.15
#: The least stand-off a plan should be asked for [m] (``plan --standoff``; see
#: ``docs/inspection.md``): a drone's radius with its propellers (0.4 m, a DJI Matrice
#: 30), its hovering error without RTK (1.5 m horizontally, DJI's figure) and the model's
#: error at the blades (1.1 m: the fitted blades' points to 0.5 m, and the flat section
#: against a real blade's, twisted 14 deg at the root: its edge 0.01 blade lengths off).
MIN_STANDOFF = 3.0
#: The least distance between a transit point and its neighbours [m]: DJI's waypoint
#: missions (Litchi's) take waypoints at least 0.5 m apart.
MIN_LEG = 0.5
#: How far [m] the router steps out of a station (back against its view, along its part
#: or round it) when no route from the station itself clears: a station just at the
#: stand-off from a blade and the clearance from the tower, or from a pitched blade, where
#: any leg straight to a transit plane first comes nearer one of them.
BACK_OFF = (1.0, 3.0)
#: The largest turn [deg] about a blade's axis between the transit points of a route
#: round the blade.
ARC_STEP_DEG = 20.0
#: The least tower clearance [m] (``plan --tower-clearance``, and the default's floor):
#: the drone's radius and hovering error; the tower and the nacelle are modelled better
#: than the blades.
MIN_TOWER_CLEARANCE = 2.0


class PlanError(ValueError):
    """A plan that cannot be made: the stand-off meets the rotor, or the camera cannot reach
    the resolution asked for at it; ``option`` names the option at fault (``standoff``,
    ``max_gsd_mm``, ``overlap``)."""

    def __init__(self, message: str, option: str) -> None:
        super().__init__(message)
        self.option = option


@dataclass(frozen=True)
class PlanOptions:
    """What the plan must achieve.

    Attributes:
        standoff: camera to the surface of the part photographed [m].
        max_gsd_mm: the resolution asked for [mm/px], or None (what the camera gives).
        overlap: fraction of the footprint neighbouring photos share (0-0.9).
        max_gimbal_up_deg: the gimbal's largest upward pitch [deg] (90: no limit).
        min_altitude: lowest camera height above the ground [m].
        tower_clearance: least distance from the tower and the nacelle [m] (None: a quarter
            of the stand-off).
        position_margin: how far [m] the drone may be from a waypoint, in any direction,
            when it takes the photo (its navigation's error relative to the turbine: 1.5-3
            m on GNSS alone, centimetres with RTK). The views added where the stations
            leave a side unseen must show it from anywhere within this margin, and a side
            the stations show only from their exact poses gets views added too (0: the
            waypoints are flown exactly).
    """

    standoff: float
    max_gsd_mm: float | None = None
    overlap: float = 0.3
    max_gimbal_up_deg: float = 90.0
    min_altitude: float = 2.0
    tower_clearance: float | None = None
    position_margin: float = 0.0


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


@dataclass
class Plan:
    """A path round the turbine (:func:`plan_path`).

    Attributes:
        waypoints: in flying order, photo stations and transit points.
        gsd_mm: the resolution at the stand-off [mm/px].
        skipped: per (part, side) the stations no view could clear.
        stations: per (part, side) the stations planned (photos).
        beyond_gimbal: per (part, side) the stations left out because every view of them
            looks up more steeply than the gimbal can (part of ``skipped``).
        fill: per blade side the stations added where the others leave it uncovered (the
            root; part of ``stations``).
        covered: per blade side the share of its span the photos planned show at
            ``goal_mm`` or finer (the coverage's rules on the surface planned for, samples
            every :data:`FILL_STEP` m).
        goal_mm: the resolution the added stations keep [mm/px]: the one asked for, else
            :data:`FILL_GSD_FACTOR` times ``gsd_mm``.
        min_rotor_clearance: least distance of the path (waypoints and legs) from the
            blades and the spinner [m], from :func:`check_plan` (a lower bound).
        min_tower_clearance: the same from the tower and the nacelle [m].
        check_s: seconds :func:`check_plan` took.
    """

    waypoints: list[Waypoint]
    gsd_mm: float
    skipped: dict[tuple[int, int], int] = field(default_factory=dict)
    stations: dict[tuple[int, int], int] = field(default_factory=dict)
    beyond_gimbal: dict[tuple[int, int], int] = field(default_factory=dict)
    fill: dict[tuple[int, int], int] = field(default_factory=dict)
    covered: dict[tuple[int, int], float] = field(default_factory=dict)
    goal_mm: float = math.nan
    min_rotor_clearance: float = math.inf
    min_tower_clearance: float = math.inf
    check_s: float = 0.0

    @property
    def length_m(self) -> float:
        return _length(np.array([w.position for w in self.waypoints]).reshape(-1, 3))

    @property
    def photos(self) -> list[Waypoint]:
        return [w for w in self.waypoints if w.photo]


def _rotate(v: FloatArray, axis: FloatArray, angle: float) -> FloatArray:
    """v rotated about unit ``axis`` by ``angle`` (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * float(axis @ v) * (1.0 - c)


class _Clearance:
    """Distances of points from the rotor (blades, spinner) and from the tower and nacelle."""

    def __init__(self, surface: TurbineSurface) -> None:
        self.s = surface

    def blade(self, p: FloatArray, i: int) -> FloatArray:
        """Distance from blade ``i``: from the section's support along the direction
        across the axis, the section the widest within ``SECTION_SLOPE`` times the
        distance along the span (the nearest point of a section that grows along the
        span lies off the point's own span)."""
        s, bl = self.s, self.s.blades[i]
        w = p - bl.root
        along = w @ bl.axis
        t = np.clip(along, 0.0, bl.length)
        perp = w - along[:, None] * bl.axis  # across the axis (beyond the tip too)
        r = np.linalg.norm(perp, axis=1)
        near = np.clip(t[:, None] + SECTION_SLOPE * r[:, None] * np.linspace(-1.0, 1.0, 5),
                       0.0, bl.length)
        A, B = (v.max(axis=1) for v in s.blade_section(near))
        tw = s.twist(t)
        chord = np.cos(tw)[:, None] * bl.chord + np.sin(tw)[:, None] * bl.normal
        normal = np.cos(tw)[:, None] * bl.normal - np.sin(tw)[:, None] * bl.chord
        cth = np.einsum("ij,ij->i", perp, chord) / np.maximum(r, 1e-12)
        sth = np.einsum("ij,ij->i", perp, normal) / np.maximum(r, 1e-12)
        ext = np.sqrt((A * cth) ** 2 + (B * sth) ** 2)
        axial = along - t
        return np.hypot(np.maximum(r - ext, 0.0), axial) - np.maximum(ext - r, 0.0)

    def rotor(self, p: FloatArray, skip: int = -1) -> FloatArray:
        s = self.s
        d = np.full(len(p), np.inf)
        for i in range(3):
            if i != skip:
                d = np.minimum(d, self.blade(p, i))
        spin = np.linalg.norm(p - s.spinner_centre, axis=1) - float(np.max(s.spinner_radii))
        return np.minimum(d, spin)

    def tower(self, p: FloatArray) -> FloatArray:
        s = self.s
        h = float(s.solid.tower_top_z - s.base[2])  # the tower reaches into the nacelle
        z = np.clip(p[:, 2] - s.base[2], 0.0, h)
        r = np.hypot(p[:, 0] - s.base[0], p[:, 1] - s.base[1]) - s.tower_radius(z)
        above = np.maximum(p[:, 2] - s.base[2] - h, 0.0)
        tower = np.hypot(np.maximum(r, 0.0), above) - np.maximum(-r, 0.0) * (above == 0)
        E = np.stack([s.shaft, s.side, s.up])
        q = np.abs((p - s.nacelle_centre) @ E.T) - s.nacelle_half
        box = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
        return np.minimum(tower, box)


class _Filler:
    """Views added where the stations' photos leave a blade side uncovered (see the module
    docstring): the samples of the side along the blade (every :data:`FILL_STEP` metres)
    that no photo shows at the resolution ``goal_mm`` [mm/px] or finer, as
    :func:`~turbinefit.inspection.coverage.sample_views` judges (the coverage's own rules:
    in the photo, the ray meeting the blade first, on that side), are covered greedily by
    views aimed at them from the stand-off out to the distance of that resolution, turned
    about the blade's axis (:data:`FILL_TURNS_DEG`) and tilted along it
    (:data:`FILL_TILTS_DEG`), each view keeping the planner's clearances and the gimbal's
    pitch, its centre showing the side.

    With a position margin ``margin`` [m], a view shows a sample only if it does from
    each of seven positions: its own and ``margin`` metres off it either way along the
    camera's three axes (a drone that flies its waypoints to within the margin). The
    greedy choice then prefers the views that show most that way, and only where none
    does falls back to what the view shows from its own position."""

    def __init__(self, s: TurbineSurface, camera: PinholeCamera, clear: _Clearance, dp: float,
                 tp: float, min_alt: float, max_up: float, goal_mm: float,
                 margin: float = 0.0) -> None:
        self.s, self.camera, self.clear = s, camera, clear
        self.dp, self.tp, self.min_alt, self.max_up = dp, tp, min_alt, max_up
        self.goal = goal_mm
        self.margin = margin
        self.depth = goal_mm * math.sqrt(camera.fx * camera.fy) / 1000.0
        self.samples = [part_samples(s, i, FILL_STEP) for i in range(3)]

    def _seen(self, position: FloatArray, yaw: FloatArray, pitch: FloatArray, i: int,
              pts: FloatArray, robust: bool = False) -> NDArray[np.bool_]:
        """(k, 4, m) whether each view (k) shows each sample ``pts`` (m, 3) of blade ``i``
        on each side at the resolution asked for; ``robust``: from every position within
        the margin (the class docstring)."""
        R = world_T_cam_from_angles(position, yaw, pitch, 0.0).rotation_matrix()
        R = R.reshape(-1, 3, 3)
        position = position.reshape(-1, 3)
        k = len(position)
        shifts = [np.zeros(3)]
        if robust and self.margin > 0.0:
            shifts += [sign * self.margin * e for e in np.eye(3) for sign in (1.0, -1.0)]
        # every shifted copy of every view at once: copy j of view v is row j * k + v
        Rs = np.concatenate([R] * len(shifts))
        ps = np.concatenate([position + np.einsum("kij,j->ki", R, d) for d in shifts])
        kk, mm, side, _, g = sample_views(self.s, self.camera, Rs, ps, i, pts)
        out = np.zeros((len(shifts), k, 4, len(pts)), dtype=bool)
        fine = g <= self.goal
        out[kk[fine] // k, kk[fine] % k, side[fine], mm[fine]] = True
        return np.asarray(out.all(axis=0), dtype=bool)

    def covered(self, photos: list[Waypoint], i: int, robust: bool = False
                ) -> NDArray[np.bool_]:
        """(4, m) the samples of blade ``i``'s sides ``photos`` show (``robust``: from
        anywhere within the margin)."""
        pts = self.samples[i][1]
        if not photos:
            return np.zeros((4, len(pts)), dtype=bool)
        p = np.array([w.position for w in photos])
        yaw, pitch = np.array([w.yaw for w in photos]), np.array([w.pitch for w in photos])
        seen = self._seen(p, yaw, pitch, i, pts)
        if robust and self.margin > 0.0:  # judged again from within the margin: the views
            some = np.flatnonzero(seen.any(axis=(1, 2)))  # that show any of the blade
            seen = self._seen(p[some], yaw[some], pitch[some], i, pts, robust=True)
        return np.asarray(seen.any(axis=0), dtype=bool)

    def _candidates(self, i: int, side: int, targets: IntArray
                    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """The views aimed at samples ``targets`` that keep the clearances and the gimbal's
        pitch and whose centre shows the side: positions (k, 3), yaws, pitches, spans aimed
        at and distances (k,)."""
        s, bl = self.s, self.s.blades[i]
        spans, pts = self.samples[i][0][targets], self.samples[i][1][targets]
        A, B = s.blade_section(spans)
        tw = s.twist(spans)[:, None]
        chord = np.cos(tw) * bl.chord + np.sin(tw) * bl.normal
        normal = np.cos(tw) * bl.normal - np.sin(tw) * bl.chord
        n = [chord, normal, -chord, -normal][side]  # (t, 3), across the axis
        turn = np.radians(FILL_TURNS_DEG)[None, :, None]
        o = np.cos(turn) * n[:, None] + np.sin(turn) * np.cross(bl.axis, n)[:, None]
        ext = np.hypot(A[:, None] * np.einsum("tuj,tj->tu", o, chord),
                       B[:, None] * np.einsum("tuj,tj->tu", o, normal))
        tilt = np.radians(FILL_TILTS_DEG)[None, None, :, None]
        u = np.cos(tilt) * o[:, :, None] + np.sin(tilt) * bl.axis  # (t, u, v, 3)
        lo = self.dp + ext
        hi = np.maximum(lo, self.depth + ext)
        q = np.linspace(0.0, 1.0, FILL_DISTANCES)
        r = lo[..., None] + (hi - lo)[..., None] * q  # (t, u, d)
        shape = (len(spans), len(FILL_TURNS_DEG), len(FILL_TILTS_DEG), FILL_DISTANCES)
        r4 = np.broadcast_to(r[:, :, None, :], shape)
        c = pts[:, None, None, None] + r4[..., None] * u[:, :, :, None]
        view = -np.broadcast_to(u[:, :, :, None], c.shape)
        c, view, r4 = c.reshape(-1, 3), view.reshape(-1, 3), r4.reshape(-1)
        span = np.broadcast_to(spans[:, None, None, None], shape).reshape(-1)
        pitch = np.arcsin(np.clip(view[:, 2], -1.0, 1.0))
        ok = (pitch <= self.max_up) & (c[:, 2] >= self.min_alt)
        ok[ok] = (self.clear.rotor(c[ok]) >= self.dp) & (self.clear.tower(c[ok]) >= self.tp)
        if np.any(ok):
            hits = s.cast_rays(c[ok], view[ok])
            ok[ok] = (hits.part == i) & (hits.side == side)
        yaw = np.arctan2(view[ok, 1], view[ok, 0])
        return c[ok], yaw, pitch[ok], span[ok], r4[ok]

    def fill(self, i: int, side: int, covered: NDArray[np.bool_]) -> list[Waypoint]:
        """The views added to cover side ``side`` of blade ``i`` where ``covered`` (4, m)
        says no photo does (see the class docstring)."""
        pts = self.samples[i][1]
        todo = ~covered[side]
        tried = np.zeros(len(pts), dtype=bool)
        added: list[Waypoint] = []
        for _ in range(FILL_ROUNDS):
            idx = np.flatnonzero(todo & ~tried)
            if idx.size == 0:
                break
            targets = idx[np.unique(np.round(np.linspace(0, idx.size - 1,
                                                         min(idx.size, FILL_TARGETS))).astype(int))]
            tried[targets] = True
            c, yaw, pitch, span, dist = self._candidates(i, side, targets)
            if not len(c):
                continue
            left = np.flatnonzero(todo)
            gain = self._seen(c, yaw, pitch, i, pts[left])[:, side]  # (k, m)
            if self.margin > 0.0:  # judged from within the margin: the views that show any
                sure = np.zeros_like(gain)
                some = np.flatnonzero(gain.any(axis=1))
                sure[some] = self._seen(c[some], yaw[some], pitch[some], i, pts[left],
                                        robust=True)[:, side]
            else:
                sure = gain
            while len(added) < FILL_MAX and gain.size:
                count, count_sure = gain.sum(axis=1), sure.sum(axis=1)
                # the view showing the most from anywhere within the margin, then from its
                # own position, of those the nearest
                k = int(np.lexsort((dist, -count, -count_sure))[0])
                if count[k] == 0:
                    break
                added.append(Waypoint(c[k].copy(), float(yaw[k]), float(pitch[k]), i, side,
                                      float(span[k])))
                shown = (sure[k] if count_sure[k] else gain[k]).copy()
                todo[left[shown]] = False
                gain[:, shown] = False
                sure[:, shown] = False
        return added


def plan_path(surface: TurbineSurface, camera: PinholeCamera, options: PlanOptions,
              samples: SolidSamples | None = None, *,
              done: Callable[[int, int, float], bool] | None = None,
              start: ArrayLike | None = None) -> Plan:
    """Waypoints covering each blade's sides and the tower (see the module docstring),
    checked by :func:`check_plan` before they are returned. ``samples``: the surface's
    :func:`~turbinefit.inspection.clearance.solid_samples` to reuse (made if not given).

    Replanning in flight: ``done(part, side, span)`` says which stations were already
    photographed (they are left out, and not counted as skipped); ``start``, the camera's
    position now, is where the path starts (its first waypoint, a transit point, and the
    legs from it are routed and checked like any other).

    Raises:
        PlanError: the camera cannot reach ``options.max_gsd_mm`` at the stand-off, the
            stand-off meets the rotor (no clear view of a blade side at it), or the path
            fails its check.
    """
    opt = options
    d = float(opt.standoff)
    if not (d > 0 and math.isfinite(d)):
        raise PlanError(f"the stand-off must be a positive number of metres, got {d:g}",
                        "standoff")
    if not 0.0 <= opt.max_gimbal_up_deg <= 90.0:  # also nan
        raise PlanError(f"the gimbal's largest upward pitch must be between 0 and 90 deg, got "
                        f"{opt.max_gimbal_up_deg:g}", "max_gimbal_up_deg")
    samples = samples if samples is not None else solid_samples(surface)
    margin = check_margin(samples)
    dp = d + margin  # what the planner keeps, so that the check can vouch for d
    f = math.sqrt(camera.fx * camera.fy)
    gsd = 1000.0 * dp / f
    if opt.max_gsd_mm is not None and gsd > opt.max_gsd_mm * (1 + 1e-9):
        raise PlanError(
            f"the camera (focal length {f:.0f} px) reaches {gsd:.2f} mm/px at a stand-off of "
            f"{d:g} m (flown at {dp:.2f} m), coarser than {opt.max_gsd_mm:g} mm/px: come "
            f"within {opt.max_gsd_mm * f / 1000.0 - margin:.2f} m or use a longer lens (a "
            f"focal length of at least {1000.0 * dp / opt.max_gsd_mm:.0f} px)",
            "max_gsd_mm")
    if not 0.0 <= opt.overlap < 0.9:
        raise PlanError(f"overlap must be in [0, 0.9), got {opt.overlap:g}", "overlap")
    if not (math.isfinite(opt.position_margin) and 0.0 <= opt.position_margin <= d):
        raise PlanError(f"the position margin must be between 0 and the stand-off ({d:g} m), "
                        f"got {opt.position_margin:g}", "position_margin")
    s = surface
    if d >= s.b:
        raise PlanError(f"a stand-off of {d:g} m meets the rotor: it is not shorter than the "
                        f"blades ({s.b:.1f} m)", "standoff")
    clear = _Clearance(s)
    t_clear = tower_clearance(opt)
    if not 0.0 < t_clear <= d:
        raise PlanError(f"the tower clearance must be more than 0 and at most the stand-off "
                        f"({d:g} m), got {t_clear:g}", "tower_clearance")
    tp = t_clear + margin
    max_up = math.radians(opt.max_gimbal_up_deg)
    foot = min(camera.width, camera.height) * dp / f  # footprint along the part [m]
    step = max((1.0 - opt.overlap) * foot, 0.1)
    sweeps: dict[tuple[int, int], list[Waypoint]] = {}
    plan = Plan([], gsd)

    def station(part: int, side: int, span: float, centre: FloatArray, axis: FloatArray,
                normal: FloatArray, section: tuple[float, float, FloatArray, FloatArray]
                ) -> Waypoint | str:
        """The first view of ``TURNS_DEG`` that clears, else why none does (``gimbal``:
        every view looks up too steeply; ``clearance``); ``section``: half chord, half
        thickness, chord and thickness directions across the axis."""
        a, b, cdir, ndir = section
        why = "gimbal"
        for turn in TURNS_DEG:
            o = _rotate(normal, axis, math.radians(turn))
            ext = math.hypot(a * float(o @ cdir), b * float(o @ ndir))
            c = centre + (dp + ext) * o
            view = -o
            if math.asin(max(-1.0, min(1.0, view[2]))) > max_up:
                continue
            why = "clearance"
            if c[2] < opt.min_altitude:
                continue
            rot = clear.rotor(c[None], skip=part if part < 3 else -1)[0]
            if rot < dp or clear.tower(c[None])[0] < (tp if part < 3 else dp):
                continue
            hits = s.cast_rays(c[None], view[None])
            if int(hits.part[0]) != part or int(hits.side[0]) != side:
                continue
            return Waypoint(c, math.atan2(view[1], view[0]), math.asin(view[2]), part, side,
                            span)
        return why

    for i, bl in enumerate(s.blades):
        lo = float(s.spinner_radii[1])
        spans = _stations(lo, bl.length, foot, step)
        # the widest section within half a step (straight legs between stations stay
        # clear) and within the reach of the planner's distances (_Clearance.blade)
        reach = max(0.5 * step, SECTION_SLOPE * (dp + s.max_half_chord()))
        near = np.clip(spans[:, None] + reach * np.linspace(-1.0, 1.0, 9), 0.0, bl.length)
        A, B = (v.max(axis=1) for v in s.blade_section(near))
        tw = s.twist(spans)[:, None]
        chords = np.cos(tw) * bl.chord + np.sin(tw) * bl.normal
        normals = np.cos(tw) * bl.normal - np.sin(tw) * bl.chord
        for side in range(4):
            sw, blocked, steep = [], 0, 0
            for j, sp in enumerate(spans):
                # the side's normal turned with the section (twist)
                normal = [chords[j], normals[j], -chords[j], -normals[j]][side]
                w = station(i, side, float(sp), bl.root + sp * bl.axis, bl.axis, normal,
                            (float(A[j]), float(B[j]), chords[j], normals[j]))
                if isinstance(w, Waypoint):
                    sw.append(w)
                else:
                    blocked += w == "clearance"
                    steep += w == "gimbal"
            sweeps[(i, side)] = sw
            plan.stations[(i, side)] = len(sw)
            plan.skipped[(i, side)] = len(spans) - len(sw)
            plan.beyond_gimbal[(i, side)] = steep
            if blocked > 0.5 * len(spans):
                raise PlanError(
                    f"a stand-off of {d:g} m meets the rotor: only {len(sw)} of {len(spans)} "
                    f"views of blade {bl.name}'s {BLADE_SIDES[side].replace('_', ' ')} keep "
                    f"{d:g} m from the other blades and the hub", "standoff")
    top = float(s.nacelle_centre[2] - s.nacelle_half[2])
    heights = _stations(max(opt.min_altitude, float(s.base[2])), top, foot, step)
    zaxis = np.array([0.0, 0.0, 1.0])
    face_dirs = [s.heading_dir, s.tower_right, -s.heading_dir, -s.tower_right]
    for face in range(4):
        sw = []
        for z in heights:
            r = float(s.tower_radius(z - s.base[2]))
            centre = np.array([s.base[0], s.base[1], z])
            w = station(TOWER, face, float(z), centre, zaxis, face_dirs[face],
                        (r, r, s.heading_dir, s.tower_right))
            if isinstance(w, Waypoint):
                sw.append(w)
        sweeps[(TOWER, face)] = sw
        plan.stations[(TOWER, face)] = len(sw)
        plan.skipped[(TOWER, face)] = len(heights) - len(sw)

    goal = opt.max_gsd_mm if opt.max_gsd_mm is not None else FILL_GSD_FACTOR * gsd
    filler = _Filler(s, camera, clear, dp, tp, opt.min_altitude, max_up, goal,
                     opt.position_margin)
    robust = opt.position_margin > 0.0
    for i, bl in enumerate(s.blades):
        photos = [w for sw in sweeps.values() for w in sw]
        covered = filler.covered(photos, i, robust)
        for side in range(4):
            added = filler.fill(i, side, covered)
            if not added:
                continue
            covered |= filler.covered(added, i, robust)
            # flown in the order of the camera's position along the blade
            both = sweeps[(i, side)] + added
            along = [float((w.position - bl.root) @ bl.axis) for w in both]
            sweeps[(i, side)] = [both[j] for j in np.argsort(along, kind="stable")]
            plan.stations[(i, side)] += len(added)
            plan.fill[(i, side)] = len(added)
    if done is not None:
        for key, sw in sweeps.items():
            left = [w for w in sw if not done(w.part, w.side, w.span)]
            plan.stations[key] -= len(sw) - len(left)
            sweeps[key] = left
    order = [(i, k) for i in range(3) for k in UPWIND_SIDES]
    order += [(i, k) for i in range(3) for k in DOWNWIND_SIDES]
    order += [(TOWER, k) for k in TOWER_ORDER]
    router = _Router(s, clear, dp, tp, opt.min_altitude)
    path: list[Waypoint] = []
    if start is not None:
        p0 = np.asarray(start, dtype=np.float64).reshape(3)
        path.append(Waypoint(p0, math.atan2(float(s.hub[1] - p0[1]), float(s.hub[0] - p0[0])),
                             0.0))
    last: tuple[int, tuple[int, int]] | None = None  # the last station: its legs' start, key
    for key in order:
        sw = sweeps[key]
        if not sw:
            continue
        if path and np.linalg.norm(sw[-1].position - path[-1].position) < np.linalg.norm(
                sw[0].position - path[-1].position):
            sw = sw[::-1]
        for w in sw:
            begin = len(path)  # where the legs to w begin
            if path:
                legs = router.connect(path[-1], w)
                if legs is None and last is not None and last[0] > 0:
                    # the last station may be a dead end: leave it out if w can be
                    # reached from where the way to it began
                    legs = router.connect(path[last[0] - 1], w)
                    if legs is not None:
                        del path[last[0]:]
                        plan.stations[last[1]] -= 1
                        plan.skipped[last[1]] += 1
                        begin = len(path)
                if legs is None:  # no clear way there: the station is left out
                    plan.stations[key] -= 1
                    plan.skipped[key] += 1
                    continue
                path += legs
            path.append(w)
            last = (begin, key)
    plan.waypoints = path
    plan.goal_mm = goal
    for i in range(3):
        shown = filler.covered(plan.photos, i)
        for side in range(4):
            plan.covered[(i, side)] = float(np.mean(shown[side])) if shown.shape[1] else 0.0
    if not plan.photos and done is None:
        raise PlanError(f"no station has a clear view at a stand-off of {d:g} m within the "
                        f"gimbal's {opt.max_gimbal_up_deg:g} deg upward pitch", "max_gimbal_up_deg")
    t0 = time.perf_counter()
    check_plan(plan, surface, options, samples)
    plan.check_s = time.perf_counter() - t0
    return plan


def tower_clearance(options: PlanOptions) -> float:
    """The least distance [m] the plan keeps from the tower and the nacelle: the option's,
    else a quarter of the stand-off, at least :data:`MIN_TOWER_CLEARANCE` (and at most the
    stand-off)."""
    if options.tower_clearance is not None:
        return float(options.tower_clearance)
    d = float(options.standoff)
    return min(d, max(d / 4.0, MIN_TOWER_CLEARANCE))


def check_margin(samples: SolidSamples) -> float:
    """How much further [m] than promised the planner keeps, so that the check, whose
    distances along the legs are lower bounds at most ``samples.tolerance + LEG_STEP / 2``
    below the truth, can vouch for what it promises."""
    return samples.tolerance + 0.5 * LEG_STEP + 0.02


def check_plan(plan: Plan, surface: TurbineSurface, options: PlanOptions,
               samples: SolidSamples | None = None) -> PathClearance:
    """Check ``plan`` against ``options`` independently of the planner's own clearance
    arithmetic (:func:`~turbinefit.inspection.clearance.path_clearance`: every waypoint and
    every straight leg between them): the stand-off from the blades and the spinner, the
    tower clearance from the tower and the nacelle, the altitude, the gimbal's pitch, all
    finite. Sets ``plan.min_rotor_clearance`` and ``plan.min_tower_clearance`` (lower
    bounds) and returns the clearances.

    Raises:
        PlanError: naming the option at fault (``standoff``, ``tower_clearance``,
            ``max_gimbal_up_deg``, ``min_altitude``) and the numbers.
    """
    d, t_clear = float(options.standoff), tower_clearance(options)
    samples = samples if samples is not None else solid_samples(surface)
    w = plan.waypoints
    p = np.array([x.position for x in w], dtype=np.float64).reshape(-1, 3)
    pitch = np.array([x.pitch for x in w], dtype=np.float64)
    yaw = np.array([x.yaw for x in w], dtype=np.float64)
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(pitch)) and np.all(np.isfinite(yaw))):
        raise PlanError("the planned path has a waypoint that is not a finite number",
                        "standoff")
    up = np.degrees(pitch)
    bad = np.flatnonzero((up > options.max_gimbal_up_deg + 1e-6) | (up < -90.0 - 1e-6))
    if bad.size:
        i = int(bad[0])
        raise PlanError(f"waypoint {i} of the planned path has the gimbal pitched {up[i]:.2f} "
                        f"deg, beyond its range (-90 to {options.max_gimbal_up_deg:g} deg)",
                        "max_gimbal_up_deg")
    low = np.flatnonzero(p[:, 2] < options.min_altitude - 1e-6)
    if low.size:
        i = int(low[0])
        raise PlanError(f"waypoint {i} of the planned path is {p[i, 2]:.2f} m high, below "
                        f"the lowest altitude {options.min_altitude:g} m", "min_altitude")
    exact = np.array([d, d, d, t_clear, t_clear, d])
    check = path_clearance(p, samples, exact_below=exact)
    for parts, need, option, what in ((ROTOR, d, "standoff", "stand-off"),
                                      (STRUCTURE, t_clear, "tower_clearance",
                                       "tower clearance")):
        least, part, i, leg = check.least(parts)
        if parts == ROTOR:
            plan.min_rotor_clearance = least
        else:
            plan.min_tower_clearance = least
        if least < need:
            where = f"its leg from waypoint {i} to {i + 1}" if leg else f"waypoint {i}"
            raise PlanError(
                f"the planned path comes within {max(least, 0.0):.2f} m of the "
                f"{PARTS[part].replace('_', ' ')} at {where}, less than the {what} of "
                f"{need:g} m (checked on the path before writing it)", option)
    return check


def _stations(lo: float, hi: float, foot: float, step: float) -> FloatArray:
    """Evenly spaced stations from ``lo`` to ``hi`` (each end 0.4 footprints inside), at
    most ``step`` apart."""
    a, b = lo + 0.4 * foot, hi - 0.4 * foot
    if b <= a:
        return np.array([0.5 * (lo + hi)])
    n = math.ceil((b - a) / step) + 1
    return np.linspace(a, b, n)


def _drop_close(p: FloatArray, least: float = MIN_LEG) -> FloatArray:
    """The polyline ``p`` (n, 3) without the inner points closer than ``least`` to the
    point kept before them or to the last point (the ends are kept)."""
    kept = [p[0]]
    for q in p[1:-1]:
        if np.linalg.norm(q - kept[-1]) >= least and np.linalg.norm(q - p[-1]) >= least:
            kept.append(q)
    return np.stack([*kept, p[-1]])


def _densify(p: FloatArray, step: float = 0.5) -> FloatArray:
    """Points along the polyline ``p`` (n, 3) at most ``step`` apart."""
    if len(p) < 2:
        return p
    out = [p[:1]]
    for a, b in itertools.pairwise(p):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step))
        t = np.linspace(0.0, 1.0, n + 1)[1:, None]
        out.append(a + t * (b - a))
    return np.concatenate(out)


class _Router:
    """Legs between consecutive waypoints: straight if clear, else through the transit
    planes (see the module docstring)."""

    def __init__(self, s: TurbineSurface, clear: _Clearance, d: float, t_clear: float,
                 min_alt: float) -> None:
        self.s, self.clear, self.d, self.t, self.min_alt = s, clear, d, t_clear, min_alt
        spin_front = float(0.25 * s.spinner_radii[0] + s.spinner_radii[0])
        self.up_off = d + max(spin_front, s.max_half_chord()) + 1.0
        rear = float(np.linalg.norm(s.nacelle_centre - s.hub)) + float(s.nacelle_half[0])
        self.down_off = -(max(rear + t_clear, d + s.max_half_chord()) + 1.0)
        # crossing: through the gap between blades whose bisector points highest
        bis = []
        for i in range(3):
            a, b = s.blades[i].axis, s.blades[(i + 1) % 3].axis
            m = a + b
            if float(np.linalg.norm(m)) < 1e-9:
                continue
            bis.append(m / np.linalg.norm(m))
        gap = max(bis, key=lambda v: float(v[2])) if bis else s.up
        a_max = s.max_half_chord()
        radius = max((d + a_max) / math.sin(math.radians(60.0)),
                     d + float(np.max(s.spinner_radii))) + 1.0
        self.cross = s.hub + radius * gap

    def _clear(self, pts: FloatArray) -> bool:
        q = _densify(pts, 0.25)
        return bool(np.all(self.clear.rotor(q) >= self.d - 1e-6)
                    and np.all(self.clear.tower(q) >= self.t - 1e-6)
                    and np.all(q[:, 2] >= self.min_alt - 1e-6))

    def _offset(self, p: FloatArray) -> float:
        return float((p - self.s.hub) @ self.s.shaft)

    def _to_plane(self, p: FloatArray, off: float) -> FloatArray:
        return p + (off - self._offset(p)) * self.s.shaft

    def connect(self, a: Waypoint, b: Waypoint) -> list[Waypoint] | None:
        """Transit points from ``a`` to ``b`` (none: straight), or None if no route
        clears."""
        pa, pb = a.position, b.position
        if self._clear(np.stack([pa, pb])):
            return []
        both_tower = a.part == TOWER and b.part == TOWER
        blade = a.part if a.part == b.part and 0 <= a.part < 3 else -1
        ea, eb = self._exits(a), self._exits(b)
        # from the stations themselves, else first stepping out of where they are (a
        # station just at the stand-off from one part and the clearance from another)
        for ends in ([(pa, pb)],
                     [(q, pb) for q in ea] + [(pa, q) for q in eb]
                     + list(itertools.product(ea[:2], eb[:2]))):
            tries = []
            for qa, qb in ends:
                for r in self._routes(qa, qb, both_tower, blade):
                    pts = np.stack([pa, qa, *r, qb, pb])
                    pts[:, 2] = np.maximum(pts[:, 2], self.min_alt)
                    tries.append(_drop_close(pts))
            for pts in sorted(tries, key=_length):  # the shortest clear route
                if self._clear(pts):
                    return [self._transit(p, b) for p in pts[1:-1]]
        return None

    def _exits(self, w: Waypoint) -> list[FloatArray]:
        """Points :data:`BACK_OFF` metres from photo station ``w``: back against its view
        (first), either way along its part's axis and round it; those themselves clear."""
        if not w.photo:
            return []
        view = _view_dir(w)
        axis = self.s.blades[w.part].axis if w.part < 3 else np.array([0.0, 0.0, 1.0])
        across = np.cross(axis, view)
        n = float(np.linalg.norm(across))
        dirs = [-view, axis, -axis] + ([across / n, -across / n] if n > 1e-6 else [])
        q = np.array([w.position + back * v for v in dirs for back in BACK_OFF])
        ok = ((self.clear.rotor(q) >= self.d - 1e-6) & (self.clear.tower(q) >= self.t - 1e-6)
              & (q[:, 2] >= self.min_alt - 1e-6))
        return list(q[ok])

    @staticmethod
    def _transit(p: FloatArray, b: Waypoint) -> Waypoint:
        """A transit point at ``p`` looking level towards ``b``."""
        v = b.position - p
        yaw = math.atan2(v[1], v[0]) if float(np.linalg.norm(v)) > 1e-9 else b.yaw
        return Waypoint(np.asarray(p, dtype=np.float64), yaw, 0.0)

    def _routes(self, pa: FloatArray, pb: FloatArray, tower: bool, blade: int
                ) -> list[list[FloatArray]]:
        """Transit points between ``pa`` and ``pb`` to try: none (straight),
        round the blade (``blade``: both are stations of that blade, else -1), round the
        tower at the lower height (``tower``: both are tower stations), through the
        upwind or the downwind transit plane, across between them."""
        routes: list[list[FloatArray]] = [[]]
        if blade >= 0:
            routes.append(self._round_blade(pa, pb, blade))
        if tower:
            z = min(pa[2], pb[2])
            c = self.s.base[:2]
            ra, rb = pa[:2] - c, pb[:2] - c
            a0, a1 = math.atan2(ra[1], ra[0]), math.atan2(rb[1], rb[0])
            da = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
            rad = 0.5 * (float(np.linalg.norm(ra)) + float(np.linalg.norm(rb)))
            routes.append([np.array([c[0] + rad * math.cos(a0 + t * da),
                                     c[1] + rad * math.sin(a0 + t * da), z])
                           for t in np.linspace(0.0, 1.0, 7)])
        for plane in (self.up_off, self.down_off):
            routes.append([self._to_plane(pa, plane), self._to_plane(pb, plane)])
        for pa_plane, pb_plane in ((self.up_off, self.down_off), (self.down_off, self.up_off)):
            routes.append([self._to_plane(pa, pa_plane), self._to_plane(self.cross, pa_plane),
                           self._to_plane(self.cross, pb_plane), self._to_plane(pb, pb_plane)])
        return routes

    def _round_blade(self, pa: FloatArray, pb: FloatArray, blade: int) -> list[FloatArray]:
        """Points round blade ``blade``'s axis from ``pa``'s side of it to ``pb``'s, in the
        middle of turns of at most :data:`ARC_STEP_DEG`, far enough out that the legs
        between them keep the larger of the two distances from the axis (the legs from
        ``pa`` and to ``pb`` run along that circle's tangents; the span changes evenly):
        a straight leg between stations looking at the blade from directions a few
        degrees apart cuts inside their distance from it."""
        bl = self.s.blades[blade]
        wa, wb = pa - bl.root, pb - bl.root
        sa, sb = float(wa @ bl.axis), float(wb @ bl.axis)
        ua, ub = wa - sa * bl.axis, wb - sb * bl.axis
        ra, rb = float(np.linalg.norm(ua)), float(np.linalg.norm(ub))
        if min(ra, rb) < 1e-9:
            return []
        angle = math.atan2(float(bl.axis @ np.cross(ua, ub)), float(ua @ ub))
        n = max(1, math.ceil(abs(math.degrees(angle)) / ARC_STEP_DEG))
        radius = max(ra, rb) / math.cos(0.5 * angle / n)
        return [bl.root + (sa + t * (sb - sa)) * bl.axis
                + radius * _rotate(ua / ra, bl.axis, t * angle)
                for t in (np.arange(n) + 0.5) / n]


def _length(p: FloatArray) -> float:
    """Length of the polyline ``p`` (n, 3) [m]."""
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


def _view_dir(w: Waypoint) -> FloatArray:
    """Unit direction of ``w``'s view."""
    cp = math.cos(w.pitch)
    return np.array([cp * math.cos(w.yaw), cp * math.sin(w.yaw), math.sin(w.pitch)])


