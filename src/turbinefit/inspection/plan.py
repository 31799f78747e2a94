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
(:class:`Filler`), each keeping the same clearances and gimbal pitch, its centre ray
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

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.inspection.clearance import (
    LEG_STEP,
    ROTOR,
    STRUCTURE,
    PathClearance,
    SolidSamples,
    path_clearance,
    solid_samples,
)
from turbinefit.inspection.distances import SECTION_SLOPE, PlannerDistances
from turbinefit.inspection.fill import FILL_GSD_FACTOR, FILL_STEP, Filler
from turbinefit.inspection.route import MIN_LEG, Router
from turbinefit.inspection.surface import (
    BLADE_SIDES,
    PARTS,
    TOWER,
    FloatArray,
    TurbineSurface,
)
from turbinefit.inspection.waypoint import Waypoint, path_length, rotate

#: Re-exported: the plan's waypoints, the least leg between transit points and the
#: added views' sample spacing are part of what a plan promises.
__all__ = ["FILL_STEP", "MIN_LEG", "MIN_STANDOFF", "MIN_TOWER_CLEARANCE", "Plan",
           "PlanError", "PlanOptions", "Waypoint", "check_margin", "check_plan",
           "plan_path", "tower_clearance"]

#: Turns of the view about the part's axis tried at a station, in order [deg].
TURNS_DEG = (0.0, 15.0, -15.0, 30.0, -30.0, 40.0, -40.0)
#: Sides in the order they are flown (indices into BLADE_SIDES) upwind, then downwind.
UPWIND_SIDES = (0, 1, 2)
DOWNWIND_SIDES = (3,)
#: Tower faces in the order they are flown (indices into TOWER_FACES).
TOWER_ORDER = (2, 3, 0, 1)
#: The least stand-off a plan should be asked for [m] (``plan --standoff``; see
#: ``docs/inspection.md``): a drone's radius with its propellers (0.4 m, a DJI Matrice
#: 30), its hovering error without RTK (1.5 m horizontally, DJI's figure) and the model's
#: error at the blades (1.1 m: the fitted blades' points to 0.5 m, and the flat section
#: against a real blade's, twisted 14 deg at the root: its edge 0.01 blade lengths off).
MIN_STANDOFF = 3.0
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
        return path_length(np.array([w.position for w in self.waypoints]).reshape(-1, 3))

    @property
    def photos(self) -> list[Waypoint]:
        return [w for w in self.waypoints if w.photo]


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
    clear = PlannerDistances(s)
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
            o = rotate(normal, axis, math.radians(turn))
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
        # clear) and within the reach of the planner's distances (PlannerDistances.blade)
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
    filler = Filler(s, camera, clear, dp, tp, opt.min_altitude, max_up, goal,
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
    router = Router(s, clear, dp, tp, opt.min_altitude)
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



