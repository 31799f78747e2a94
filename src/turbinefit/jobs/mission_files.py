"""The mission files of ``turbinefit plan`` (:mod:`turbinefit.io.missions`): the planned
path in WGS84 as the drone apps of a platform (:mod:`turbinefit.io.platforms`) fly it,
split into missions the platform takes.

Heights are above the take-off point, taken as the georeference's origin (``import dji``
puts it on the ground under the first photo, the previous flight's take-off point; for a
simulated flight placed with ``plan --origin``, the origin given). Take off from there, or
from a point at the same ground height: a take-off from higher ground flies the whole
path higher by the difference.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from turbinefit.errors import InputError
from turbinefit.inspection.coverage import side_names
from turbinefit.inspection.plan import Plan
from turbinefit.inspection.surface import PARTS
from turbinefit.io.atomic import write_bytes_atomic, write_text_atomic
from turbinefit.io.georef import Georef
from turbinefit.io.missions import (
    LITCHI_ALTITUDE,
    MAV_AUTOPILOT_ARDUPILOTMEGA,
    MAV_AUTOPILOT_GENERIC,
    MAV_AUTOPILOT_PX4,
    Mission,
    MissionPoint,
    MissionSettings,
    format_litchi_csv,
    format_mavlink_wpl,
    format_qgc_plan,
    mavlink_items,
    mission_file_name,
    split_missions,
    wpml_kmz,
)
from turbinefit.io.platforms import MISSION_FORMATS, Platform, drone_platforms

#: Per mission format: the files' stem and suffix.
FILES = {"dji-wpml": ("dji", ".kmz"), "litchi": ("litchi", ".csv"),
         "qgc": ("mission", ".plan"), "mavlink": ("mission", ".waypoints")}
#: The names of the mission files (numbered when a plan needs several missions).
FILE_PATTERNS = tuple(rf"{stem}(_\d+)?\{suffix}" for stem, suffix in FILES.values())
#: The MAVLink items of a mission besides its waypoints' (home position, speed).
MAVLINK_OVERHEAD = 2


def mission_points(plan: Plan, georef: Georef) -> list[MissionPoint]:
    """The plan's waypoints in WGS84 about ``georef`` (see the module docstring): the
    aircraft heads where the camera looks, the gimbal pitches as the view."""
    p = np.array([w.position for w in plan.waypoints], dtype=np.float64).reshape(-1, 3)
    lat, lon, alt = georef.geodetic(p)
    out = []
    for i, w in enumerate(plan.waypoints):
        name = f"{PARTS[w.part]} {side_names(w.part)[w.side]} {w.span:.2f} m" if w.photo else ""
        out.append(MissionPoint(i, float(lat[i]), float(lon[i]), float(alt[i]),
                                float(alt[i] - georef.altitude),
                                round((90.0 - math.degrees(w.yaw)) % 360.0, 6) % 360.0,
                                round(math.degrees(w.pitch), 6) + 0.0, w.photo, name))
    return out


def platforms_flying(fmt: str) -> list[str]:
    """The table's platforms whose apps fly format ``fmt``."""
    return [k for k, p in drone_platforms().items() if fmt in p.formats]


def check_formats(formats: Sequence[str], platform: Platform) -> tuple[str, ...]:
    """``formats`` checked: known, and flown by ``platform``.

    Raises:
        InputError: field ``--format``, naming the platforms that fly it.
    """
    for f in formats:
        if f not in MISSION_FORMATS:
            raise InputError(f"unknown mission format {f!r}; known: {', '.join(MISSION_FORMATS)}",
                             field="--format")
        if f not in platform.formats:
            raise InputError(f"platform {platform.key} does not fly {f} missions (it flies "
                             f"{', '.join(platform.formats)}); {f}: --platform "
                             f"{', '.join(platforms_flying(f))}", field="--format")
    return tuple(dict.fromkeys(formats))


def _settings(name: str, georef: Georef, platform: Platform, speed: float,
              rth_height: float) -> MissionSettings:
    autopilot = {"px4": MAV_AUTOPILOT_PX4, "ardupilot": MAV_AUTOPILOT_ARDUPILOTMEGA}.get(
        platform.key, MAV_AUTOPILOT_GENERIC)
    return MissionSettings(name, georef.latitude, georef.longitude, georef.altitude, speed,
                           rth_height, platform.wpml, autopilot,
                           condition_yaw=platform.key == "ardupilot")


def split_for(fmt: str, points: list[MissionPoint], platform: Platform,
              settings: MissionSettings) -> list[Mission]:
    """``points`` split into the missions ``platform`` takes in format ``fmt``."""
    try:
        if fmt in ("qgc", "mavlink"):
            return split_missions(points, platform.max_waypoints,
                                  lambda p: mavlink_items(p, settings.condition_yaw),
                                  platform.max_items, MAVLINK_OVERHEAD)
        return split_missions(points, platform.max_waypoints)
    except ValueError as exc:
        raise InputError(f"platform {platform.key} takes too few waypoints per mission for "
                         f"{fmt}: {exc}", field="--platform") from None


#: The least distance between consecutive waypoints DJI's Mobile SDK waypoint missions
#: (Litchi's) take [m].
DJI_MIN_LEG_M = 0.5


def check_flyable(points: Sequence[MissionPoint], formats: Sequence[str],
                  world_p: np.ndarray) -> None:
    """Refuse what a format cannot hold: Litchi's heights above the take-off point and
    waypoints closer than :data:`DJI_MIN_LEG_M` (``world_p``: their positions [m]).

    Raises:
        InputError: field ``--format``, naming the waypoint.
    """
    if "litchi" in formats:
        lo, hi = LITCHI_ALTITUDE
        for p in points:
            if not lo <= p.height <= hi:
                raise InputError(f"waypoint {p.index} is {p.height:.1f} m above the take-off "
                                 f"point, outside Litchi's {lo:g} to {hi:g} m", field="--format")
        legs = np.linalg.norm(np.diff(world_p, axis=0), axis=1)
        short = np.flatnonzero(legs < DJI_MIN_LEG_M)
        if short.size:
            i = int(short[0])
            raise InputError(f"waypoints {i} and {i + 1} are {legs[i]:.2f} m apart, closer "
                             f"than the {DJI_MIN_LEG_M:g} m Litchi's missions take",
                             field="--format")


def write_mission_files(out_dir: Path, points: list[MissionPoint], formats: Sequence[str],
                        platform: Platform, georef: Georef, speed: float, rth_height: float,
                        name: str) -> dict[str, list[str]]:
    """Write the mission files of ``formats`` (but ``kml``) into ``out_dir``; returns the
    files written per format."""
    settings = _settings(name, georef, platform, speed, rth_height)
    written: dict[str, list[str]] = {}
    for fmt in formats:
        if fmt not in FILES:
            continue
        stem, suffix = FILES[fmt]
        missions = split_for(fmt, points, platform, settings)
        names = []
        for m in missions:
            file = mission_file_name(stem, m, len(missions), suffix)
            if fmt == "dji-wpml":
                write_bytes_atomic(out_dir / file, wpml_kmz(m, settings), fsync=False)
            elif fmt == "litchi":
                write_text_atomic(out_dir / file, format_litchi_csv(m, speed), fsync=False)
            elif fmt == "qgc":
                write_text_atomic(out_dir / file, format_qgc_plan(m, settings), fsync=False)
            else:
                write_text_atomic(out_dir / file, format_mavlink_wpl(m, settings), fsync=False)
            names.append(file)
        written[fmt] = names
    return written
