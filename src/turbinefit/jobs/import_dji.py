"""The ``import dji`` job: DJI photos (their EXIF/XMP metadata) to georeferenced flight
folders that ``fit`` and ``track`` read.

What each photo's metadata becomes (:mod:`turbinefit.io.dji` reads it,
:mod:`turbinefit.io.georef` states the conventions; docs/import.md says it for users):

* **Cameras**: photos are grouped by camera (EXIF make and model, the kind of camera -
  wide, zoom or thermal - from the camera table, XMP ``ImageSource`` or a file name suffix
  ``_W``/``_Z``/``_T``, and the image size). Photos of several cameras (the wide, zoom and
  thermal photos of one H20T capture) are refused, naming each, unless ``camera`` picks one.
* **Flights**: the chosen camera's photos, sorted by EXIF ``DateTimeOriginal`` +
  ``SubSecTimeOriginal``, are split where more than ``max_gap_s`` passes between two
  photos. One flight is written to ``out_dir``; several to ``out_dir/flight-1``,
  ``flight-2``, ... (each a flight folder of its own, all written at once); a flight of one
  photo among several flights (a photo whose clock is off) is left out and named.
* **Timestamps**: seconds since the flight's first photo (camera local time without a
  zone, so only differences are used); the first photo's time is kept as ``time_origin``
  in ``georef.yaml``. Two photos at the same time are an error.
* **Positions**: WGS84 latitude, longitude (XMP, else EXIF GPS) and ``AbsoluteAltitude``
  (else EXIF ``GPSAltitude``) to east-north-up metres about the origin: ``origin`` if
  given, else the flight's first photo at ground level (its altitude minus its
  ``RelativeAltitude``), written to ``georef.yaml``. A photo farther than
  :data:`MAX_FLIGHT_RADIUS_M` from the flight's median position (or at latitude and
  longitude 0, 0: no GPS fix) is refused, naming it, and so is an ``origin`` that far
  from the photos.
* **Attitude**: the gimbal angles (``GimbalYawDegree`` etc.; where the gimbal yaw is
  missing the aircraft's ``FlightYawDegree``, reported in the summary) to ``world_T_cam``
  (:func:`turbinefit.io.georef.world_T_cam_from_gimbal`), written to ``keyframes.txt``.
* **Camera** (``camera.yaml``, :func:`turbinefit.io.dji_flight.photo_camera`): DJI's calibration
  (``DewarpData``: intrinsics and OpenCV distortion), else ``CalibratedFocalLength`` and
  ``CalibratedOpticalCenterX``/``Y``, else the camera table
  (:mod:`turbinefit.io.dji_cameras`: the lens on the sensor's width), else the 35 mm
  equivalent focal length over the sensor's full frame (taken as 4:3: a wider photo is a
  crop of it, and the summary says so), else ``FocalLength`` times
  ``FocalPlaneXResolution``. Every camera passes the check ``camera.yaml`` passes
  (:func:`turbinefit.io.camera_yaml.check_camera`); every photo of a flight must give the
  same camera.
* **RTK**: when the photos carry ``RtkFlag``, each keyframe's position standard
  deviations (:func:`turbinefit.io.dji_flight.rtk_sigmas`) go to ``keyframes_sigma.csv``
  (:mod:`turbinefit.io.flight_folder`), which ``fit`` and ``track`` turn into position
  priors.
* **Photos**: ``images/<timestamp %.6f>.jpg``, hard links to the originals (to the files
  symbolic links lead to) where the file system allows, else copies; the originals are
  never changed.
* **Turbine**: ``turbine_yaml`` is validated and copied in; when it gives ``latitude`` and
  ``longitude`` of the base (a georeferenced fit's ``turbine.yaml``), its base is moved to
  that position in the flight's frame. A turbine position alone
  (``turbine_location_deg``) makes ``turbine.yaml`` from the photos
  (:func:`turbinefit.jobs.init.init_folder` near that position, the photos detected by
  the CNN); a parameter they do not determine is refused and nothing is written.

Bad input is an :class:`~turbinefit.errors.InputError` naming the file (and field), raised
before anything is written; the output is written atomically.
"""

from __future__ import annotations

import os
import re
import shutil
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from turbinefit.errors import InputError
from turbinefit.io.atomic import (
    StrPath,
    atomic_output_dir,
    check_output_dir,
    read_text,
    write_text_atomic,
)
from turbinefit.io.camera_yaml import format_camera_yaml
from turbinefit.io.dji import DjiPhoto, list_photos, read_dji_photo
from turbinefit.io.dji_flight import (
    camera_label,
    check_near,
    check_positions,
    flight_camera,
    ground_origin,
    photo_pose,
    pick_camera,
    rtk_sigmas,
    sorted_by_time,
    split_flights,
)
from turbinefit.io.flight_folder import (
    CAMERA_FILE,
    GEOREF_FILE,
    IMAGE_DIR,
    KEYFRAMES_FILE,
    SIGMA_FILE,
    TURBINE_FILE,
    format_position_sigmas,
    only_flight_entries,
)
from turbinefit.io.georef import (
    Georef,
    format_georef_yaml,
    location_lines,
    turbine_location,
    world_T_cam_from_gimbal,
)
from turbinefit.io.heatmap_files import keyframe_stem
from turbinefit.io.quantities import Quantity, check_latlonalt
from turbinefit.io.tum import format_tum
from turbinefit.io.turbine_yaml import format_turbine_yaml, read_turbine_yaml
from turbinefit.jobs.outputs import OVERWRITE_HINT, check_not_input

#: Default longest pause between two photos of one flight [s] (``--max-gap``).
DEFAULT_MAX_GAP_S = 600.0
#: ``--max-gap``: a pause [s] (at most about 30 years).
MAX_GAP = Quantity("gap between flights", "s", 0.0, 1e9, lo_open=True)
#: Name of the k-th flight's folder when the photos hold several flights.
FLIGHT_DIR = "flight-{}"


@dataclass
class DjiFlightSummary:
    """One flight folder ``import dji`` wrote.

    Attributes:
        out_dir: the flight folder.
        num_photos: photos imported (= keyframes).
        first_photo: the name of its first photo.
        intrinsics: where the camera came from.
        crop: how a cropped photo was placed on its sensor, or None.
        origin: the ENU origin; origin_source: how it was chosen.
        duration_s: time from the first photo to the last [s].
        rtk: what ``keyframes_sigma.csv`` holds (solutions counted), or None (no RTK).
        flight_yaw: photos whose gimbal yaw was missing (the aircraft's yaw used).
        position_from_exif: photos whose position came from the EXIF GPS block.
        images: how ``images/`` was filled: ``hard links``, ``copies`` or both.
        turbine: what ``turbine.yaml`` is, or None (not written).
    """

    out_dir: str
    num_photos: int
    first_photo: str
    intrinsics: str
    crop: str | None
    origin: Georef
    origin_source: str
    duration_s: float
    rtk: str | None = None
    flight_yaw: list[str] = field(default_factory=list)
    position_from_exif: list[str] = field(default_factory=list)
    images: str = ""
    turbine: str | None = None


@dataclass
class DjiImportSummary:
    """What ``import dji`` made (printed by the command).

    Attributes:
        out_dir: the output folder: the flight folder, or the folder of flight folders.
        camera: camera make, model and kind; image_size: (W, H) [px].
        flights: each flight folder written.
        other_cameras: photos of other cameras not imported (``camera`` picked one).
        timings: seconds per stage (read, write, total).
    """

    out_dir: str
    camera: str
    image_size: tuple[int, int]
    flights: list[DjiFlightSummary]
    other_cameras: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def num_photos(self) -> int:
        return sum(f.num_photos for f in self.flights)

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
    camera: str | None = None,
    max_gap_s: float = DEFAULT_MAX_GAP_S,
) -> DjiImportSummary:
    """Make flight folders from DJI photos (module docstring).

    Args:
        inputs: photos and folders of photos (folders: their ``.jpg``/``.jpeg`` files).
        out_dir: where to write: the flight folder, or with several flights the folder of
            ``flight-1``, ``flight-2``, ...; an existing non-empty one only with
            ``overwrite`` and only if it holds nothing but what this writes.
        origin: (latitude [deg], longitude [deg], altitude [m]) of the ENU origin; None =
            each flight's first photo at ground level.
        turbine_yaml: a turbine file to copy in as ``turbine.yaml``.
        turbine_location_deg: (latitude, longitude) of the turbine's base: turbine.yaml
            is estimated from the photos near it (``turbinefit init --near``).
        camera: which camera's photos to import when they are of several: ``wide``,
            ``zoom``, ``thermal``, or a name (EXIF model, e.g. ``ZH20T``, or make and
            model); None = the only one.
        max_gap_s: the longest pause [s] between two photos of one flight.

    Raises:
        InputError: naming the file of the first problem; nothing is written then.
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    paths = [Path(p) for p in inputs]
    turbine_path = None if turbine_yaml is None else Path(turbine_yaml)
    if not paths:
        raise InputError("no photos given", field="import dji")
    max_gap_s = MAX_GAP.check(max_gap_s, field="--max-gap")
    if origin is not None:
        origin = check_latlonalt(*origin, prefix="--origin ")  # type: ignore[assignment]
    check_not_input(out, paths + ([turbine_path] if turbine_path is not None else []))
    check_output_dir(out, overwrite, _may_replace, OVERWRITE_HINT)

    photos = [read_dji_photo(p) for p in list_photos(paths)]
    chosen, others = pick_camera(photos, camera)
    groups = split_flights(sorted_by_time(chosen), max_gap_s)
    plans = [_plan_flight(g, origin, turbine_path, turbine_location_deg) for g in groups]
    t1 = time.perf_counter()
    several = len(plans) > 1
    flights = []
    with atomic_output_dir(out, overwrite=overwrite, may_replace=_may_replace,
                           overwrite_hint=OVERWRITE_HINT) as tmp:
        for k, plan in enumerate(plans, start=1):
            sub = FLIGHT_DIR.format(k) if several else ""
            flights.append(_write_flight(plan, tmp / sub, out / sub))
    t2 = time.perf_counter()
    first = plans[0].photos[0]
    return DjiImportSummary(
        str(out), camera_label(first), (first.width, first.height), flights,
        other_cameras=others,
        timings={"read": t1 - t0, "write": t2 - t1, "total": t2 - t0})


def _only_flight_sets(folder: Path) -> str | None:
    """None if ``folder`` holds nothing but ``flight-N`` flight folders."""
    for entry in folder.iterdir():
        if not re.fullmatch(r"flight-[0-9]+", entry.name) or not entry.is_dir() \
                or entry.is_symlink():
            return f"{entry.name!r} is not a flight folder of turbinefit import dji"
        why = only_flight_entries(entry)
        if why is not None:
            return f"{entry.name}: {why}"
    return None


def _may_replace(folder: Path) -> str | None:
    """None if ``folder`` is a flight folder or a folder of flight folders (what ``import
    dji`` writes, with one flight or several), else why it may not be replaced."""
    why = only_flight_entries(folder)
    return None if why is None or _only_flight_sets(folder) is None else why


@dataclass
class _FlightPlan:
    """Everything one flight folder holds, computed before anything is written."""

    photos: list[DjiPhoto]
    texts: dict[str, str]
    timestamps: np.ndarray
    summary: DjiFlightSummary
    georef: Georef
    near_xy: tuple[float, float] | None


def _plan_flight(photos: list[DjiPhoto], origin: tuple[float, float, float] | None,
                 turbine_path: Path | None,
                 turbine_location_deg: tuple[float, float] | None) -> _FlightPlan:
    """The files of one flight's folder (module docstring)."""
    for p in photos:
        photo_pose(p)  # every photo has what a keyframe needs, before positions are judged
    check_positions(photos)
    meta = np.array([photo_pose(photo) for photo in photos])  # (N, 6)
    cam, intrinsics, crop = flight_camera(photos)
    if origin is None:
        georef = ground_origin(photos[0])
        origin_source = f"the first photo, {photos[0].path.name}, at ground level"
    else:
        georef = Georef(*origin)
        origin_source = "given"
        check_near(georef, photos)
    first_time = photos[0].time
    assert first_time is not None  # sorted_by_time
    georef = replace(georef, time_origin=first_time.isoformat(timespec="microseconds"))
    timestamps = np.array([(p.time - first_time).total_seconds()  # type: ignore[operator]
                           for p in photos])
    world_T_cam = world_T_cam_from_gimbal(georef, *meta.T)
    turbine_text, turbine_note = _turbine(turbine_path, georef)
    near_xy = (None if turbine_location_deg is None
               else _flight_position(georef, *turbine_location_deg))
    texts = {
        CAMERA_FILE: format_camera_yaml(cam, name=photos[0].camera_name),
        KEYFRAMES_FILE: format_tum(timestamps, world_T_cam, None,
                                   "world_T_cam of each photo (turbinefit import dji)"),
        GEOREF_FILE: format_georef_yaml(georef, "turbinefit import dji: the world frame's "
                                        "origin (east-north-up, metres)"),
    }
    sigmas, rtk = rtk_sigmas(photos)
    if sigmas is not None:
        texts[SIGMA_FILE] = format_position_sigmas(timestamps, sigmas)
    if turbine_text is not None:
        texts[TURBINE_FILE] = turbine_text
    summary = DjiFlightSummary(
        "", len(photos), photos[0].path.name, intrinsics, crop, georef, origin_source,
        float(timestamps[-1]), rtk=rtk,
        flight_yaw=[p.path.name for p in photos if p.gimbal_yaw is None],
        position_from_exif=[p.path.name for p in photos if p.position_source == "exif"],
        turbine=turbine_note)
    return _FlightPlan(photos, texts, timestamps, summary, georef, near_xy)


def _write_flight(plan: _FlightPlan, tmp: Path, final: Path) -> DjiFlightSummary:
    """Write one planned flight folder into ``tmp`` (``final`` names errors)."""
    tmp.mkdir(parents=True, exist_ok=True)
    for name, text in plan.texts.items():
        write_text_atomic(tmp / name, text, fsync=False)
    how = link_photos([p.path for p in plan.photos], plan.timestamps, tmp / IMAGE_DIR,
                      final / IMAGE_DIR)
    note = plan.summary.turbine
    if plan.near_xy is not None:  # turbine.yaml from the photos, near that position
        note = _initialise(tmp, final, plan.near_xy, plan.georef)
    return replace(plan.summary, out_dir=str(final), images=how, turbine=note)




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
    check_latlonalt(latitude, longitude, prefix="--turbine ")
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
        src = Path(os.path.realpath(src))  # link the photo, never a (relative) symbolic link
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
