"""The table of drone platforms (``turbinefit plan --platform NAME``).

``turbinefit/data/drone_platforms.yaml`` lists, per platform, the mission formats its app
flies, its gimbal's pitch range, how many waypoints (and MAVLink items) one mission takes,
its top speed, optionally its camera and DJI's WPML enumeration values, with the
published source of each number. :func:`drone_platforms` reads and checks it;
:func:`drone_platform` finds one by name.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from turbinefit.errors import InputError
from turbinefit.io.quantities import Quantity
from turbinefit.io.yaml_files import load_yaml_mapping

#: The table shipped with the package.
TABLE = Path(__file__).resolve().parent.parent / "data" / "drone_platforms.yaml"
#: The platform ``plan`` uses when none is named.
DEFAULT_PLATFORM = "generic"
#: The mission formats ``plan --format`` writes, in the order it lists them.
MISSION_FORMATS = ("dji-wpml", "litchi", "qgc", "mavlink", "kml")

GIMBAL_PITCH = Quantity("gimbal pitch", "deg", -180.0, 90.0)
WAYPOINTS = Quantity("waypoints per mission", "", 2.0, 65535.0, integer=True)
SPEED = Quantity("speed", "m/s", 0.0, 50.0, lo_open=True)
PIXELS = Quantity("image size", "px", 24.0, 100000.0, integer=True)
ENUM = Quantity("enumeration value", "", 0.0, 65535.0, integer=True)


@dataclass(frozen=True)
class PlatformCamera:
    """A platform's camera: its name in the camera table, lens and sensor (the table's),
    and image size."""

    name: str
    focal_length_mm: float
    sensor_width_mm: float
    width: int
    height: int

    def intrinsics(self) -> tuple[int, int, float, float, float, float]:
        """``(width, height, fx, fy, cx, cy)`` of the pinhole camera [px] (square pixels,
        centred principal point)."""
        f = self.focal_length_mm * self.width / self.sensor_width_mm
        return self.width, self.height, f, f, (self.width - 1) / 2.0, (self.height - 1) / 2.0


@dataclass(frozen=True)
class Platform:
    """One entry of the table (see the table's header).

    Attributes:
        key: the ``--platform`` name.
        name: the aircraft, gimbal and camera in words.
        formats: the mission formats its app flies.
        gimbal_min_deg, gimbal_max_deg: the gimbal's controllable pitch [deg], up positive.
        max_waypoints: waypoints per mission; max_items: MAVLink items per mission.
        max_speed_m_s: top speed in waypoint missions [m/s].
        camera: its camera, or None (the fit's flight's).
        wpml: DJI's enumeration values (``droneEnumValue`` ...), empty if none.
        source: where the numbers come from.
    """

    key: str
    name: str
    formats: tuple[str, ...]
    gimbal_min_deg: float
    gimbal_max_deg: float
    max_waypoints: int
    max_items: int
    max_speed_m_s: float
    camera: PlatformCamera | None
    wpml: dict[str, int]
    source: str


_REQUIRED = {"name", "formats", "gimbal_pitch_deg", "max_waypoints", "max_speed_m_s", "source"}
_KNOWN = _REQUIRED | {"max_items", "camera", "wpml"}
_WPML_KEYS = ("droneEnumValue", "droneSubEnumValue", "payloadEnumValue")


def _entry(key: str, data: Any, path: Path) -> Platform:
    if not isinstance(data, dict):
        raise InputError("must be a mapping", path=path, field=key)
    missing, unknown = _REQUIRED - set(data), set(data) - _KNOWN
    if missing or unknown:
        what = f"missing {', '.join(sorted(missing))}" if missing else \
            f"unknown {', '.join(sorted(unknown))}"
        raise InputError(what, path=path, field=key)
    formats = data["formats"]
    if not isinstance(formats, list) or not formats or \
            any(f not in MISSION_FORMATS for f in formats):
        raise InputError(f"formats must be a list of {', '.join(MISSION_FORMATS)}", path=path,
                         field=f"{key}.formats")
    pitch = data["gimbal_pitch_deg"]
    if not isinstance(pitch, list) or len(pitch) != 2:
        raise InputError("must be [min, max]", path=path, field=f"{key}.gimbal_pitch_deg")
    lo, hi = (GIMBAL_PITCH.check(v, path, field=f"{key}.gimbal_pitch_deg") for v in pitch)
    if not (lo <= -90.0 and hi >= 0.0):
        raise InputError(f"[{lo:g}, {hi:g}] must reach from -90 (straight down) to level or "
                         "above", path=path, field=f"{key}.gimbal_pitch_deg")
    camera = None
    if "camera" in data:
        c = data["camera"]
        if not isinstance(c, dict) or set(c) != {"name", "width", "height"}:
            raise InputError("must give name, width, height", path=path,
                             field=f"{key}.camera")
        camera = _camera(str(c["name"]),
                         int(PIXELS.check(c["width"], path, field=f"{key}.camera.width")),
                         int(PIXELS.check(c["height"], path, field=f"{key}.camera.height")),
                         path, f"{key}.camera")
    wpml: dict[str, int] = {}
    if "wpml" in data:
        w = data["wpml"]
        if not isinstance(w, dict) or set(w) != set(_WPML_KEYS):
            raise InputError(f"must give {', '.join(_WPML_KEYS)}", path=path, field=f"{key}.wpml")
        wpml = {k: int(ENUM.check(w[k], path, field=f"{key}.wpml.{k}")) for k in _WPML_KEYS}
    waypoints = int(WAYPOINTS.check(data["max_waypoints"], path, field=f"{key}.max_waypoints"))
    items = int(WAYPOINTS.check(data.get("max_items", 65535), path, field=f"{key}.max_items"))
    return Platform(key, str(data["name"]), tuple(formats), lo, hi, waypoints, items,
                    SPEED.check(data["max_speed_m_s"], path, field=f"{key}.max_speed_m_s"),
                    camera, wpml, str(data["source"]))


def _camera(name: str, width: int, height: int, path: Path, field: str) -> PlatformCamera:
    """The platform's camera: the fixed lens ``name`` of the camera table
    (:mod:`turbinefit.io.dji_cameras`, its lens and sensor), at a width it writes."""
    from turbinefit.io.dji_cameras import dji_cameras

    found = next((c for c in dji_cameras() if c.name == name), None)
    if found is None:
        raise InputError(f"{name!r} is not a camera of the camera table", path=path,
                         field=field)
    if not found.fixed_focal or width not in found.widths:
        raise InputError(f"{name!r} is no fixed lens writing {width} px wide photos in the "
                         "camera table", path=path, field=field)
    return PlatformCamera(name, found.focal_range_mm[0], found.sensor_width_mm, width, height)


@cache
def drone_platforms(path: Path = TABLE) -> dict[str, Platform]:
    """The table, by ``--platform`` name.

    Raises:
        InputError: naming the file and the entry's field that is missing or out of range.
    """
    data = load_yaml_mapping(path)
    return {str(k): _entry(str(k), v, path) for k, v in data.items()}


def drone_platform(name: str) -> Platform:
    """The table's entry ``name`` (case-insensitive).

    Raises:
        InputError: naming the known platforms, for an unknown name (field ``--platform``).
    """
    table = drone_platforms()
    key = name.strip().lower()
    if key not in table:
        raise InputError(f"unknown platform {name!r}; known: {', '.join(table)}",
                         field="--platform")
    return table[key]
