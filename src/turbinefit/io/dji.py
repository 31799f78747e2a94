"""DJI photos: the position, attitude, time, camera and RTK status a DJI drone writes into
each JPEG.

Only the metadata is read, never the pixels: the photo is opened by
:func:`turbinefit.io.images.open_photo` (headers up to the first scan; a JPEG with MPF
preview images appended, as most DJI cameras write it, is read from its primary image),
:meth:`~PIL.Image.Image.getexif` gives the EXIF block and :meth:`~PIL.Image.Image.getxmp`
the XMP packet (parsed by ``defusedxml``; Pillow strips the namespace prefixes). One
:class:`DjiPhoto` per file, all values as the drone wrote them (degrees, metres, pixels);
:mod:`turbinefit.jobs.import_dji` turns them into flights.

Fields read (XMP namespace ``drone-dji``, ``http://www.dji.com/drone-dji/1.0/``, as
attributes of ``rdf:Description`` as DJI writes them, or as child elements as other tools
rewrite them):

* ``GpsLatitude``, ``GpsLongitude`` (or the misspelt ``GpsLongtitude`` of some firmware),
  ``AbsoluteAltitude``, ``RelativeAltitude`` (above the take-off point);
* ``GimbalYawDegree``, ``GimbalPitchDegree``, ``GimbalRollDegree`` and
  ``FlightYawDegree``, ``FlightPitchDegree``, ``FlightRollDegree``;
* ``CalibratedFocalLength``, ``CalibratedOpticalCenterX``, ``CalibratedOpticalCenterY``
  (pixels);
* ``DewarpData`` (``date;fx,fy,cx,cy,k1,k2,p1,p2,k3``: DJI's calibration, pixels, the
  optical centre as an offset from the photo's centre) and ``DewarpFlag`` (1: the photo
  was already undistorted);
* ``RtkFlag`` (0 no position, 16 single point, 32-49 float, 50 fixed) and ``RtkStdLon``,
  ``RtkStdLat``, ``RtkStdHgt`` (standard deviations [m]);
* ``ImageSource`` (``WideCamera``, ``ZoomCamera``, ``InfraredCamera`` ... on payloads
  with several cameras).

Older firmware writes the same fields under the prefix ``DJI:`` (namespace
``http://www.dji.com``), sometimes in a packet that is not well-formed XML; such a packet
is read field by field (:func:`_xmp_fields`).

XMP numbers are decimal strings with or without a sign (``+101.30``, ``82.400002``).

EXIF: ``Make``, ``Model``, ``Orientation``, ``DateTimeOriginal`` (``YYYY:MM:DD
HH:MM:SS``, or with dashes in the date as some DJI firmware writes it) +
``SubSecTimeOriginal``, ``FocalLength``, ``FocalLengthIn35mmFilm``,
``FocalPlaneXResolution`` (+ unit) and the GPS block (``GPSLatitude``/``Ref``,
``GPSLongitude``/``Ref``, ``GPSAltitude``/``Ref``), which gives the position when the XMP
has none.

Every number passes the one validation layer (:mod:`turbinefit.io.quantities`): latitude,
longitude and altitude as in ``georef.yaml`` and on the command line, the six angles as
:data:`~turbinefit.io.quantities.ATTITUDE_DEG`, the rest by the quantities declared here.
Every problem is an :class:`~turbinefit.errors.InputError` naming the file and field: a
file that is not a JPEG, an unreadable file, a value that is not a number or is out of
range. Missing fields are ``None``; the importer decides which it needs.
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from turbinefit.errors import InputError
from turbinefit.io.quantities import (
    ALTITUDE,
    ATTITUDE_DEG,
    LATITUDE,
    LONGITUDE,
    Quantity,
    named,
)

#: File name suffixes taken as photos when a folder is listed (lower case).
JPEG_SUFFIXES = (".jpg", ".jpeg")

# ---- the quantities only photo metadata has ------------------------------------------------

#: A lens's focal length [mm] (EXIF ``FocalLength``): the longest zoom lenses on drones
#: reach about 170 mm.
FOCAL_LENGTH_MM = Quantity("focal length", "mm", 0.0, 2000.0, lo_open=True)
#: A 35 mm equivalent focal length [mm] (EXIF ``FocalLengthIn35mmFilm``): the longest
#: optical zooms on drones reach about 800 mm.
FOCAL_35MM = Quantity("35 mm equivalent focal length", "mm", 0.0, 5000.0, lo_open=True)
#: A focal length in pixels (``CalibratedFocalLength``, DewarpData's fx, fy); the camera
#: it makes is then checked as ``camera.yaml`` is (:func:`turbinefit.io.camera_yaml.check_camera`).
FOCAL_PX = Quantity("focal length", "px", 0.0, 1e7, lo_open=True)
#: A pixel position or offset (optical centres), checked with the camera afterwards.
PIXEL_POSITION = Quantity("optical centre", "px", -1e7, 1e7)
#: A distortion coefficient of DewarpData (the limit of ``camera.yaml``).
DISTORTION_COEFFICIENT = Quantity("distortion coefficient", "", -1000.0, 1000.0)
#: EXIF ``FocalPlaneXResolution`` in pixels per millimetre (pixel pitch >= 0.01 um).
FOCAL_PLANE_RESOLUTION = Quantity("focal plane resolution", "px/mm", 0.0, 1e5, lo_open=True)
#: DJI's ``RtkFlag`` (a GNSS solution type).
RTK_FLAG = Quantity("RTK status", "", 0.0, 255.0, integer=True)
#: DJI's ``RtkStdLon``/``Lat``/``Hgt`` [m].
RTK_STD = Quantity("RTK standard deviation", "m", 0.0, 1e5)
#: DJI's ``DewarpFlag`` (0: not undistorted, 1: undistorted).
DEWARP_FLAG = Quantity("DewarpFlag", "", 0.0, 1.0, integer=True)
#: Altitude above the take-off point [m] (``RelativeAltitude``).
RELATIVE_ALTITUDE = named(ALTITUDE, "relative altitude")

_XMP_FIELDS: dict[str, tuple[tuple[str, ...], Quantity]] = {
    # DjiPhoto attribute -> drone-dji names (the first present wins), quantity
    "latitude": (("GpsLatitude",), LATITUDE),
    "longitude": (("GpsLongitude", "GpsLongtitude"), LONGITUDE),
    "altitude": (("AbsoluteAltitude",), ALTITUDE),
    "relative_altitude": (("RelativeAltitude",), RELATIVE_ALTITUDE),
    "gimbal_yaw": (("GimbalYawDegree",), named(ATTITUDE_DEG, "gimbal yaw")),
    "gimbal_pitch": (("GimbalPitchDegree",), named(ATTITUDE_DEG, "gimbal pitch")),
    "gimbal_roll": (("GimbalRollDegree",), named(ATTITUDE_DEG, "gimbal roll")),
    "flight_yaw": (("FlightYawDegree",), named(ATTITUDE_DEG, "flight yaw")),
    "flight_pitch": (("FlightPitchDegree",), named(ATTITUDE_DEG, "flight pitch")),
    "flight_roll": (("FlightRollDegree",), named(ATTITUDE_DEG, "flight roll")),
    "calibrated_focal_px": (("CalibratedFocalLength",), FOCAL_PX),
    "calibrated_cx": (("CalibratedOpticalCenterX",), PIXEL_POSITION),
    "calibrated_cy": (("CalibratedOpticalCenterY",), PIXEL_POSITION),
    "rtk_flag": (("RtkFlag",), RTK_FLAG),
    "rtk_std_lon": (("RtkStdLon",), RTK_STD),
    "rtk_std_lat": (("RtkStdLat",), RTK_STD),
    "rtk_std_hgt": (("RtkStdHgt",), RTK_STD),
    "dewarp_flag": (("DewarpFlag",), DEWARP_FLAG),
}

# EXIF tags (numbers as in the EXIF 2.32 standard; PIL.ExifTags names them too)
_IFD_EXIF, _IFD_GPS = 0x8769, 0x8825
_MAKE, _MODEL, _ORIENTATION = 0x010F, 0x0110, 0x0112
_DATETIME_ORIGINAL, _SUBSEC_ORIGINAL = 0x9003, 0x9291
_FOCAL_LENGTH, _FOCAL_35MM = 0x920A, 0xA405
_FOCAL_PLANE_X_RES, _FOCAL_PLANE_UNIT = 0xA20E, 0xA210
_GPS_LAT_REF, _GPS_LAT, _GPS_LON_REF, _GPS_LON, _GPS_ALT_REF, _GPS_ALT = 1, 2, 3, 4, 5, 6
#: FocalPlaneResolutionUnit -> millimetres per unit
_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 1e-3}
#: The forms of DateTimeOriginal read (EXIF's, and the dashes of some DJI firmware).
_TIME_FORMATS = ("%Y:%m:%d %H:%M:%S", "%Y-%m-%d %H:%M:%S")


@dataclass(frozen=True)
class DewarpData:
    """DJI's calibration of one camera (``drone-dji:DewarpData``).

    Attributes:
        date: the calibration's date as written ('' if none).
        fx, fy: focal lengths [px].
        cx_offset, cy_offset: the optical centre's offset from the photo's centre [px]
            (``cx = W / 2 + cx_offset``, DJI's convention; docs/import.md).
        distortion: OpenCV's ``(k1, k2, p1, p2, k3)``.
    """

    date: str
    fx: float
    fy: float
    cx_offset: float
    cy_offset: float
    distortion: tuple[float, float, float, float, float]


@dataclass(frozen=True)
class DjiPhoto:
    """What one DJI photo says about itself (None: not in the file).

    Attributes:
        path: the file.
        width, height: image size [px] as stored (before any EXIF orientation).
        make, model: EXIF camera make and model ('' if absent).
        image_source: XMP ``ImageSource`` ('' if absent): which camera of a payload.
        orientation: EXIF orientation (1 = as stored), or None.
        time: ``DateTimeOriginal`` + ``SubSecTimeOriginal`` (camera local time, no zone).
        latitude, longitude: WGS84 [deg] (XMP, else the EXIF GPS block).
        altitude: [m] (XMP ``AbsoluteAltitude``, else EXIF ``GPSAltitude``), in the
            drone's datum.
        relative_altitude: [m] above the take-off point.
        position_source: ``"xmp"`` or ``"exif"`` (where latitude and longitude came from).
        gimbal_yaw, gimbal_pitch, gimbal_roll: the camera's attitude [deg] (NED: yaw
            clockwise from north, pitch 0 level and -90 down, roll about the optical axis).
        flight_yaw, flight_pitch, flight_roll: the aircraft's attitude [deg].
        calibrated_focal_px, calibrated_cx, calibrated_cy: calibrated intrinsics [px].
        dewarp: DJI's calibration with distortion, or None; dewarp_flag: 1 if the photo
            was undistorted in the camera.
        rtk_flag: DJI's GNSS solution (0 none, 16 single point, 32-49 float, 50 fixed).
        rtk_std_lon, rtk_std_lat, rtk_std_hgt: its standard deviations [m].
        focal_length_mm: EXIF ``FocalLength`` [mm].
        focal_35mm: EXIF ``FocalLengthIn35mmFilm`` [mm, 35 mm equivalent].
        focal_plane_px_per_mm: EXIF ``FocalPlaneXResolution`` in pixels per millimetre.
    """

    path: Path
    width: int
    height: int
    make: str = ""
    model: str = ""
    image_source: str = ""
    orientation: int | None = None
    time: datetime | None = None
    latitude: float | None = None
    longitude: float | None = None
    altitude: float | None = None
    relative_altitude: float | None = None
    position_source: str | None = None
    gimbal_yaw: float | None = None
    gimbal_pitch: float | None = None
    gimbal_roll: float | None = None
    flight_yaw: float | None = None
    flight_pitch: float | None = None
    flight_roll: float | None = None
    calibrated_focal_px: float | None = None
    calibrated_cx: float | None = None
    calibrated_cy: float | None = None
    dewarp: DewarpData | None = None
    dewarp_flag: int | None = None
    rtk_flag: int | None = None
    rtk_std_lon: float | None = None
    rtk_std_lat: float | None = None
    rtk_std_hgt: float | None = None
    focal_length_mm: float | None = None
    focal_35mm: float | None = None
    focal_plane_px_per_mm: float | None = None

    @property
    def camera_name(self) -> str:
        """``make model`` (e.g. ``DJI FC6310``), or ``unknown camera``."""
        return " ".join(s for s in (self.make, self.model) if s) or "unknown camera"


def list_photos(inputs: Iterable[Path]) -> list[Path]:
    """The photos named by ``inputs``: files as given, folders listed (not recursively;
    only ``.jpg``/``.jpeg`` files, any case, so a DJI folder's ``.MRK``, ``.SRT`` and
    videos are skipped), in the order given, each folder sorted by name.

    Raises:
        InputError: for a path that does not exist, a folder without JPEG files, or a
            symbolic link that leads nowhere.
    """
    from turbinefit.io.images import list_images

    return list_images(inputs, JPEG_SUFFIXES)


def read_dji_photo(path: Path) -> DjiPhoto:
    """The metadata of one photo (module docstring), without decoding its pixels.

    Raises:
        InputError: naming the file (and field) if it is not a readable JPEG or a value is
            malformed or out of range.
    """
    from turbinefit.io.images import open_photo

    try:
        with (open_photo(path, jpeg_only="not a JPEG photo",
                         unidentified="not a JPEG photo (not an image file)") as im,
              warnings.catch_warnings()):
            warnings.simplefilter("ignore")  # e.g. Pillow's "corrupt EXIF" warnings
            width, height = im.size
            exif = im.getexif()
            exif_ifd = exif.get_ifd(_IFD_EXIF)
            gps_ifd = exif.get_ifd(_IFD_GPS)
            xmp = _xmp_fields(im)
    except (SyntaxError, ValueError) as e:  # bad XMP (defusedxml), broken EXIF
        raise InputError(f"cannot read the photo's metadata: {e}", path=path) from e

    values: dict[str, Any] = {}
    for attr, (names, quantity) in _XMP_FIELDS.items():
        name = next((n for n in names if n in xmp), None)
        if name is not None:
            values[attr] = _number(xmp[name], path, f"drone-dji:{name}", quantity)
    for attr in ("rtk_flag", "dewarp_flag"):
        if attr in values:
            values[attr] = int(values[attr])
    if "DewarpData" in xmp:
        values["dewarp"] = parse_dewarp(_string(xmp["DewarpData"]), path)
    position_source = "xmp" if "latitude" in values and "longitude" in values else None
    if position_source is None and _GPS_LAT in gps_ifd and _GPS_LON in gps_ifd:
        values["latitude"] = _gps_degrees(gps_ifd, _GPS_LAT, _GPS_LAT_REF, "S", path)
        values["longitude"] = _gps_degrees(gps_ifd, _GPS_LON, _GPS_LON_REF, "W", path)
        position_source = "exif"
    if "altitude" not in values and _GPS_ALT in gps_ifd:
        below = gps_ifd.get(_GPS_ALT_REF) in (1, b"\x01")
        alt = _raw_number(gps_ifd[_GPS_ALT], path, "EXIF GPSAltitude")
        values["altitude"] = ALTITUDE.check(-alt if below else alt, path,
                                            field="EXIF GPSAltitude")
    unit = _UNIT_MM.get(_int(exif_ifd.get(_FOCAL_PLANE_UNIT, 2)))
    if _FOCAL_PLANE_X_RES in exif_ifd and unit is not None:
        res = _raw_number(exif_ifd[_FOCAL_PLANE_X_RES], path, "EXIF FocalPlaneXResolution")
        if res != 0:  # 0: unknown
            values["focal_plane_px_per_mm"] = FOCAL_PLANE_RESOLUTION.check(
                res / unit, path, field="EXIF FocalPlaneXResolution")
    for attr, tag, name, quantity in (
            ("focal_length_mm", _FOCAL_LENGTH, "FocalLength", FOCAL_LENGTH_MM),
            ("focal_35mm", _FOCAL_35MM, "FocalLengthIn35mmFilm", FOCAL_35MM)):
        if tag in exif_ifd:
            v = _raw_number(exif_ifd[tag], path, f"EXIF {name}")
            if v != 0:  # 0 means unknown
                values[attr] = quantity.check(v, path, field=f"EXIF {name}")
    orientation = exif.get(_ORIENTATION)
    return DjiPhoto(
        path=path, width=int(width), height=int(height), make=_text(exif.get(_MAKE)),
        model=_text(exif.get(_MODEL)), image_source=_string(xmp.get("ImageSource", "")),
        orientation=None if orientation is None else _int(orientation),
        time=_time(exif_ifd, path), position_source=position_source, **values)


def parse_dewarp(text: str, path: Path) -> DewarpData | None:
    """DJI's ``DewarpData`` (``date;fx,fy,cx,cy,k1,k2,p1,p2,k3``; the date may be
    missing); None for an empty field.

    Raises:
        InputError: naming the file and field for another count of numbers, or a number
            out of range.
    """
    field = "drone-dji:DewarpData"
    text = text.strip()
    if not text:
        return None
    date, _, numbers = text.rpartition(";")
    parts = [p for p in numbers.split(",")]
    if len(parts) != 9:
        raise InputError(f"expected 'date;fx,fy,cx,cy,k1,k2,p1,p2,k3', got {text!r}",
                         path=path, field=field)
    fx, fy = (FOCAL_PX.parse(p, path, field=field) for p in parts[:2])
    cx, cy = (PIXEL_POSITION.parse(p, path, field=field) for p in parts[2:4])
    k = tuple(DISTORTION_COEFFICIENT.parse(p, path, field=field) for p in parts[4:])
    return DewarpData(date.strip(), fx, fy, cx, cy, k)  # type: ignore[arg-type]


#: An XMP attribute ``prefix:Name="value"`` or simple element ``<prefix:Name>value<``.
_XMP_ATTRIBUTE = re.compile(r'[\w.-]+:(\w+)\s*=\s*"([^"]*)"')
_XMP_ELEMENT = re.compile(r"<[\w.-]+:(\w+)>([^<]*)<")


def _xmp_fields(im: Any) -> dict[str, Any]:
    """The ``drone-dji`` fields of an opened photo's XMP packet ({} without one).

    Parsed as XML (:meth:`~PIL.Image.Image.getxmp`, ``defusedxml``); a packet that is not
    well-formed XML - older DJI firmware declares its namespace twice (``xmlns:DJI`` in a
    Zenmuse XT S photo), which XML forbids - is read field by field instead: attributes
    ``prefix:Name="value"`` and simple elements ``<prefix:Name>value<``, the prefix
    dropped as Pillow drops it. No XML library reads a malformed packet, hence by hand."""
    raw = im.info.get("xmp")
    if not raw:
        return {}
    try:
        return _drone_dji(im.getxmp())
    except (SyntaxError, ValueError):  # defusedxml's ParseError is a SyntaxError
        text = raw.decode("utf-8", "replace") if isinstance(raw, bytes) else str(raw)
        out: dict[str, Any] = {}
        for pattern in (_XMP_ELEMENT, _XMP_ATTRIBUTE):
            for name, value in pattern.findall(text):
                out.setdefault(name, value.strip())
        return out


def _drone_dji(xmp: Mapping[str, Any]) -> dict[str, Any]:
    """The fields of every ``rdf:Description`` of a :meth:`getxmp` dict, merged."""
    rdf = xmp.get("xmpmeta", xmp).get("RDF", {}) if isinstance(xmp, Mapping) else {}
    descriptions = rdf.get("Description", []) if isinstance(rdf, Mapping) else []
    if isinstance(descriptions, Mapping):
        descriptions = [descriptions]
    out: dict[str, Any] = {}
    for d in descriptions:
        if isinstance(d, Mapping):
            out.update(d)
    return out


def _string(value: Any) -> str:
    """The text of an XMP value (an attribute, or an element with attributes)."""
    if isinstance(value, Mapping):
        value = value.get("text", "")
    return value.strip() if isinstance(value, str) else ""


def _number(value: Any, path: Path, field: str, quantity: Quantity) -> float:
    """An XMP value (``+101.30``, ``82.400002``) checked as ``quantity``."""
    if isinstance(value, Mapping) and "text" in value:  # an element with attributes
        value = value["text"]
    if not isinstance(value, str):
        raise InputError(f"{quantity.what} must be a number, got {value!r}", path=path,
                         field=field)
    return quantity.parse(value, path, field=field)


def _raw_number(value: Any, path: Path, field: str) -> float:
    """The float of an EXIF number or rational (finite; ranges are the caller's)."""
    try:
        v = float(value)
    except (TypeError, ValueError, ZeroDivisionError):
        raise InputError(f"not a number: {value!r}", path=path, field=field) from None
    if not math.isfinite(v):
        raise InputError(f"must be finite, got {value!r}", path=path, field=field)
    return v


def _int(value: Any) -> int:
    try:
        return int(value)
    except (TypeError, ValueError):
        return -1


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        value = value.decode("latin-1")
    return value.strip("\x00 \t\r\n") if isinstance(value, str) else ""


def _gps_degrees(gps: Mapping[int, Any], tag: int, ref_tag: int, negative: str,
                 path: Path) -> float:
    """Degrees of an EXIF GPS (degrees, minutes, seconds) triple, signed by its ref."""
    name, quantity = {_GPS_LAT: ("GPSLatitude", LATITUDE),
                      _GPS_LON: ("GPSLongitude", LONGITUDE)}[tag]
    dms = gps[tag]
    if not isinstance(dms, tuple | list) or len(dms) != 3:
        raise InputError(f"expected degrees, minutes, seconds, got {dms!r}", path=path,
                         field=f"EXIF {name}")
    d, m, s = (_raw_number(x, path, f"EXIF {name}") for x in dms)
    sign = -1.0 if _text(gps.get(ref_tag)).upper() == negative else 1.0
    return quantity.check(sign * (d + m / 60 + s / 3600), path, field=f"EXIF {name}")


def _time(exif_ifd: Mapping[int, Any], path: Path) -> datetime | None:
    """``DateTimeOriginal`` + ``SubSecTimeOriginal`` (digits of a second, at most 6 used)."""
    text = _text(exif_ifd.get(_DATETIME_ORIGINAL))
    if not text:
        return None
    for form in _TIME_FORMATS:
        try:
            t = datetime.strptime(text, form)
            break
        except ValueError:
            continue
    else:
        raise InputError(f"expected 'YYYY:MM:DD HH:MM:SS', got {text!r}", path=path,
                         field="EXIF DateTimeOriginal")
    sub = _text(exif_ifd.get(_SUBSEC_ORIGINAL))
    if sub:
        if not sub.isdigit():
            raise InputError(f"expected digits, got {sub!r}", path=path,
                             field="EXIF SubSecTimeOriginal")
        t += timedelta(microseconds=int(sub[:6].ljust(6, "0")))
    return t
