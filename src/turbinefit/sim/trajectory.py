"""Ground-truth inspection flights: camera poses around a turbine.

World frame: metres, z up, ground z = 0. Poses are ``world_T_cam`` (camera-to-world) of
OpenCV cameras (x right, y down, z forward); angles in radians unless a name ends in
``_deg``.

The flight, in order (the phases of :data:`PHASES`):

1. ``approach`` - from far in front of the rotor (within +-45 deg of the heading), low,
   where the whole turbine is in view (~220 m), up to the orbit.
2. ``orbit`` - round the tower at hub height, ``orbit_standoff`` m outside the rotor
   disc, looking at the hub; at least half a turn, ending behind the turbine.
3. ``tower`` - down behind the tower, then up the tower at ``tower_standoff`` m from its
   axis, looking horizontally at the tower.
4. ``blades`` - each blade from root to tip on one side of the rotor plane, round the tip,
   and back to the root on the other side, at ``blade_standoff`` m, looking at the nearest
   point of the blade; between blades the drone turns round the hub on one side.
5. ``depart`` - out in front of the hub, looking back at it.

Close views therefore show only part of the turbine (a piece of tower or blade). The
camera's y axis points roughly down (no roll but ``roll_jitter_deg``); smooth random yaw and
pitch offsets (``look_jitter_deg``) keep the target off-centre.

The path is built as a dense polyline (``step`` m), smoothed, pushed out to
``min_clearance`` m from the turbine's skeleton (the five model lines) and above
``min_altitude``; keyframes are spread evenly along it, counting both distance flown and
view rotation (``rotation_weight`` m per radian). The dense path and its random offsets do
not depend on the number of keyframes: the same ``rng`` state gives the same flight path
for every N, sampled more or less densely.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from turbinefit.geometry.se3 import SE3, world_T_cam_from_angles
from turbinefit.turbine.model import (
    PAPER_GEOMETRY,
    TurbineGeometry,
    TurbineParams,
    model_points,
    skeleton_segments,
)

FloatArray = NDArray[np.float64]

#: Names of the flight phases, indexed by :attr:`InspectionPath.phase`.
PHASES = ("approach", "orbit", "tower", "blades", "depart")

_UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class TrajectoryConfig:
    """Shape of the simulated inspection flight.

    Attributes:
        approach_distance: minimum horizontal distance [m] of the start from the
            turbine's centre.
        approach_fov_deg: the start is also far enough for the whole turbine (the sphere
            round its six model points) to fit in a cone of this full angle [deg] round
            the line of sight to its centre (40 deg: ~220 m for a 150 m machine, inside a
            70 x 55 deg camera's view even with the look jitter).
        approach_altitude: start altitude as a fraction of the tower height.
        orbit_standoff: orbit clearance [m] outside the rotor disc (orbit radius about the
            tower axis = nacelle + blade length + this).
        orbit_extra_turns: full turns added to the orbit (which is at least half a turn).
        tower_standoff: (min, max) distance [m] of the tower scan from the tower axis;
            drawn uniformly per flight.
        tower_bottom: altitude [m] where the scan up the tower starts.
        blade_standoff: (min, max) distance [m] from the rotor plane while scanning a
            blade; drawn per blade and side (raised where needed to keep clear of the
            tower and nacelle).
        root_start: where a blade scan starts, as a fraction of the blade length from the
            hub.
        min_clearance: minimum distance [m] of the path from the skeleton (the five model
            lines); 5 m keeps ~3 m from the surface of a tower of 2 m radius.
        min_altitude: minimum altitude [m].
        look_jitter_deg: standard deviation of the smooth yaw and pitch offsets [deg].
        roll_jitter_deg: standard deviation of the smooth roll [deg].
        jitter_length: correlation length of the offsets along the path [m].
        max_pitch_deg: the camera never looks further up or down than this [deg].
        rotation_weight: path length [m] that one radian of view rotation counts as when
            spreading keyframes.
        position_smoothing: Gaussian smoothing of the path's corners [m].
        direction_smoothing: Gaussian smoothing of the viewing direction [m of path].
        step: spacing of the dense path [m].
    """

    approach_distance: float = 150.0
    approach_fov_deg: float = 40.0
    approach_altitude: float = 0.5
    orbit_standoff: float = 30.0
    orbit_extra_turns: int = 0
    tower_standoff: tuple[float, float] = (10.0, 25.0)
    tower_bottom: float = 5.0
    blade_standoff: tuple[float, float] = (8.0, 25.0)
    root_start: float = 0.12
    min_clearance: float = 5.0
    min_altitude: float = 2.0
    look_jitter_deg: float = 4.0
    roll_jitter_deg: float = 0.5
    jitter_length: float = 15.0
    max_pitch_deg: float = 75.0
    rotation_weight: float = 20.0
    position_smoothing: float = 2.0
    direction_smoothing: float = 4.0
    step: float = 0.25


@dataclass(frozen=True)
class InspectionPath:
    """A planned flight.

    Attributes:
        world_T_cam: (N,) ground-truth camera-to-world poses.
        phase: (N,) index into :data:`PHASES` of each keyframe.
        target: (N, 3) world point [m] each keyframe is aimed at (before jitter).
    """

    world_T_cam: SE3
    phase: NDArray[np.int_]
    target: FloatArray


# ---- geometry helpers ---------------------------------------------------------------


def distance_to_segments(points: FloatArray, segments: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Distance [m] of each point (n, 3) to the nearest of ``segments`` (m, 2, 3), and the
    nearest segment point (n, 3)."""
    a = segments[:, 0]
    ab = segments[:, 1] - a
    ap = points[:, None, :] - a[None]
    t = np.clip(np.einsum("nmk,mk->nm", ap, ab) / np.maximum(np.sum(ab * ab, -1), 1e-12), 0, 1)
    closest = a[None] + t[..., None] * ab[None]
    d = np.linalg.norm(points[:, None, :] - closest, axis=-1)
    i = np.argmin(d, axis=1)
    rows = np.arange(len(points))
    return d[rows, i], closest[rows, i]


def _push_clear(points: FloatArray, segments: FloatArray, clearance: float,
                min_altitude: float) -> FloatArray:
    """Move points to at least ``clearance`` from the segments and above ``min_altitude``."""
    p = points.copy()
    for _ in range(30):
        p[:, 2] = np.maximum(p[:, 2], min_altitude)
        d, c = distance_to_segments(p, segments)
        bad = d < clearance - 1e-9
        if not np.any(bad):
            break
        away = p[bad] - c[bad]
        n = np.linalg.norm(away, axis=-1, keepdims=True)
        # a point exactly on the skeleton: leave horizontally
        away = np.where(n > 1e-9, away / np.maximum(n, 1e-12), np.array([1.0, 0.0, 0.0]))
        p[bad] += away * (clearance - d[bad])[:, None] * 1.001
    p[:, 2] = np.maximum(p[:, 2], min_altitude)
    return p


def _rotate(v: FloatArray, axis: FloatArray, angle: FloatArray) -> FloatArray:
    """Rodrigues rotation of vector ``v`` (3,) about unit ``axis`` by ``angle`` (n,) -> (n, 3)."""
    c = np.cos(angle)[:, None]
    s = np.sin(angle)[:, None]
    return v * c + np.cross(axis, v) * s + axis * (axis @ v) * (1.0 - c)


def _unit(v: FloatArray) -> FloatArray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _horizontal(az: float) -> FloatArray:
    return np.array([math.cos(az), math.sin(az), 0.0])


def _count(length: float, step: float) -> int:
    return max(2, math.ceil(length / step) + 1)


def _lerp(a: FloatArray, b: FloatArray, n: int) -> FloatArray:
    t = np.linspace(0.0, 1.0, n)[:, None]
    return a * (1.0 - t) + b * t


# ---- the flight ------------------------------------------------------------------------


class _Builder:
    """Accumulates dense (position, target, phase) samples of the flight."""

    def __init__(self, step: float) -> None:
        self.step = step
        self.pos: list[FloatArray] = []
        self.tgt: list[FloatArray] = []
        self.phase: list[NDArray[np.int_]] = []

    @property
    def last(self) -> tuple[FloatArray, FloatArray]:
        return self.pos[-1][-1], self.tgt[-1][-1]

    def add(self, pos: FloatArray, tgt: FloatArray, phase: int) -> None:
        self.pos.append(pos)
        self.tgt.append(np.broadcast_to(tgt, pos.shape).copy())
        self.phase.append(np.full(len(pos), phase))

    def go_to(self, pos: FloatArray, tgt: FloatArray, phase: int, segments: FloatArray,
              clearance: float, min_altitude: float) -> None:
        """Transfer from the last sample, straight or detouring round the structure."""
        p0, t0 = self.last
        route = _route(p0, pos, segments, clearance, min_altitude, self.step)
        along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(route, axis=0), axis=-1))]
        t = (along / max(along[-1], 1e-12))[:, None]
        self.add(route, t0 * (1.0 - t) + tgt * t, phase)


def _route(a: FloatArray, b: FloatArray, segments: FloatArray, clearance: float,
           min_altitude: float, step: float, depth: int = 0) -> FloatArray:
    """Dense polyline from a to b keeping ``clearance`` from the segments and above
    ``min_altitude``: straight if possible, else through a waypoint beside the nearest
    obstacle (recursively). Continuous by construction (no jumps)."""
    line = _lerp(a, b, _count(float(np.linalg.norm(b - a)), step))
    d, c = distance_to_segments(line, segments)
    margin = np.minimum(d - clearance, line[:, 2] - min_altitude)
    if depth >= 6 or float(margin.min()) >= 0.0:
        return line
    k = int(np.argmin(margin))
    away = line[k] - c[k]
    norm = float(np.linalg.norm(away))
    if norm < 1e-6:  # straight through the skeleton: step aside horizontally
        away = np.cross(b - a, _UP)
        norm = float(np.linalg.norm(away))
        if norm < 1e-6:
            away, norm = np.array([1.0, 0.0, 0.0]), 1.0
    way = c[k] + away / norm * max(1.5 * clearance, d[k])
    way[2] = max(way[2], min_altitude + 1.0)
    first = _route(a, way, segments, clearance, min_altitude, step, depth + 1)
    second = _route(way, b, segments, clearance, min_altitude, step, depth + 1)
    return np.concatenate([first, second[1:]])


def plan_inspection(
    turbine: TurbineParams,
    n_keyframes: int,
    rng: np.random.Generator,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
    cfg: TrajectoryConfig | None = None,
) -> InspectionPath:
    """Plan an inspection flight of ``turbine`` with ``n_keyframes`` (>= 1) keyframes.

    See the module docstring for the phases. Deterministic given ``rng``'s state.
    """
    cfg = cfg or TrajectoryConfig()
    if n_keyframes < 1:
        raise ValueError(f"need at least one keyframe, got {n_keyframes}")
    step = cfg.step
    clear = cfg.min_clearance
    p, _ = model_points(turbine.to_vector(), geometry)
    segs = skeleton_segments(turbine, geometry)
    base, hub, tips = p[0], p[2], p[3:]
    b = turbine.blade_length
    r = turbine.nacelle_length
    heading = turbine.heading
    tau = geometry.shaft_tilt
    n_axis = np.array([math.cos(heading) * math.cos(tau), math.sin(heading) * math.cos(tau),
                       math.sin(tau)])  # rotor axis, pointing forward (away from the tower)
    blade_dir = _unit(tips - hub)
    centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
    bld = _Builder(step)
    detour = 1.5 * clear

    # 1. approach: in front, low and far, to the orbit
    az_app = heading + rng.uniform(-math.pi / 4, math.pi / 4)
    r_orbit = r + b + cfg.orbit_standoff
    z_orbit = float(hub[2])
    z_start = max(cfg.approach_altitude * turbine.tower_height, cfg.min_altitude)
    fit = float(np.max(np.linalg.norm(p - centre, axis=-1))) / math.sin(
        math.radians(cfg.approach_fov_deg) / 2.0)
    reach = max(cfg.approach_distance, math.sqrt(max(fit**2 - (centre[2] - z_start) ** 2, 0.0)))
    start = np.array([centre[0], centre[1], z_start]) + reach * _horizontal(az_app)
    orbit0 = base + r_orbit * _horizontal(az_app)
    orbit0[2] = z_orbit
    n = _count(float(np.linalg.norm(orbit0 - start)), step)
    bld.add(_push_clear(_lerp(start, orbit0, n), segs, detour, cfg.min_altitude), centre, 0)

    # 2. orbit: at least half a turn, ending behind the turbine
    az_back = heading + math.pi + rng.uniform(-math.pi / 3, math.pi / 3)
    ccw = (az_back - az_app) % (2 * math.pi)
    total = max(ccw, 2 * math.pi - ccw)
    sweep = (ccw if total == ccw else -(2 * math.pi - ccw))
    sweep += math.copysign(2 * math.pi * cfg.orbit_extra_turns, sweep)
    n = _count(abs(sweep) * r_orbit, step)
    az = az_app + np.linspace(0.0, sweep, n)
    bob = rng.uniform(0.05, 0.15) * b * np.sin(np.linspace(0.0, 2 * math.pi, n) * rng.integers(1, 3))
    orbit = base + r_orbit * np.stack([np.cos(az), np.sin(az), np.zeros(n)], -1)
    orbit[:, 2] = z_orbit + bob
    bld.add(orbit, hub, 1)
    az_end = float(az[-1])

    # 3. tower: down behind it, then up it
    rho = rng.uniform(*cfg.tower_standoff)
    z0 = max(cfg.tower_bottom, cfg.min_altitude)
    low = base + rho * _horizontal(az_end)
    low[2] = z0
    bld.go_to(low, base + np.array([0.0, 0.0, z0]), 2, segs, detour, cfg.min_altitude)
    n = _count(turbine.tower_height - z0, step)
    z = np.linspace(z0, turbine.tower_height, n)
    up = np.repeat(low[None], n, axis=0)
    up[:, 2] = z
    tgt = np.repeat(base[None], n, axis=0)
    tgt[:, 2] = z
    bld.add(up, tgt, 2)

    # 4. blades: out on one side, round the tip, back on the other; turn round the hub
    s0 = cfg.root_start * b

    def standoff(side: int) -> float:
        d = rng.uniform(*cfg.blade_standoff)
        # behind the rotor plane keep clear of the tower and nacelle too
        return max(d, clear + 3.0) if side > 0 else max(d, r + clear + 3.0)

    p_end = bld.last[0]
    back_roots = hub + s0 * blade_dir - (r + clear + 3.0) * n_axis
    first = int(np.argmin(np.linalg.norm(back_roots - p_end, axis=-1)))
    turn = 1 if rng.uniform() < 0.5 else -1
    order = [first, (first + turn) % 3, (first + 2 * turn) % 3]
    side = -1  # start behind the rotor plane, where the tower scan ended
    d_prev = 0.0
    for k, i in enumerate(order):
        u = blade_dir[i]
        d_out, d_in = standoff(side), standoff(-side)
        if k == 0:
            root = hub + s0 * u + side * d_out * n_axis
            bld.go_to(root, hub + s0 * u, 3, segs, detour, cfg.min_altitude)
        else:
            # turn round the hub on the current side from the previous blade's root
            u_prev = blade_dir[order[k - 1]]
            ang = math.atan2(float(np.cross(u_prev, u) @ n_axis), float(
                (u_prev - (u_prev @ n_axis) * n_axis) @ (u - (u @ n_axis) * n_axis)))
            m = _count(abs(ang) * s0, step)
            t = np.linspace(0.0, 1.0, m)
            radial = s0 * _rotate(u_prev, n_axis, ang * t)
            d_t = (1 - t) * d_prev + t * d_out
            arc = hub + radial + side * d_t[:, None] * n_axis
            arc = _push_clear(arc, segs, detour, cfg.min_altitude)
            bld.add(arc, hub + radial, 3)
        m = _count(b - s0, step)
        s = np.linspace(s0, b, m)[:, None]
        bld.add(hub + s * u + side * d_out * n_axis, hub + s * u, 3)
        # round the tip to the other side, in the most nearly horizontal clear plane
        tip = hub + b * u
        bld.add(_tip_arc(tip, u, n_axis, side * d_out, -side * d_in, segs, clear,
                         cfg.min_altitude, step), tip, 3)
        s = s[::-1]
        bld.add(hub + s * u - side * d_in * n_axis, hub + s * u, 3)
        side = -side
        d_prev = d_in

    # 5. depart: out in front of the hub
    if side < 0:  # ended behind the rotor plane: go round beside the rotor disc
        p_end = bld.last[0]
        lateral = _unit(np.cross(_UP, n_axis))
        if float((p_end - hub) @ lateral) < 0:
            lateral = -lateral
        bld.go_to(hub + (b + clear + 10.0) * lateral, hub, 4, segs, detour, cfg.min_altitude)
    dep = hub + (b + cfg.orbit_standoff) * n_axis
    bld.go_to(dep, hub, 4, segs, detour, cfg.min_altitude)

    return _sample_path(bld, n_keyframes, rng, segs, cfg)


def _tip_arc(tip: FloatArray, u: FloatArray, n_axis: FloatArray, off_out: float,
             off_in: float, segments: FloatArray, clearance: float, min_altitude: float,
             step: float) -> FloatArray:
    """Half ellipse round a blade tip from ``tip + off_out n`` to ``tip + off_in n``.

    It passes beyond the tip (along u) or beside it, in the most nearly horizontal plane
    that keeps clear of the structure and the ground: over the tip of a blade pointing up
    the camera would look straight down and have to spin round, under the tip of a blade
    pointing down the drone would meet the tower."""
    lat = _unit(np.cross(n_axis, u))
    d_tip = 0.5 * (abs(off_out) + abs(off_in))
    m = _count(math.pi * d_tip, step)
    a = np.linspace(0.0, math.pi, m)[:, None]
    radial = np.maximum(np.cos(a), 0.0) * off_out + np.maximum(-np.cos(a), 0.0) * off_in
    betas = np.radians([0.0, 45.0, -45.0, 90.0, -90.0])
    dirs = np.cos(betas)[:, None] * u + np.sin(betas)[:, None] * lat
    best, best_margin = None, -math.inf
    for w in dirs[np.argsort(np.abs(dirs[:, 2]), kind="stable")]:
        arc = tip + radial * n_axis + np.sin(a) * d_tip * w
        d, _ = distance_to_segments(arc, segments)
        margin = min(float(d.min()) - clearance, float(arc[:, 2].min()) - min_altitude)
        if margin >= 2.0:
            return arc
        if margin > best_margin:
            best, best_margin = arc, margin
    assert best is not None
    return best


def _sample_path(bld: _Builder, n_keyframes: int, rng: np.random.Generator, segs: FloatArray,
                 cfg: TrajectoryConfig) -> InspectionPath:
    """Resample, smooth and clear the dense path, then spread keyframes along it."""
    step = cfg.step
    pos = np.concatenate(bld.pos)
    tgt = np.concatenate(bld.tgt)
    phase = np.concatenate(bld.phase)
    # uniform resampling by arc length
    seg_len = np.linalg.norm(np.diff(pos, axis=0), axis=-1)
    keep = np.r_[True, seg_len > 1e-9]
    pos, tgt, phase = pos[keep], tgt[keep], phase[keep]
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=-1))]
    grid = np.linspace(0.0, arc[-1], max(2, math.ceil(arc[-1] / step) + 1))
    pos = np.stack([np.interp(grid, arc, pos[:, k]) for k in range(3)], -1)
    tgt = np.stack([np.interp(grid, arc, tgt[:, k]) for k in range(3)], -1)
    idx = np.clip(np.searchsorted(arc, grid, side="right") - 1, 0, len(phase) - 1)
    phase = phase[idx]
    ds = float(grid[1] - grid[0]) if len(grid) > 1 else step

    pos = gaussian_filter1d(pos, cfg.position_smoothing / ds, axis=0, mode="nearest")
    pos = _push_clear(pos, segs, cfg.min_clearance, cfg.min_altitude)
    view = _unit(tgt - pos)
    view = _unit(gaussian_filter1d(view, cfg.direction_smoothing / ds, axis=0, mode="nearest"))

    # smooth random yaw / pitch / roll offsets (unit-variance low-pass noise)
    sig = max(cfg.jitter_length / ds, 1e-3)
    noise = gaussian_filter1d(rng.standard_normal((len(grid), 3)), sig, axis=0, mode="wrap")
    noise *= math.sqrt(2.0 * math.sqrt(math.pi) * sig) if sig > 0.5 else 1.0
    jitter = noise * np.radians([cfg.look_jitter_deg, cfg.look_jitter_deg, cfg.roll_jitter_deg])

    # keyframes evenly spread over distance flown + view rotation
    turn = np.arccos(np.clip(np.sum(view[1:] * view[:-1], -1), -1.0, 1.0))
    inc = np.linalg.norm(np.diff(pos, axis=0), axis=-1) + cfg.rotation_weight * turn + 1e-9
    q = np.r_[0.0, np.cumsum(inc)]
    qk = np.linspace(0.0, q[-1], n_keyframes) if n_keyframes > 1 else np.zeros(1)

    def interp(a: FloatArray) -> FloatArray:
        return np.stack([np.interp(qk, q, a[:, k]) for k in range(a.shape[1])], -1)

    pos_k = interp(pos)
    view_k = _unit(interp(view))
    jit_k = interp(jitter)
    tgt_k = interp(tgt)
    idx = np.clip(np.searchsorted(q, qk, side="right") - 1, 0, len(phase) - 1)
    return InspectionPath(_look(pos_k, view_k, jit_k, cfg.max_pitch_deg), phase[idx], tgt_k)


def _look(pos: FloatArray, view: FloatArray, jitter: FloatArray, max_pitch_deg: float) -> SE3:
    """world_T_cam of cameras at ``pos`` looking along ``view`` with (yaw, pitch, roll)
    offsets ``jitter`` [rad], pitch clipped to +-``max_pitch_deg``
    (:func:`~turbinefit.geometry.se3.world_T_cam_from_angles`)."""
    yaw = np.arctan2(view[:, 1], view[:, 0]) + jitter[:, 0]
    lim = math.radians(max_pitch_deg)
    pitch = np.clip(np.arcsin(np.clip(view[:, 2], -1.0, 1.0)) + jitter[:, 1], -lim, lim)
    return world_T_cam_from_angles(pos, yaw, pitch, jitter[:, 2])


def inspection_trajectory(
    turbine: TurbineParams,
    n_keyframes: int,
    rng: np.random.Generator,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
    cfg: TrajectoryConfig | None = None,
) -> SE3:
    """Ground-truth ``world_T_cam`` (N,) of an inspection flight (see :func:`plan_inspection`)."""
    return plan_inspection(turbine, n_keyframes, rng, geometry, cfg).world_T_cam
