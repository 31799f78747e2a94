"""Random camera views of a turbine for training data: far, medium and close views aimed
near its parts, clear of its solid (:func:`sample_training_view`), and close-ups of one
blade or the tower filling the frame, as surface inspection photographs them
(:func:`sample_closeup_view`).
"""

from __future__ import annotations

import math

import numpy as np

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, world_T_cam_from_angles
from turbinefit.sim.images.turbine import blade_profile, solid_segments
from turbinefit.sim.trajectory import distance_to_segments
from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineGeometry, TurbineParams, model_points

_CLEARANCE = 6.0  # [m] sample_training_view keeps this far from the turbine


def sample_training_view(
    rng: np.random.Generator,
    turbine: TurbineParams,
    camera: PinholeCamera,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> SE3:
    """``world_T_cam`` of a varied training view of ``turbine``.

    A mix of far views (150-500 m from the turbine's centre, 30 %), medium views (40-150 m
    from a random point of the skeleton, 35 %) and close views (12-40 m from a point of the
    nacelle, a blade or the tower, 35 %) aimed at that point with random offsets of up to
    about half the field of view (more for close views, so parts leave the frame). The
    camera is at least 3 m above the ground and 6 m from the turbine's skeleton (and the
    nacelle's rear), mostly level (roll within +-5 deg), pitch within +-60 deg.
    """
    p, _ = model_points(turbine.to_vector(), geometry)
    segs = solid_segments(turbine, geometry)
    lengths = np.linalg.norm(segs[:, 1] - segs[:, 0], axis=-1)
    half_h = math.atan(0.5 * camera.width / camera.fx)
    half_v = math.atan(0.5 * camera.height / camera.fy)
    centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
    kind = int(rng.choice(3, p=[0.3, 0.35, 0.35]))
    pos = target = centre
    for _attempt in range(200):
        if kind == 0:
            target = centre + rng.normal(0.0, 0.1, 3) * np.array([1.0, 1.0, 2.0]) * turbine.blade_length
            dist = rng.uniform(150.0, 500.0)
            el = math.radians(rng.uniform(-25.0, 30.0))
            spread = 0.45
        elif kind == 1:
            k = int(rng.choice(5, p=lengths[:5] / lengths[:5].sum()))
            target = segs[k, 0] + rng.uniform() * (segs[k, 1] - segs[k, 0])
            dist = rng.uniform(40.0, 150.0)
            el = math.radians(rng.uniform(-40.0, 40.0))
            spread = 0.7
        else:
            part = rng.choice(3, p=[0.35, 0.4, 0.25])
            if part == 0:  # nacelle, hub, blade roots
                target = p[1] + rng.uniform(-0.5, 1.2) * (p[2] - p[1]) + rng.normal(0, 1.5, 3)
            elif part == 1:  # a blade
                i = int(rng.integers(0, 3))
                target = p[2] + rng.uniform(0.1, 1.0) * (p[3 + i] - p[2])
            else:  # the tower
                target = p[0] + rng.uniform(0.05, 1.0) * (p[1] - p[0])
            dist = rng.uniform(12.0, 40.0)
            el = math.radians(rng.uniform(-50.0, 50.0))
            spread = 1.0
        az = rng.uniform(0.0, 2 * math.pi)
        pos = target + dist * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az),
                                        math.sin(el)])
        if pos[2] < 3.0:
            pos[2] = rng.uniform(3.0, 3.0 + 0.2 * dist)
        d, _ = distance_to_segments(pos[None], segs)
        if float(d[0]) >= _CLEARANCE:
            break
    else:  # give up on the close view: go back far enough (always succeeds)
        away = pos - centre
        away[2] = 0.0
        nrm = float(np.linalg.norm(away))
        away = away / nrm if nrm > 1e-9 else np.array([1.0, 0.0, 0.0])
        pos = centre + away * (turbine.blade_length + turbine.nacelle_length + 3 * _CLEARANCE)
        pos[2] = max(pos[2], 3.0)
        target = centre
    v = target - pos
    yaw = math.atan2(v[1], v[0]) + spread * half_h * rng.uniform(-1.0, 1.0)
    pitch = math.atan2(v[2], math.hypot(v[0], v[1])) + spread * half_v * rng.uniform(-1.0, 1.0)
    pitch = float(np.clip(pitch, -math.radians(60.0), math.radians(60.0)))
    roll = float(np.clip(rng.normal(0.0, math.radians(2.0)), -math.radians(5.0), math.radians(5.0)))
    return world_T_cam_from_angles(pos, yaw, pitch, roll)


#: [m] range of a close-up's distance from the part's surface.
CLOSEUP_RANGE_M = (3.0, 30.0)


def sample_closeup_view(
    rng: np.random.Generator,
    turbine: TurbineParams,
    camera: PinholeCamera,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> SE3:
    """``world_T_cam`` of a close-up of one blade (75 %) or the tower (25 %), as a surface
    inspection photographs them: the camera 3-30 m from the part's surface
    (:data:`CLOSEUP_RANGE_M`, log-uniform), looking at a point of it from any side and at
    up to 55 deg off the part's normal (mostly from above, the ground behind, as
    inspection photos are taken), so the part fills much of the frame and crosses it
    at any angle; aimed with offsets of up to a third of the field of view (the part's
    line need not pass through the centre); blade points are drawn towards the tip (span
    0.3-1.05: a blade tip is in view in about half of all close-ups), roll within
    +-20 deg. The camera keeps 2 m from the part's surface, 3 m above the ground and 5 m
    from the other parts' axes; a draw that fails 200 times falls back to a view from
    30 m out.
    """
    p, _ = model_points(turbine.to_vector(), geometry)
    segs = solid_segments(turbine, geometry)
    half_h = math.atan(0.5 * camera.width / camera.fx)
    half_v = math.atan(0.5 * camera.height / camera.fy)
    blade = rng.uniform() < 0.75
    i = int(rng.integers(0, 3))
    a, b = (p[2], p[3 + i]) if blade else (p[0], p[1])
    axis = b - a
    length = float(np.linalg.norm(axis))
    e = axis / max(length, 1e-9)
    n1 = np.cross(e, [0.0, 0.0, 1.0]) if abs(e[2]) < 0.95 else np.cross(e, [1.0, 0.0, 0.0])
    n1 /= np.linalg.norm(n1)
    n2 = np.cross(e, n1)
    others = np.stack([g for g in segs if not (np.allclose(g[0], a) and np.allclose(g[1], b))])
    pos = target = a + 0.5 * axis
    for _attempt in range(200):
        s = rng.uniform(0.3, 1.05) if blade else rng.uniform(0.1, 0.95)
        if blade:
            u = np.array([min(s, 1.0)], dtype=np.float32)
            radius = float(blade_profile(u, turbine.blade_length)[0][0])
        else:
            radius = turbine.tower_height * (1 / 30 + (1 / 45 - 1 / 30) * s)
        target = a + min(s, 1.0) * axis
        lo, hi = CLOSEUP_RANGE_M
        dist = radius + math.exp(rng.uniform(math.log(lo), math.log(hi)))
        phi = rng.uniform(0.0, 2 * math.pi)
        tilt = math.radians(rng.uniform(-55.0, 55.0))  # off the part's normal, along it
        normal = math.cos(phi) * n1 + math.sin(phi) * n2
        if normal[2] < 0 and rng.uniform() < 0.6:  # mostly from above, the ground behind
            normal = -normal
        d = math.cos(tilt) * normal + math.sin(tilt) * e
        pos = target + dist * d
        if pos[2] < 3.0:
            continue
        own, _ = distance_to_segments(pos[None], np.stack([a, b])[None])
        gap, _ = distance_to_segments(pos[None], others)
        if float(own[0]) >= radius + 2.0 and float(gap[0]) >= 5.0:
            break
    else:
        pos = target + (turbine.blade_length * 0.1 + 30.0) * np.array([1.0, 0.0, 0.0])
        pos[2] = max(pos[2], 3.0)
    v = target - pos
    yaw = math.atan2(v[1], v[0]) + half_h * rng.uniform(-1.0, 1.0) / 3.0
    pitch = math.atan2(v[2], math.hypot(v[0], v[1])) + half_v * rng.uniform(-1.0, 1.0) / 3.0
    pitch = float(np.clip(pitch, -math.radians(85.0), math.radians(85.0)))
    roll = math.radians(rng.uniform(-20.0, 20.0))
    return world_T_cam_from_angles(pos, yaw, pitch, roll)
