"""Georeferenced flights: ``georef.yaml``, WGS84 <-> the flight's east-north-up frame, and
the WGS84 outputs of ``fit`` and ``track``.

A flight folder with ``georef.yaml`` has its world frame tied to the Earth: x east, y
north, z up, in metres, about the origin the file gives (``pymap3d``'s ``geodetic2enu`` /
``enu2geodetic`` on the WGS84 ellipsoid; no hand-written geodesy)::

    latitude: 51.4512345678     # deg, WGS84, of the world frame's origin
    longitude: -2.5123456789    # deg
    altitude: 45.2              # m, in the photos' altitude datum
    frame: enu
    time_origin: '2024-05-01T12:00:00.120000'   # optional: camera time of timestamp 0

The altitude is taken as ellipsoidal height in the conversion; DJI's ``AbsoluteAltitude``
is often above mean sea level instead. One datum per flight shifts the whole flight by a
constant, which the ENU frame absorbs (the origin's ``altitude`` is in the same datum).

**Attitude** (DJI's gimbal angles, degrees): north-east-down Euler angles of the camera in
the local frame at the photo's own position: ``yaw`` clockwise from north, ``pitch`` 0
level and -90 straight down, ``roll`` about the optical axis (positive turns the image's
x axis towards its y axis, clockwise as seen from behind the camera). The camera looks
along ``(sin yaw cos pitch, cos yaw cos pitch, sin pitch)`` in local ENU; image x is to its
right, image y down (:func:`~turbinefit.geometry.se3.world_T_cam_from_angles` with azimuth
``90 deg - yaw``). The local frame at the photo is then rotated into the origin's ENU frame
(``pymap3d.enu2uvw`` / ``uvw2enu``; a few millidegrees per kilometre from the origin), so
poses and angles convert both ways exactly (:func:`world_T_cam_from_gimbal`,
:func:`gimbal_from_world_T_cam`).

**Outputs of fit and track** on a flight with ``georef.yaml``
(:func:`location_text`, :func:`write_georef_outputs`): ``turbine.yaml`` gains
``latitude`` and ``longitude`` of the fitted tower base, and ``keyframes_wgs84.csv``
lists each optimised camera as ``timestamp,latitude,longitude,altitude,yaw,pitch,roll``
in the same gimbal convention, so that the angles read back as ``import dji`` reads a
photo's; ``keyframes_wgs84.csvt`` and ``.prj`` beside it make GDAL and QGIS open it as
EPSG:4326 points, and ``keyframes_wgs84.geojson`` is the same points as GeoJSON.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.errors import InputError
from turbinefit.geometry.se3 import SE3, world_T_cam_from_angles
from turbinefit.io.atomic import StrPath, write_text_atomic
from turbinefit.io.flight_folder import GEOREF_FILE
from turbinefit.io.yaml_files import load_yaml_mapping, parse_number, yaml_float, yaml_str
from turbinefit.turbine.model import TurbineParams

#: The WGS84 trajectory that fit and track write next to keyframes.txt.
WGS84_CSV = "keyframes_wgs84.csv"
WGS84_HEADER = "timestamp,latitude,longitude,altitude,yaw,pitch,roll"

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Georef:
    """The origin of a flight's east-north-up world frame.

    Attributes:
        latitude, longitude: WGS84 [deg].
        altitude: [m], in the flight's altitude datum.
        time_origin: optional camera time (ISO 8601, no zone) of timestamp 0.
    """

    latitude: float
    longitude: float
    altitude: float
    time_origin: str | None = None

    def __post_init__(self) -> None:
        check_latlon(self.latitude, self.longitude)
        if not np.isfinite(self.altitude):
            raise ValueError(f"altitude must be finite, got {self.altitude}")

    def enu(self, latitude: ArrayLike, longitude: ArrayLike, altitude: ArrayLike) -> FloatArray:
        """East, north, up [m] (..., 3) of WGS84 positions about this origin."""
        import pymap3d

        e, n, u = pymap3d.geodetic2enu(np.asarray(latitude, np.float64),
                                       np.asarray(longitude, np.float64),
                                       np.asarray(altitude, np.float64),
                                       self.latitude, self.longitude, self.altitude)
        return np.stack([e, n, u], axis=-1)

    def geodetic(self, enu: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(latitude [deg], longitude [deg], altitude [m]) of ENU positions (..., 3)."""
        import pymap3d

        p = np.asarray(enu, dtype=np.float64)
        lat, lon, alt = pymap3d.enu2geodetic(p[..., 0], p[..., 1], p[..., 2], self.latitude,
                                             self.longitude, self.altitude)
        return np.asarray(lat), np.asarray(lon), np.asarray(alt)


def check_latlon(latitude: float, longitude: float) -> None:
    """Raise ValueError for a latitude outside [-90, 90] or a longitude outside
    [-180, 180]."""
    if not -90.0 <= latitude <= 90.0:
        raise ValueError(f"latitude must be in [-90, 90] deg, got {latitude}")
    if not -180.0 <= longitude <= 180.0:
        raise ValueError(f"longitude must be in [-180, 180] deg, got {longitude}")


# --------------------------------------------------------------------------- attitude

def _rotate_axes(R: FloatArray, lat_from: ArrayLike, lon_from: ArrayLike,
                 lat_to: ArrayLike, lon_to: ArrayLike) -> FloatArray:
    """Rotation matrices (N, 3, 3) whose columns are ENU vectors at (lat_from, lon_from),
    re-expressed in the ENU frame at (lat_to, lon_to) (through Earth-centred axes)."""
    import pymap3d

    out = np.empty_like(R)
    for c in range(3):
        u, v, w = pymap3d.enu2uvw(R[:, 0, c], R[:, 1, c], R[:, 2, c], lat_from, lon_from)
        e, n, up = pymap3d.uvw2enu(u, v, w, lat_to, lon_to)
        out[:, :, c] = np.stack([e, n, up], axis=-1)
    return out


def world_T_cam_from_gimbal(georef: Georef, latitude: ArrayLike, longitude: ArrayLike,
                            altitude: ArrayLike, yaw_deg: ArrayLike, pitch_deg: ArrayLike,
                            roll_deg: ArrayLike) -> SE3:
    """``world_T_cam`` (N,) in the ENU frame of ``georef`` of cameras at WGS84 positions
    with gimbal angles (module docstring; all inputs 1-D of length N)."""
    lat = np.atleast_1d(np.asarray(latitude, np.float64))
    lon = np.atleast_1d(np.asarray(longitude, np.float64))
    local = world_T_cam_from_angles(np.zeros((lat.size, 3)),
                                    np.radians(90.0 - np.asarray(yaw_deg, np.float64)),
                                    np.radians(pitch_deg), np.radians(roll_deg))
    R = _rotate_axes(local.rotation_matrix(), lat, lon, georef.latitude, georef.longitude)
    return SE3.from_rotation_translation(R, georef.enu(lat, lon, altitude))


@dataclass(frozen=True)
class Wgs84Poses:
    """Camera positions (WGS84 [deg], altitude [m]) and gimbal angles [deg], each (N,)."""

    latitude: FloatArray
    longitude: FloatArray
    altitude: FloatArray
    yaw: FloatArray
    pitch: FloatArray
    roll: FloatArray


def gimbal_from_world_T_cam(georef: Georef, world_T_cam: SE3) -> Wgs84Poses:
    """The inverse of :func:`world_T_cam_from_gimbal`: yaw in (-180, 180], pitch in
    [-90, 90], roll in (-180, 180] degrees. Straight up or down (pitch +-90) yaw and roll
    are not separable; the pair returned still gives the same rotation."""
    poses = SE3(world_T_cam.wxyz_xyz.reshape(-1, 7))
    lat, lon, alt = georef.geodetic(poses.translation)
    R = _rotate_axes(poses.rotation_matrix(), georef.latitude, georef.longitude, lat, lon)
    x, z = R[:, :, 0], R[:, :, 2]
    pitch = np.arcsin(np.clip(z[:, 2], -1.0, 1.0))
    azimuth = np.arctan2(z[:, 1], z[:, 0])
    x0 = np.stack([np.sin(azimuth), -np.cos(azimuth), np.zeros_like(azimuth)], axis=-1)
    y0 = np.cross(z, x0)
    roll = np.arctan2(np.sum(x * y0, axis=-1), np.sum(x * x0, axis=-1))
    yaw = 90.0 - np.degrees(azimuth)
    yaw = np.where(yaw > 180.0, yaw - 360.0, yaw)
    return Wgs84Poses(lat, lon, alt, yaw, np.degrees(pitch), np.degrees(roll))


# --------------------------------------------------------------------------- georef.yaml

def format_georef_yaml(georef: Georef, comment: str | None = None) -> str:
    """The text of ``georef.yaml`` (module docstring)."""
    lines = [f"# {c}" for c in (comment or "").splitlines()]
    lines += [f"latitude: {yaml_float(georef.latitude)}  # deg, WGS84",
              f"longitude: {yaml_float(georef.longitude)}  # deg, WGS84",
              f"altitude: {yaml_float(georef.altitude)}  # m, the photos' altitude datum",
              "frame: enu  # world x east, y north, z up [m] about this point"]
    if georef.time_origin is not None:
        lines.append(f"time_origin: {yaml_str(georef.time_origin)}  # camera time of t = 0")
    return "\n".join(lines) + "\n"


def read_georef_yaml(path: StrPath) -> Georef:
    """Read ``georef.yaml``.

    Raises:
        InputError: naming the file and key (missing, unknown, out of range - the ranges
            of :mod:`turbinefit.io.quantities`, which ``import dji`` applies to photos -,
            a frame other than ``enu``).
    """
    data = load_yaml_mapping(path)
    known = ("latitude", "longitude", "altitude", "frame", "time_origin")
    for key in data:
        if key not in known:
            raise InputError(f"unknown key (expected: {', '.join(known)})", path=path,
                             field=key)
    for key in known[:4]:
        if key not in data:
            raise InputError("missing", path=path, field=key)
    if data["frame"] != "enu":
        raise InputError(f"only 'enu' is supported, got {data['frame']!r}", path=path,
                         field="frame")
    from turbinefit.io.quantities import check_latlonalt

    lat, lon, alt = check_latlonalt(parse_number(data["latitude"], path, "latitude"),
                                    parse_number(data["longitude"], path, "longitude"),
                                    parse_number(data["altitude"], path, "altitude"), path)
    time_origin = data.get("time_origin")
    if time_origin is not None and not isinstance(time_origin, str):
        time_origin = str(time_origin)
    return Georef(lat, lon, alt, time_origin=time_origin)


def read_flight_georef(flight_dir: StrPath) -> Georef | None:
    """The flight folder's ``georef.yaml``, or None if it has none."""
    path = Path(flight_dir) / GEOREF_FILE
    return read_georef_yaml(path) if path.exists() else None


def turbine_location(path: StrPath) -> tuple[float, float] | None:
    """``(latitude, longitude)`` of a turbine file's base, if it gives them (as the
    ``turbine.yaml`` of a georeferenced fit does)."""
    data: dict[str, Any] = load_yaml_mapping(path)
    if "latitude" not in data and "longitude" not in data:
        return None
    lat, lon = (parse_number(data.get(k), path, k) for k in ("latitude", "longitude"))
    try:
        check_latlon(lat, lon)
    except ValueError as e:
        raise InputError(str(e), path=path) from None
    return lat, lon


def location_lines(georef: Georef, turbine: TurbineParams) -> str:
    """The ``latitude`` / ``longitude`` lines of the turbine's base for ``turbine.yaml``."""
    lat, lon, _ = georef.geodetic([turbine.base_x, turbine.base_y, 0.0])
    return (f"latitude: {float(lat):.10f}  # deg, WGS84, of the tower base\n"
            f"longitude: {float(lon):.10f}  # deg, WGS84, of the tower base\n")


# --------------------------------------------------------------------------- outputs

def format_wgs84_csv(georef: Georef, timestamps: ArrayLike, world_T_cam: SE3) -> str:
    """The text of ``keyframes_wgs84.csv``: the header, then one row per camera
    (timestamp [s], latitude and longitude [deg, 10 decimals], altitude [m], yaw, pitch,
    roll [deg])."""
    w = gimbal_from_world_T_cam(georef, world_T_cam)
    rows = [WGS84_HEADER]
    for row in zip(np.asarray(timestamps, np.float64).tolist(), w.latitude.tolist(),
                   w.longitude.tolist(), w.altitude.tolist(), w.yaw.tolist(),
                   w.pitch.tolist(), w.roll.tolist(), strict=True):
        t, lat, lon, alt, yaw, pitch, roll = row
        rows.append(f"{t:.6f},{lat:.10f},{lon:.10f},{alt:.4f},{yaw:.6f},{pitch:.6f},"
                    f"{roll:.6f}")
    return "\n".join(rows) + "\n"


def location_text(georef: Georef | None, turbine: TurbineParams) -> str:
    """What ``turbine.yaml`` of a fit or track gains on a georeferenced flight: the
    base's :func:`location_lines`; nothing without a georef."""
    return "" if georef is None else location_lines(georef, turbine)


#: The GIS files next to ``keyframes_wgs84.csv``: GDAL's sidecars (column types with the
#: coordinates marked, EPSG:4326) and the GeoJSON twin (:mod:`turbinefit.io.geojson`).
WGS84_SIDECARS = ("keyframes_wgs84.csvt", "keyframes_wgs84.prj", "keyframes_wgs84.geojson")
#: Column types of ``keyframes_wgs84.csv`` for GDAL's ``.csvt``.
WGS84_TYPES = {"timestamp": "Real", "latitude": "CoordY", "longitude": "CoordX",
               "altitude": "Real", "yaw": "Real", "pitch": "Real", "roll": "Real"}


def write_georef_outputs(out_dir: Path, georef: Georef | None, timestamps: ArrayLike,
                         world_T_cam: SE3) -> None:
    """On a georeferenced flight (``georef`` not None): write
    ``out_dir/keyframes_wgs84.csv`` and its GIS files (:data:`WGS84_SIDECARS`: it opens in
    QGIS and GDAL as EPSG:4326 points without being asked). Nothing without a georef."""
    from turbinefit.io.geojson import write_csv_sidecars, write_geojson_twin

    if georef is None:
        return
    text = format_wgs84_csv(georef, timestamps, world_T_cam)
    write_text_atomic(out_dir / WGS84_CSV, text, fsync=False)
    write_csv_sidecars(out_dir / WGS84_CSV, WGS84_HEADER, WGS84_TYPES)
    write_geojson_twin(out_dir / WGS84_CSV, text)
