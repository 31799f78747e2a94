"""DJI photos: the position, attitude, time and camera a DJI drone writes into each JPEG.

Only the metadata is read, never the pixels: :func:`PIL.Image.open` parses the JPEG's
headers (up to the first scan), :meth:`~PIL.Image.Image.getexif` the EXIF block and
:meth:`~PIL.Image.Image.getxmp` the XMP packet (parsed by ``defusedxml``; Pillow strips the
namespace prefixes). One :class:`DjiPhoto` per file, all values as the drone wrote them
(degrees, metres, pixels); :mod:`turbinefit.jobs.import_dji` turns them into a flight.

Fields read (XMP namespace ``drone-dji``, ``http://www.dji.com/drone-dji/1.0/``, as
attributes of ``rdf:Description`` as DJI writes them, or as child elements as other tools
rewrite them):

* ``GpsLatitude``, ``GpsLongitude`` (or the misspelt ``GpsLongtitude`` of some firmware),
  ``AbsoluteAltitude``, ``RelativeAltitude`` (above the take-off point);
* ``GimbalYawDegree``, ``GimbalPitchDegree``, ``GimbalRollDegree`` and
  ``FlightYawDegree``, ``FlightPitchDegree``, ``FlightRollDegree``;
* ``CalibratedFocalLength``, ``CalibratedOpticalCenterX``, ``CalibratedOpticalCenterY``
  (pixels).

EXIF: ``Make``, ``Model``, ``Orientation``, ``DateTimeOriginal`` + ``SubSecTimeOriginal``,
``FocalLength``, ``FocalLengthIn35mmFilm``, ``FocalPlaneXResolution`` (+ unit) and the GPS
block (``GPSLatitude``/``Ref``, ``GPSLongitude``/``Ref``, ``GPSAltitude``/``Ref``), which
gives the position when the XMP has none. XMP values are strings with signs (``+101.30``).

Every problem is an :class:`~turbinefit.errors.InputError` naming the file (and field):
a file that is not a JPEG, an unreadable file, a metadata value that is not a number.
Missing fields are ``None``; the importer decides which it needs.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from turbinefit.errors import InputError

#: File name suffixes taken as photos when a folder is listed (lower case).
JPEG_SUFFIXES = (".jpg", ".jpeg")

_XMP_FIELDS = {  # DjiPhoto attribute -> drone-dji names, the first present wins
    "latitude": ("GpsLatitude",),
    "longitude": ("GpsLongitude", "GpsLongtitude"),
    "altitude": ("AbsoluteAltitude",),
    "relative_altitude": ("RelativeAltitude",),
    "gimbal_yaw": ("GimbalYawDegree",),
    "gimbal_pitch": ("GimbalPitchDegree",),
    "gimbal_roll": ("GimbalRollDegree",),
    "flight_yaw": ("FlightYawDegree",),
    "flight_pitch": ("FlightPitchDegree",),
    "flight_roll": ("FlightRollDegree",),
    "calibrated_focal_px": ("CalibratedFocalLength",),
    "calibrated_cx": ("CalibratedOpticalCenterX",),
    "calibrated_cy": ("CalibratedOpticalCenterY",),
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


@dataclass(frozen=True)
class DjiPhoto:
    """What one DJI photo says about itself (None: not in the file).

    Attributes:
        path: the file.
        width, height: image size [px] as stored (before any EXIF orientation).
        make, model: EXIF camera make and model ('' if absent).
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
        focal_length_mm: EXIF ``FocalLength`` [mm].
        focal_35mm: EXIF ``FocalLengthIn35mmFilm`` [mm, 35 mm equivalent].
        focal_plane_px_per_mm: EXIF ``FocalPlaneXResolution`` in pixels per millimetre.
    """

    path: Path
    width: int
    height: int
    make: str = ""
    model: str = ""
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
        InputError: for a path that does not exist, or a folder without JPEG files.
    """
    from turbinefit.io.images import list_images

    return list_images(inputs, JPEG_SUFFIXES)


def read_dji_photo(path: Path) -> DjiPhoto:
    """The metadata of one photo (module docstring), without decoding its pixels.

    Raises:
        InputError: naming the file (and field) if it is not a readable JPEG or a value is
            malformed.
    """
    from PIL import Image, UnidentifiedImageError

    from turbinefit.io.limits import open_input

    try:
        with open_input(path) as f, Image.open(f) as im, warnings.catch_warnings():
            warnings.simplefilter("ignore")  # e.g. Pillow's "corrupt EXIF" warnings
            if im.format != "JPEG":
                raise InputError(f"not a JPEG photo ({im.format or 'unknown'} image)", path=path)
            width, height = im.size
            exif = im.getexif()
            exif_ifd = exif.get_ifd(_IFD_EXIF)
            gps_ifd = exif.get_ifd(_IFD_GPS)
            xmp = _drone_dji(im.getxmp()) if "xmp" in im.info else {}
    except UnidentifiedImageError as e:
        raise InputError("not a JPEG photo (not an image file)", path=path) from e
    except FileNotFoundError as e:
        raise InputError("photo not found", path=path) from e
    except (OSError, SyntaxError, ValueError) as e:  # truncated headers, bad XMP
        raise InputError(f"cannot read the photo's metadata: {e}", path=path) from e

    values: dict[str, Any] = {}
    for attr, names in _XMP_FIELDS.items():
        name = next((n for n in names if n in xmp), None)
        if name is not None:
            values[attr] = _number(xmp[name], path, f"drone-dji:{name}")
    position_source = "xmp" if "latitude" in values and "longitude" in values else None
    if position_source is None and _GPS_LAT in gps_ifd and _GPS_LON in gps_ifd:
        values["latitude"] = _gps_degrees(gps_ifd, _GPS_LAT, _GPS_LAT_REF, "S", path)
        values["longitude"] = _gps_degrees(gps_ifd, _GPS_LON, _GPS_LON_REF, "W", path)
        position_source = "exif"
    if "altitude" not in values and _GPS_ALT in gps_ifd:
        alt = _number(gps_ifd[_GPS_ALT], path, "EXIF GPSAltitude")
        below = gps_ifd.get(_GPS_ALT_REF) in (1, b"\x01")
        values["altitude"] = -alt if below else alt
    unit = _UNIT_MM.get(_int(exif_ifd.get(_FOCAL_PLANE_UNIT, 2)))
    if _FOCAL_PLANE_X_RES in exif_ifd and unit is not None:
        res = _number(exif_ifd[_FOCAL_PLANE_X_RES], path, "EXIF FocalPlaneXResolution")
        values["focal_plane_px_per_mm"] = res / unit if res > 0 else None
    for attr, tag, name in (("focal_length_mm", _FOCAL_LENGTH, "FocalLength"),
                            ("focal_35mm", _FOCAL_35MM, "FocalLengthIn35mmFilm")):
        if tag in exif_ifd:
            v = _number(exif_ifd[tag], path, f"EXIF {name}")
            values[attr] = v if v > 0 else None  # 0 means unknown
    orientation = exif.get(_ORIENTATION)
    return DjiPhoto(
        path=path, width=int(width), height=int(height), make=_text(exif.get(_MAKE)),
        model=_text(exif.get(_MODEL)),
        orientation=None if orientation is None else _int(orientation),
        time=_time(exif_ifd, path), position_source=position_source, **values)


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


def _number(value: Any, path: Path, field: str) -> float:
    """A finite float from an XMP string (``+101.30``), an EXIF number or rational."""
    if isinstance(value, Mapping) and "text" in value:  # an element with attributes
        value = value["text"]
    try:
        v = float(value.strip() if isinstance(value, str) else value)
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
    name = {_GPS_LAT: "GPSLatitude", _GPS_LON: "GPSLongitude"}[tag]
    dms = gps[tag]
    if not isinstance(dms, tuple | list) or len(dms) != 3:
        raise InputError(f"expected degrees, minutes, seconds, got {dms!r}", path=path,
                         field=f"EXIF {name}")
    d, m, s = (_number(x, path, f"EXIF {name}") for x in dms)
    return (-1.0 if _text(gps.get(ref_tag)).upper() == negative else 1.0) * (d + m / 60 + s / 3600)


def _time(exif_ifd: Mapping[int, Any], path: Path) -> datetime | None:
    """``DateTimeOriginal`` + ``SubSecTimeOriginal`` (digits of a second, at most 6 used)."""
    text = _text(exif_ifd.get(_DATETIME_ORIGINAL))
    if not text:
        return None
    try:
        t = datetime.strptime(text, "%Y:%m:%d %H:%M:%S")
    except ValueError:
        raise InputError(f"expected 'YYYY:MM:DD HH:MM:SS', got {text!r}", path=path,
                         field="EXIF DateTimeOriginal") from None
    sub = _text(exif_ifd.get(_SUBSEC_ORIGINAL))
    if sub:
        if not sub.isdigit():
            raise InputError(f"expected digits, got {sub!r}", path=path,
                             field="EXIF SubSecTimeOriginal")
        t += timedelta(microseconds=int(sub[:6].ljust(6, "0")))
    return t
