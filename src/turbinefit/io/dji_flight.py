"""DJI photos' metadata as flights (for :mod:`turbinefit.jobs.import_dji`): which camera
took each photo and the one picked, the flights they split into, their times, positions
and attitudes as poses, the positions checked, the camera's intrinsics and the RTK
standard deviations. Bad metadata is an :class:`~turbinefit.errors.InputError` naming
the photo and the tag."""

from __future__ import annotations

import itertools
import math
import re

import numpy as np

from turbinefit.errors import InputError, plain_number
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.io.camera_yaml import check_camera
from turbinefit.io.dji import DjiPhoto
from turbinefit.io.dji_cameras import KINDS, find_camera
from turbinefit.io.georef import Georef
from turbinefit.io.quantities import check_latlonalt

#: Diagonal of a 35 mm film frame (36 x 24 mm) [mm]: the 35 mm equivalent focal length's
#: reference.
FILM_DIAGONAL_MM = math.hypot(36.0, 24.0)
#: The aspect ratio (width / height) of the sensor assumed behind a 35 mm equivalent focal
#: length when the camera is not in the table: most drone cameras' sensors are 4:3.
SENSOR_ASPECT = 4.0 / 3.0

#: Largest distance [m] of a photo from its flight's median position: beyond any drone's
#: radio range (DJI's enterprise drones: 15-20 km); a photo farther away has a wrong
#: position (a flipped sign or hemisphere, no GPS fix) and is left out.
MAX_FLIGHT_RADIUS_M = 20_000.0

#: Kinds of camera told by a file name's suffix (DJI's multi-camera payloads).
_SUFFIX_KINDS = {"W": "wide", "Z": "zoom", "T": "thermal", "R": "thermal"}
#: Kinds of camera told by XMP ``ImageSource``.
_SOURCE_KINDS = {"widecamera": "wide", "zoomcamera": "zoom", "infraredcamera": "thermal",
                 "visualcamera": "wide"}
#: RTK position standard deviations' floors [m] (horizontal, vertical) per solution:
#: what each solution is trusted to at best, whatever the receiver says (DJI's manuals:
#: fixed "centimetre level", float "decimetre to metre level", single point "metre level";
#: single-point and no-RTK errors drift together over a flight, so their priors are kept
#: weak, as ``FitConfig.gps_sigma``).
RTK_SIGMA_FLOOR = {"fixed": (0.02, 0.03), "float": (0.3, 0.5), "single": (3.0, 5.0)}


def camera_kind(photo: DjiPhoto) -> str:
    """``wide``, ``zoom``, ``thermal`` or '' (unknown): from the camera table, else XMP
    ``ImageSource``, else the file name's suffix (``DJI_0001_W.JPG``)."""
    cam = find_camera(photo.make, photo.model, photo.width, photo.focal_length_mm)
    if cam is not None:
        return cam.kind
    kind = _SOURCE_KINDS.get(photo.image_source.lower())
    if kind is not None:
        return kind
    m = re.search(r"_([A-Za-z])$", photo.path.stem)
    return _SUFFIX_KINDS.get(m.group(1).upper(), "") if m else ""


def camera_label(photo: DjiPhoto) -> str:
    """The camera of a photo in words: ``DJI ZH20T thermal``."""
    kind = camera_kind(photo)
    return f"{photo.camera_name} {kind}" if kind else photo.camera_name


def pick_camera(photos: list[DjiPhoto], camera: str | None) -> tuple[list[DjiPhoto], list[str]]:
    """The photos of one camera (``camera``: a kind or a name; None: the only one) and the
    cameras left aside, in words.

    Raises:
        InputError: for photos of several cameras and no choice, or a choice none matches
            or that matches several, naming each camera with its count and first photo.
    """
    groups: dict[tuple[str, int, int], list[DjiPhoto]] = {}
    for p in photos:
        groups.setdefault((camera_label(p), p.width, p.height), []).append(p)

    def describe(key: tuple[str, int, int]) -> str:
        g = groups[key]
        return f"{key[0]} {key[1]}x{key[2]} ({len(g)} photos, first {g[0].path})"

    keys = list(groups)
    if camera is not None:
        want = camera.strip().lower()
        keys = [k for k in keys if (want in KINDS and camera_kind(groups[k][0]) == want)
                or want in (groups[k][0].model.lower(), groups[k][0].camera_name.lower(),
                            k[0].lower())]
        if not keys:
            raise InputError(f"no photos of camera {camera!r} among "
                             f"{'; '.join(describe(k) for k in groups)}", field="--camera")
    if len(keys) > 1:
        raise InputError(f"photos of {len(keys)} cameras: {'; '.join(describe(k) for k in keys)}; "
                         "pick one with --camera wide|zoom|thermal|MODEL", field="--camera"
                         if camera is not None else None,
                         path=None if camera is not None else groups[keys[1]][0].path)
    others = [describe(k) for k in groups if k != keys[0]]
    return groups[keys[0]], others


def split_flights(photos: list[DjiPhoto], max_gap_s: float) -> list[list[DjiPhoto]]:
    """Photos in time order split where more than ``max_gap_s`` passes between two.

    Raises:
        InputError: for a photo alone in its flight among several (a wrong clock, or a
            stray photo), naming it and how far in time it is from the others.
    """
    groups: list[list[DjiPhoto]] = [[photos[0]]]
    for a, b in itertools.pairwise(photos):
        gap = (b.time - a.time).total_seconds()  # type: ignore[operator]
        if gap > max_gap_s:
            groups.append([])
        groups[-1].append(b)
    if len(groups) > 1:
        for g in groups:
            if len(g) == 1:
                p = g[0]
                raise InputError(
                    f"taken {_time_apart(p, photos)} from any other photo (DateTimeOriginal "
                    f"{p.time}), alone in a flight of its own (flights are split at pauses "
                    f"over {plain_number(max_gap_s)} s): a wrong clock? leave it out of the "
                    "photos given, or raise --max-gap", path=p.path)
    return groups


def _time_apart(p: DjiPhoto, photos: list[DjiPhoto]) -> str:
    s = min(abs((q.time - p.time).total_seconds())  # type: ignore[operator]
            for q in photos if q is not p)
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if s >= size:
            return f"{s / size:.1f} {unit}"
    return f"{s:.1f} s"


def check_positions(photos: list[DjiPhoto]) -> None:
    """Refuse a flight with a photo at latitude and longitude 0, 0 (no GPS fix) or farther
    than :data:`MAX_FLIGHT_RADIUS_M` from the photos' median position (a flipped sign or
    hemisphere), naming the photo and the distance.

    Raises:
        InputError: naming the first such photo.
    """
    lat = np.array([p.latitude for p in photos], dtype=np.float64)
    lon = np.array([p.longitude for p in photos], dtype=np.float64)
    alt = np.array([p.altitude for p in photos], dtype=np.float64)
    null = (lat == 0.0) & (lon == 0.0)
    if null.all():
        raise InputError(f"every photo of the flight ({len(photos)}) is at latitude 0, "
                         "longitude 0: the drone had no GPS fix", path=photos[0].path)
    good = ~null
    centre = Georef(float(np.median(lat[good])), float(np.median(lon[good])),
                    float(np.median(alt[good])))
    dist = np.linalg.norm(centre.enu(lat, lon, alt), axis=-1)
    far = null | (dist > MAX_FLIGHT_RADIUS_M)
    if not far.any():
        return
    k = int(np.flatnonzero(far)[0])
    why = ("at latitude 0, longitude 0: no GPS fix" if null[k] else
           f"{dist[k] / 1000:.0f} km from the flight's other photos (their median position; "
           f"a flight stays within {MAX_FLIGHT_RADIUS_M / 1000:g} km): a wrong position")
    raise InputError(f"{why} ({int(far.sum())} of {len(photos)} photos so); leave it out "
                     "of the photos given", path=photos[k].path)


def check_near(georef: Georef, photos: list[DjiPhoto]) -> None:
    """Refuse an origin farther than :data:`MAX_FLIGHT_RADIUS_M` from the photos."""
    lat = np.median([p.latitude for p in photos])
    lon = np.median([p.longitude for p in photos])
    d = float(np.hypot(*georef.enu(lat, lon, georef.altitude)[:2]))
    if d > MAX_FLIGHT_RADIUS_M:
        raise InputError(f"{d / 1000:.0f} km from the photos (their median position); the "
                         f"origin must lie within {MAX_FLIGHT_RADIUS_M / 1000:g} km of them",
                         field="--origin")


def rtk_sigmas(photos: list[DjiPhoto]) -> tuple[np.ndarray | None, str | None]:
    """(N, 3) position standard deviations [m] (east, north, up) of the photos from their
    RTK status, and the solutions counted in words; (None, None) when no photo has an
    ``RtkFlag``.

    Per photo: ``RtkStdLon``, ``RtkStdLat``, ``RtkStdHgt`` (0 or missing: unknown) raised
    to the floor of its solution (:data:`RTK_SIGMA_FLOOR`): ``RtkFlag`` 50 fixed, 32-49
    float, anything else (16 single point, 0 none, or no flag) single.
    """
    if all(p.rtk_flag in (None, 0) for p in photos):
        return None, None
    out = np.empty((len(photos), 3))
    counts: dict[str, int] = {}
    for k, p in enumerate(photos):
        flag = p.rtk_flag if p.rtk_flag is not None else 0
        kind = "fixed" if flag == 50 else "float" if 32 <= flag <= 49 else "single"
        counts[kind] = counts.get(kind, 0) + 1
        h, v = RTK_SIGMA_FLOOR[kind]
        out[k] = [max(p.rtk_std_lon or 0.0, h), max(p.rtk_std_lat or 0.0, h),
                  max(p.rtk_std_hgt or 0.0, v)]
    words = ", ".join(f"{counts[k]} {k}" for k in ("fixed", "float", "single") if k in counts)
    return out, f"RTK {words}"


def sorted_by_time(photos: list[DjiPhoto]) -> list[DjiPhoto]:
    """The photos in time order.

    Raises:
        InputError: for no photos, a photo without ``DateTimeOriginal`` or two photos at
            the same time (naming both).
    """
    for p in photos:
        if p.time is None:
            raise InputError("no EXIF DateTimeOriginal: cannot place the photo in time",
                             path=p.path)
    out = sorted(photos, key=lambda p: p.time)  # type: ignore[arg-type,return-value]
    for a, b in itertools.pairwise(out):
        if a.time == b.time:
            raise InputError(f"taken at the same time as {a.path} ({b.time}): two keyframes "
                             "need two timestamps", path=b.path)
    return out


def photo_pose(photo: DjiPhoto) -> tuple[float, float, float, float, float, float]:
    """(latitude, longitude, altitude, yaw, pitch, roll) of a photo: its position and its
    gimbal angles, the flight yaw where the gimbal yaw is missing.

    Raises:
        InputError: naming the photo if it lacks a position or an attitude, or is stored
            rotated.
    """
    if photo.latitude is None or photo.longitude is None:
        raise InputError("no GPS position (XMP drone-dji:GpsLatitude/GpsLongitude or the "
                         "EXIF GPS block)", path=photo.path)
    if photo.altitude is None:
        raise InputError("no altitude (XMP drone-dji:AbsoluteAltitude or EXIF GPSAltitude)",
                         path=photo.path)
    if photo.gimbal_pitch is None or photo.gimbal_roll is None:
        missing = " and ".join(n for n, v in (("GimbalPitchDegree", photo.gimbal_pitch),
                                              ("GimbalRollDegree", photo.gimbal_roll))
                               if v is None)
        raise InputError(f"no gimbal attitude (XMP drone-dji:{missing}): the camera's "
                         "orientation is unknown; this drone's photos cannot be imported",
                         path=photo.path)
    if photo.gimbal_yaw is None and photo.flight_yaw is None:
        raise InputError("no yaw (XMP drone-dji:GimbalYawDegree or FlightYawDegree)",
                         path=photo.path)
    if photo.orientation not in (None, 1):
        raise InputError(f"EXIF Orientation {photo.orientation}: rotated photos are not "
                         "supported", path=photo.path)
    yaw = photo.gimbal_yaw if photo.gimbal_yaw is not None else photo.flight_yaw
    assert yaw is not None
    return (photo.latitude, photo.longitude, photo.altitude, yaw, photo.gimbal_pitch,
            photo.gimbal_roll)


def photo_camera(photo: DjiPhoto) -> tuple[PinholeCamera, str, str | None]:
    """The camera of one photo, where it came from, and (for a crop of a sensor assumed
    4:3) how the photo was placed on it (module docstring).

    Raises:
        InputError: naming the photo if it gives no focal length, or the field its camera
            came from if that camera is implausible (the check of ``camera.yaml``).
    """
    w, h = photo.width, photo.height
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    crop = None
    d = photo.dewarp
    if d is not None:
        undistorted = photo.dewarp_flag == 1
        cam = PinholeCamera(w, h, d.fx, d.fy, w / 2.0 + d.cx_offset, h / 2.0 + d.cy_offset,
                            distortion=(0.0,) * 5 if undistorted else d.distortion)
        field = "drone-dji:DewarpData"
        source = (f"DJI's calibration (XMP {field}{', ' + d.date if d.date else ''}"
                  + (": the photo was undistorted in the camera (DewarpFlag 1)"
                     if undistorted else ", with its distortion") + ")")
    elif photo.calibrated_focal_px is not None:
        cam = PinholeCamera(w, h, photo.calibrated_focal_px, photo.calibrated_focal_px,
                            cx if photo.calibrated_cx is None else photo.calibrated_cx,
                            cy if photo.calibrated_cy is None else photo.calibrated_cy)
        field = "drone-dji:CalibratedFocalLength"
        source = f"calibrated (XMP {field})"
    else:
        table = find_camera(photo.make, photo.model, w, photo.focal_length_mm)
        f = None if table is None else table.focal_px(w, photo.focal_length_mm)
        if table is not None and f is not None:
            mm = photo.focal_length_mm or table.focal_range_mm[0]
            field = "EXIF FocalLength" if photo.focal_length_mm else "the camera table"
            source = (f"the camera table: {table.name}, {plain_number(round(mm, 3))} mm on "
                      f"{plain_number(table.sensor_width_mm)} mm across {w} px")
        elif photo.focal_35mm is not None:
            field = "EXIF FocalLengthIn35mmFilm"
            frame_w, frame_h = (w, w / SENSOR_ASPECT) if w / h > SENSOR_ASPECT + 1e-3 else (w, h)
            if frame_h != h:
                crop = (f"the {w}x{h} photo taken as a crop of a 4:3 sensor "
                        f"{w}x{round(frame_h)} px (the 35 mm equivalent is the full frame's)")
            f = photo.focal_35mm * math.hypot(frame_w, frame_h) / FILM_DIAGONAL_MM
            source = "35 mm equivalent focal length (EXIF FocalLengthIn35mmFilm)"
        elif photo.focal_length_mm is not None and photo.focal_plane_px_per_mm is not None:
            f = photo.focal_length_mm * photo.focal_plane_px_per_mm
            field = "EXIF FocalPlaneXResolution"
            source = "EXIF FocalLength and FocalPlaneXResolution"
        else:
            raise InputError(f"no focal length: {photo.camera_name} {w}x{h} is not in the "
                             "camera table and its metadata has none (XMP drone-dji:"
                             "CalibratedFocalLength, EXIF FocalLengthIn35mmFilm, or "
                             "FocalLength with FocalPlaneXResolution)", path=photo.path)
        cam = PinholeCamera(w, h, f, f, cx, cy)
    return check_camera(cam, photo.path, field), source, crop


def flight_camera(photos: list[DjiPhoto]) -> tuple[PinholeCamera, str, str | None]:
    """The one camera of all photos, where it came from and the crop note.

    Raises:
        InputError: naming two photos of different cameras (model, size or intrinsics).
    """
    def describe(p: DjiPhoto, c: PinholeCamera) -> str:
        return f"{p.camera_name}, {p.width}x{p.height}, f {c.fx:.1f} px"

    first = photos[0]
    cam0, source, crop = photo_camera(first)
    k0 = np.array([cam0.fx, cam0.fy, cam0.cx, cam0.cy, *cam0.distortion])
    for p in photos[1:]:
        cam, _, _ = photo_camera(p)
        k = np.array([cam.fx, cam.fy, cam.cx, cam.cy, *cam.distortion])
        same = ((p.camera_name, p.width, p.height) == (first.camera_name, first.width,
                                                         first.height)
                and np.allclose(k, k0, rtol=1e-6, atol=1e-6))
        if not same:
            raise InputError(f"photos of more than one camera: {first.path} "
                             f"({describe(first, cam0)}) and this one ({describe(p, cam)}); "
                             "import each camera's photos into its own flight folder",
                             path=p.path)
    return cam0, source, crop


def ground_origin(photo: DjiPhoto) -> Georef:
    """The photo's position at ground level: its altitude minus its relative altitude.

    Raises:
        InputError: naming the photo if it has no ``RelativeAltitude``, or if the ground
            would lie at an altitude out of range.
    """
    if photo.relative_altitude is None:
        raise InputError("no XMP drone-dji:RelativeAltitude to find the ground under the "
                         "first photo; give --origin LAT,LON,ALT", path=photo.path)
    assert photo.latitude is not None and photo.longitude is not None
    assert photo.altitude is not None
    lat, lon, alt = check_latlonalt(photo.latitude, photo.longitude,
                                    photo.altitude - photo.relative_altitude, photo.path,
                                    prefix="ground (AbsoluteAltitude - RelativeAltitude) ")
    return Georef(lat, lon, alt)
