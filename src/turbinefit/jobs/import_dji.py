"""The ``import dji`` job: DJI photos (their EXIF/XMP metadata) to a georeferenced flight
folder that ``fit`` and ``track`` read.

What each photo's metadata becomes (:mod:`turbinefit.io.dji` reads it,
:mod:`turbinefit.io.georef` states the conventions):

* **Timestamps**: seconds since the first photo, from EXIF ``DateTimeOriginal`` +
  ``SubSecTimeOriginal`` (camera local time without a zone, so only differences are
  used); the first photo's time is kept as ``time_origin`` in ``georef.yaml``. Keyframes
  are sorted by time; two photos at the same time are an error.
* **Positions**: WGS84 latitude, longitude (XMP, else EXIF GPS) and ``AbsoluteAltitude``
  (else EXIF ``GPSAltitude``) to east-north-up metres about the origin: ``origin`` if
  given, else the first photo's position at ground level (its altitude minus its
  ``RelativeAltitude``, i.e. the take-off point's height), written to ``georef.yaml``.
* **Attitude**: the gimbal angles (``GimbalYawDegree`` etc.; where the gimbal yaw is
  missing the aircraft's ``FlightYawDegree``, reported in the summary) to ``world_T_cam``
  (:func:`turbinefit.io.georef.world_T_cam_from_gimbal`), written to ``keyframes.txt``.
* **Camera** (``camera.yaml``, no distortion): ``CalibratedFocalLength`` and
  ``CalibratedOpticalCenterX``/``Y`` when present; else the 35 mm equivalent focal length
  over the image diagonal (``f = f35 * hypot(W, H) / hypot(36, 24)``), else
  ``FocalLength`` times ``FocalPlaneXResolution``; principal point at the image centre
  (``(W - 1) / 2``, ``(H - 1) / 2``). Every photo must give the same camera.
* **Photos**: ``images/<timestamp %.6f>.jpg``, hard links to the originals where the file
  system allows, else copies; the originals are never changed.
* **Turbine**: ``turbine_yaml`` is validated and copied in; when it gives ``latitude`` and
  ``longitude`` of the base (a georeferenced fit's ``turbine.yaml``), its base is moved to
  that position in this flight's frame. Without it the folder has no ``turbine.yaml``
  (``fit`` and ``track`` then estimate one). A turbine position alone
  (``turbine_location_deg``) makes ``turbine.yaml`` from the photos
  (:func:`turbinefit.jobs.init.init_folder` near that position, the photos detected by
  the CNN); a parameter they do not determine is refused and nothing is written.

Bad input (no photos, a non-JPEG, a photo without time, GPS or gimbal metadata, two
photos at one time, photos of two cameras, a bad turbine file) is an
:class:`~turbinefit.errors.InputError` naming the file, raised before anything is written.
The folder is written atomically (:func:`turbinefit.io.flight_folder.flight_output_dir`).
"""

from __future__ import annotations

import itertools
import math
import os
import shutil
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.io.atomic import StrPath, read_text, write_text_atomic
from turbinefit.io.camera_yaml import format_camera_yaml
from turbinefit.io.dji import DjiPhoto, list_photos, read_dji_photo
from turbinefit.io.flight_folder import (
    CAMERA_FILE,
    GEOREF_FILE,
    IMAGE_DIR,
    KEYFRAMES_FILE,
    TURBINE_FILE,
    check_flight_destination,
    flight_output_dir,
)
from turbinefit.io.georef import (
    Georef,
    format_georef_yaml,
    location_lines,
    turbine_location,
    world_T_cam_from_gimbal,
)
from turbinefit.io.heatmap_files import keyframe_stem
from turbinefit.io.tum import format_tum
from turbinefit.io.turbine_yaml import format_turbine_yaml, read_turbine_yaml
from turbinefit.jobs.outputs import OVERWRITE_HINT, check_not_input

#: Diagonal of a 35 mm film frame (36 x 24 mm) [mm]: the 35 mm equivalent focal length's
#: reference.
FILM_DIAGONAL_MM = math.hypot(36.0, 24.0)


@dataclass
class DjiImportSummary:
    """What ``import dji`` made (printed by the command).

    Attributes:
        out_dir: the flight folder written.
        num_photos: photos imported (= keyframes).
        camera: camera make and model; image_size: (W, H) [px].
        intrinsics: where the focal length came from.
        origin: the ENU origin; origin_source: how it was chosen.
        duration_s: time from the first photo to the last [s].
        flight_yaw: photos whose gimbal yaw was missing (the aircraft's yaw used).
        position_from_exif: photos whose position came from the EXIF GPS block.
        images: how ``images/`` was filled: ``hard links``, ``copies`` or both.
        turbine: what ``turbine.yaml`` is, or None (not written).
        timings: seconds per stage (read, write, total).
    """

    out_dir: str
    num_photos: int
    camera: str
    image_size: tuple[int, int]
    intrinsics: str
    origin: Georef
    origin_source: str
    duration_s: float
    flight_yaw: list[str] = field(default_factory=list)
    position_from_exif: list[str] = field(default_factory=list)
    images: str = ""
    turbine: str | None = None
    timings: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def import_dji(
    inputs: Sequence[StrPath],
    out_dir: StrPath,
    *,
    origin: tuple[float, float, float] | None = None,
    turbine_yaml: StrPath | None = None,
    turbine_location_deg: tuple[float, float] | None = None,
    overwrite: bool = False,
) -> DjiImportSummary:
    """Make the flight folder ``out_dir`` from DJI photos (module docstring).

    Args:
        inputs: photos and folders of photos (folders: their ``.jpg``/``.jpeg`` files).
        out_dir: the flight folder to write; an existing non-empty one only with
            ``overwrite`` and only if it holds nothing but a flight folder's entries.
        origin: (latitude [deg], longitude [deg], altitude [m]) of the ENU origin; None =
            the first photo's position at ground level.
        turbine_yaml: a turbine file to copy in as ``turbine.yaml``.
        turbine_location_deg: (latitude, longitude) of the turbine's base: turbine.yaml
            is estimated from the photos near it (``turbinefit init --near``).

    Raises:
        InputError: naming the file of the first problem; nothing is written then.
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    paths = [Path(p) for p in inputs]
    turbine_path = None if turbine_yaml is None else Path(turbine_yaml)
    if not paths:
        raise InputError("no photos given", field="import dji")
    check_not_input(out, paths + ([turbine_path] if turbine_path is not None else []))
    check_flight_destination(out, overwrite, OVERWRITE_HINT)

    photos = sorted_by_time([read_dji_photo(p) for p in list_photos(paths)])
    meta = np.array([photo_pose(photo) for photo in photos])  # (N, 6)
    camera, intrinsics = flight_camera(photos)
    if origin is None:
        georef = ground_origin(photos[0])
        origin_source = f"the first photo, {photos[0].path.name}, at ground level"
    else:
        georef = _georef(*origin)
        origin_source = "given"
    first_time = photos[0].time
    assert first_time is not None  # check_photo
    georef = replace(georef, time_origin=first_time.isoformat(timespec="microseconds"))
    timestamps = np.array([(p.time - first_time).total_seconds()  # type: ignore[operator]
                           for p in photos])
    world_T_cam = world_T_cam_from_gimbal(georef, *meta.T)
    turbine_text, turbine_note = _turbine(turbine_path, georef)
    near_xy = (None if turbine_location_deg is None
               else _flight_position(georef, *turbine_location_deg))

    texts = {
        CAMERA_FILE: format_camera_yaml(camera, name=photos[0].camera_name),
        KEYFRAMES_FILE: format_tum(timestamps, world_T_cam, out / KEYFRAMES_FILE,
                                   "world_T_cam of each photo (turbinefit import dji)"),
        GEOREF_FILE: format_georef_yaml(georef, "turbinefit import dji: the world frame's "
                                        "origin (east-north-up, metres)"),
    }
    if turbine_text is not None:
        texts[TURBINE_FILE] = turbine_text
    t1 = time.perf_counter()
    with flight_output_dir(out, overwrite) as tmp:
        for name, text in texts.items():
            write_text_atomic(tmp / name, text, fsync=False)
        how = link_photos([p.path for p in photos], timestamps, tmp / IMAGE_DIR, out / IMAGE_DIR)
        if near_xy is not None:  # turbine.yaml from the photos, near that position
            turbine_note = _initialise(tmp, out, near_xy, georef)
    t2 = time.perf_counter()
    return DjiImportSummary(
        str(out), len(photos), photos[0].camera_name, (camera.width, camera.height),
        intrinsics, georef, origin_source, float(timestamps[-1]),
        flight_yaw=[p.path.name for p in photos if p.gimbal_yaw is None],
        position_from_exif=[p.path.name for p in photos if p.position_source == "exif"],
        images=how, turbine=turbine_note,
        timings={"read": t1 - t0, "write": t2 - t1, "total": t2 - t0})


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
        raise InputError("no gimbal attitude (XMP drone-dji:GimbalPitchDegree and "
                         "GimbalRollDegree)", path=photo.path)
    if photo.gimbal_yaw is None and photo.flight_yaw is None:
        raise InputError("no yaw (XMP drone-dji:GimbalYawDegree or FlightYawDegree)",
                         path=photo.path)
    if photo.orientation not in (None, 1):
        raise InputError(f"EXIF Orientation {photo.orientation}: rotated photos are not "
                         "supported", path=photo.path)
    try:
        Georef(photo.latitude, photo.longitude, photo.altitude)
    except ValueError as e:
        raise InputError(str(e), path=photo.path) from None
    yaw = photo.gimbal_yaw if photo.gimbal_yaw is not None else photo.flight_yaw
    assert yaw is not None
    return (photo.latitude, photo.longitude, photo.altitude, yaw, photo.gimbal_pitch,
            photo.gimbal_roll)


def photo_intrinsics(photo: DjiPhoto) -> tuple[float, float, float, str]:
    """``(f, cx, cy)`` [px] of one photo and where ``f`` came from (module docstring).

    Raises:
        InputError: naming the photo if it gives no focal length.
    """
    w, h = photo.width, photo.height
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    if photo.calibrated_focal_px is not None and photo.calibrated_focal_px > 0:
        return (photo.calibrated_focal_px,
                cx if photo.calibrated_cx is None else photo.calibrated_cx,
                cy if photo.calibrated_cy is None else photo.calibrated_cy,
                "calibrated (XMP drone-dji:CalibratedFocalLength)")
    if photo.focal_35mm is not None:
        return (photo.focal_35mm * math.hypot(w, h) / FILM_DIAGONAL_MM, cx, cy,
                "35 mm equivalent focal length (EXIF FocalLengthIn35mmFilm)")
    if photo.focal_length_mm is not None and photo.focal_plane_px_per_mm is not None:
        return (photo.focal_length_mm * photo.focal_plane_px_per_mm, cx, cy,
                "EXIF FocalLength and FocalPlaneXResolution")
    raise InputError("no focal length (XMP drone-dji:CalibratedFocalLength, EXIF "
                     "FocalLengthIn35mmFilm, or FocalLength with FocalPlaneXResolution)",
                     path=photo.path)


def flight_camera(photos: list[DjiPhoto]) -> tuple[PinholeCamera, str]:
    """The one camera of all photos and where its focal length came from.

    Raises:
        InputError: naming two photos of different cameras (model, size or intrinsics).
    """
    def describe(p: DjiPhoto, f: float) -> str:
        return f"{p.camera_name}, {p.width}x{p.height}, f {f:.1f} px"

    first = photos[0]
    f0, cx0, cy0, source = photo_intrinsics(first)
    for p in photos[1:]:
        f, cx, cy, _ = photo_intrinsics(p)
        same = ((p.camera_name, p.width, p.height) == (first.camera_name, first.width,
                                                         first.height)
                and np.allclose([f, cx, cy], [f0, cx0, cy0], rtol=1e-6, atol=1e-6))
        if not same:
            raise InputError(f"photos of more than one camera: {first.path} "
                             f"({describe(first, f0)}) and this one ({describe(p, f)}); "
                             "import each camera's photos into its own flight folder",
                             path=p.path)
    camera = PinholeCamera(first.width, first.height, f0, f0, cx0, cy0)
    return camera, source


def ground_origin(photo: DjiPhoto) -> Georef:
    """The photo's position at ground level: its altitude minus its relative altitude.

    Raises:
        InputError: naming the photo if it has no ``RelativeAltitude``.
    """
    if photo.relative_altitude is None:
        raise InputError("no XMP drone-dji:RelativeAltitude to find the ground under the "
                         "first photo; give --origin LAT,LON,ALT", path=photo.path)
    assert photo.latitude is not None and photo.longitude is not None
    assert photo.altitude is not None
    return Georef(photo.latitude, photo.longitude, photo.altitude - photo.relative_altitude)


def _georef(latitude: float, longitude: float, altitude: float) -> Georef:
    try:
        return Georef(latitude, longitude, altitude)
    except ValueError as e:
        raise InputError(str(e), field="--origin") from None


def _turbine(path: Path | None, georef: Georef) -> tuple[str | None, str | None]:
    """The text of ``turbine.yaml`` and what it is (None, None without a file)."""
    if path is None:
        return None, None
    params = read_turbine_yaml(path)
    location = turbine_location(path)
    if location is None:
        return read_text(path), f"copied from {path}"
    x, y, _ = georef.enu(location[0], location[1], georef.altitude)
    params = replace(params, base_x=float(x), base_y=float(y))
    text = format_turbine_yaml(params, f"turbinefit import dji: {path}, its base moved to "
                               "its latitude/longitude in this flight's frame", path)
    return (text + location_lines(georef, params),
            f"from {path}, base at its latitude/longitude: ({float(x):.2f}, {float(y):.2f}) m")


def _flight_position(georef: Georef, latitude: float, longitude: float
                     ) -> tuple[float, float]:
    """A turbine given by its position (``--turbine``), in the flight's frame."""
    try:
        Georef(latitude, longitude, georef.altitude)
    except ValueError as e:
        raise InputError(str(e), field="--turbine") from None
    x, y, _ = georef.enu(latitude, longitude, georef.altitude)
    return float(x), float(y)


def _initialise(tmp: Path, out: Path, near_xy: tuple[float, float], georef: Georef) -> str:
    """Write ``tmp/turbine.yaml`` estimated from the photos (``turbinefit init --near``
    the turbine's position; the CNN detects every photo); what it is, in words. A parameter
    the photos do not determine is an InputError naming ``out`` (nothing is written)."""
    from turbinefit.jobs.init import init_folder
    from turbinefit.solver.init import TurbinePrior

    try:
        report = init_folder(tmp, tmp / TURBINE_FILE, TurbinePrior(near_xy=near_xy),
                             from_images=True)
    except InputError as e:
        raise InputError(str(e).replace(str(tmp), str(out)) + " (or give --turbine-yaml)",
                         field="--turbine") from None
    with open(tmp / TURBINE_FILE, "a", encoding="utf-8") as f:
        f.write(location_lines(georef, report.summary.turbine))
    return (f"estimated from the photos near ({near_xy[0]:.2f}, {near_xy[1]:.2f}) m "
            f"(turbinefit init, {report.summary.keyframes_seen} photos showing it)")


def link_photos(sources: list[Path], timestamps: np.ndarray, tmp_dir: Path,
                final_dir: Path) -> str:
    """Fill ``tmp_dir`` with ``<timestamp %.6f>.jpg`` hard links to ``sources`` (copies
    where the file system refuses a link); ``final_dir`` names errors. Returns how."""
    tmp_dir.mkdir()
    links = copies = 0
    for src, t in zip(sources, timestamps.tolist(), strict=True):
        dst = tmp_dir / (keyframe_stem(t) + ".jpg")
        try:
            os.link(src, dst)
            links += 1
            continue
        except OSError:
            pass
        try:
            shutil.copyfile(src, dst)
        except OSError as e:
            raise InputError(f"cannot copy {src}: {e.strerror or e}",
                             path=final_dir / dst.name) from e
        copies += 1
    return " and ".join(f"{n} {what}" for n, what in ((links, "hard links"),
                                                        (copies, "copies")) if n)
