"""DJI-style photos of simulated cameras: JPEGs whose EXIF and XMP metadata say where each
camera was, as a DJI drone writes them, for tests and benchmarks of ``import dji``.

A simulated flight's world frame (z up, ground at z = 0) is taken as the east-north-up
frame about a WGS84 origin (:class:`turbinefit.io.georef.Georef`, the take-off point on
the ground), and each ``world_T_cam`` becomes a position and gimbal angles
(:func:`turbinefit.io.georef.gimbal_from_world_T_cam`, the inverse of what the importer
does). :func:`write_dji_photo` then writes one JPEG with Pillow: the EXIF block
(``Make``, ``Model``, ``DateTimeOriginal`` + ``SubSecTimeOriginal`` to the microsecond,
``FocalLength``, ``FocalLengthIn35mmFilm``, the GPS IFD) and an XMP packet built with
:mod:`xml.etree.ElementTree`: one ``rdf:Description`` whose ``drone-dji:`` attributes are
the position, altitudes, gimbal and flight angles and (optionally) calibrated intrinsics,
signed decimal strings as DJI writes them, with enough digits for 0.1 mm and 1e-6 deg.

The structures real DJI files have are available as options, so that tests need no real
photo: a preview image appended behind a Multi-Picture Format (MPF, APP2) segment
(``preview=True``: Pillow then reads the file as ``MPO``, as it reads a Mavic's or an
H20T's), XMP numbers without a sign (``signed=False``, as FLIR-cored payloads write them),
no 35 mm equivalent (``focal_35mm=None``), a dashed ``DateTimeOriginal``, and any further
``drone-dji`` fields (``extra_xmp``: ``DewarpData``, ``RtkFlag``, ``RtkStdLon`` ...,
``ImageSource``).
"""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.io.atomic import StrPath, write_bytes_atomic
from turbinefit.io.georef import Georef, gimbal_from_world_T_cam

DRONE_DJI_NS = "http://www.dji.com/drone-dji/1.0/"
_RDF_NS = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
_X_NS = "adobe:ns:meta/"
#: A start time for simulated photos (camera local time).
DEFAULT_START = datetime(2024, 5, 1, 11, 30, 0)


@dataclass(frozen=True)
class DjiPose:
    """What a DJI photo's metadata says about its camera (degrees, metres).

    Attributes:
        time: camera time (microseconds kept).
        latitude, longitude: WGS84 [deg]; altitude: absolute [m]; relative_altitude:
            above the take-off point [m].
        yaw, pitch, roll: gimbal angles [deg] (NED; see :mod:`turbinefit.io.georef`).
    """

    time: datetime
    latitude: float
    longitude: float
    altitude: float
    relative_altitude: float
    yaw: float
    pitch: float
    roll: float


def dji_poses(georef: Georef, world_T_cam: SE3, timestamps: ArrayLike,
              start: datetime = DEFAULT_START) -> list[DjiPose]:
    """The DJI metadata of cameras ``world_T_cam`` (ENU about ``georef``, which is also the
    take-off point) at ``timestamps`` [s] after ``start``."""
    w = gimbal_from_world_T_cam(georef, world_T_cam)
    t = np.asarray(timestamps, dtype=np.float64)
    return [DjiPose(start + timedelta(microseconds=round(float(t[k]) * 1e6)),
                    float(w.latitude[k]), float(w.longitude[k]), float(w.altitude[k]),
                    float(w.altitude[k] - georef.altitude), float(w.yaw[k]),
                    float(w.pitch[k]), float(w.roll[k])) for k in range(len(t))]


def xmp_packet(fields: Mapping[str, str]) -> bytes:
    """An XMP packet with one ``rdf:Description`` whose ``drone-dji:NAME`` attributes are
    ``fields`` (as DJI writes them)."""
    ET.register_namespace("x", _X_NS)
    ET.register_namespace("rdf", _RDF_NS)
    ET.register_namespace("drone-dji", DRONE_DJI_NS)
    meta = ET.Element(f"{{{_X_NS}}}xmpmeta")
    rdf = ET.SubElement(meta, f"{{{_RDF_NS}}}RDF")
    attrs = {f"{{{_RDF_NS}}}about": "DJI Meta Data"}
    attrs.update({f"{{{DRONE_DJI_NS}}}{k}": v for k, v in fields.items()})
    ET.SubElement(rdf, f"{{{_RDF_NS}}}Description", attrs)
    return ET.tostring(meta, encoding="utf-8", xml_declaration=False)


def _dms(deg: float) -> tuple[float, float, float]:
    a = abs(deg)
    d = math.floor(a)
    m = math.floor((a - d) * 60.0)
    return float(d), float(m), (a - d - m / 60.0) * 3600.0


def dji_metadata(pose: DjiPose, *, model: str = "FC6310", focal_35mm: float | None = 24.0,
                 focal_mm: float | None = 8.8, camera: PinholeCamera | None = None,
                 gimbal_yaw: bool = True, xmp_position: bool = True,
                 misspelt_longitude: bool = False, signed: bool = True,
                 dashed_time: bool = False, make: str = "DJI",
                 extra_xmp: Mapping[str, str] | None = None) -> tuple[bytes, bytes]:
    """(EXIF, XMP) bytes of a DJI photo at ``pose``.

    Args:
        model: EXIF ``Model`` (``Make`` is ``DJI``).
        focal_35mm, focal_mm: EXIF focal lengths (None: not written).
        camera: written as ``CalibratedFocalLength`` (its fx) and
            ``CalibratedOpticalCenterX``/``Y`` when given.
        gimbal_yaw: False leaves ``GimbalYawDegree`` out (``FlightYawDegree`` carries it).
        xmp_position: False leaves the XMP position out (only the EXIF GPS block has it).
        misspelt_longitude: write ``GpsLongtitude`` as some firmware does.
        signed: False writes XMP numbers without a ``+`` (``82.400002``).
        dashed_time: ``DateTimeOriginal`` as ``YYYY-MM-DD HH:MM:SS``.
        make: EXIF ``Make``.
        extra_xmp: further ``drone-dji`` fields, written as given.
    """
    from PIL import ExifTags, Image

    exif = Image.Exif()
    exif[ExifTags.Base.Make] = make
    exif[ExifTags.Base.Model] = model
    sub = exif.get_ifd(ExifTags.IFD.Exif)
    sub[ExifTags.Base.DateTimeOriginal] = pose.time.strftime(
        "%Y-%m-%d %H:%M:%S" if dashed_time else "%Y:%m:%d %H:%M:%S")
    sub[ExifTags.Base.SubsecTimeOriginal] = f"{pose.time.microsecond:06d}"
    if focal_mm is not None:
        sub[ExifTags.Base.FocalLength] = focal_mm
    if focal_35mm is not None:
        sub[ExifTags.Base.FocalLengthIn35mmFilm] = round(focal_35mm)
    gps = exif.get_ifd(ExifTags.IFD.GPSInfo)
    gps[ExifTags.GPS.GPSVersionID] = b"\x02\x03\x00\x00"
    gps[ExifTags.GPS.GPSLatitudeRef] = "N" if pose.latitude >= 0 else "S"
    gps[ExifTags.GPS.GPSLatitude] = _dms(pose.latitude)
    gps[ExifTags.GPS.GPSLongitudeRef] = "E" if pose.longitude >= 0 else "W"
    gps[ExifTags.GPS.GPSLongitude] = _dms(pose.longitude)
    gps[ExifTags.GPS.GPSAltitudeRef] = b"\x00" if pose.altitude >= 0 else b"\x01"
    gps[ExifTags.GPS.GPSAltitude] = abs(pose.altitude)

    fields: dict[str, str] = {}
    if xmp_position:
        fields["GpsLatitude"] = f"{pose.latitude:+.10f}"
        fields["GpsLongtitude" if misspelt_longitude else "GpsLongitude"] = \
            f"{pose.longitude:+.10f}"
    fields["AbsoluteAltitude"] = f"{pose.altitude:+.4f}"
    fields["RelativeAltitude"] = f"{pose.relative_altitude:+.4f}"
    if gimbal_yaw:
        fields["GimbalYawDegree"] = f"{pose.yaw:+.6f}"
    fields["GimbalPitchDegree"] = f"{pose.pitch:+.6f}"
    fields["GimbalRollDegree"] = f"{pose.roll:+.6f}"
    fields["FlightYawDegree"] = f"{pose.yaw:+.6f}"
    fields["FlightPitchDegree"] = "+0.000000"
    fields["FlightRollDegree"] = "+0.000000"
    if camera is not None:
        fields["CalibratedFocalLength"] = f"{camera.fx:.6f}"
        fields["CalibratedOpticalCenterX"] = f"{camera.cx:.6f}"
        fields["CalibratedOpticalCenterY"] = f"{camera.cy:.6f}"
    if not signed:
        fields = {k: v.lstrip("+") for k, v in fields.items()}
    fields.update(extra_xmp or {})
    return exif.tobytes(), xmp_packet(fields)


def dewarp_text(camera: PinholeCamera, date: str = "2024-01-01") -> str:
    """``DewarpData`` of ``camera`` as DJI writes it: ``date;fx,fy,cx,cy,k1,k2,p1,p2,k3``
    with the optical centre as an offset from the photo's centre (``W / 2``, ``H / 2``)."""
    nums = [camera.fx, camera.fy, camera.cx - camera.width / 2.0,
            camera.cy - camera.height / 2.0, *camera.distortion]
    return date + ";" + ",".join(f"{v:.12f}" for v in nums)


def write_dji_photo(path: StrPath, pixels: NDArray[np.uint8], pose: DjiPose, *,
                    quality: int = 90, preview: bool = False, **metadata: object) -> Path:
    """Write ``pixels`` (H, W, 3 uint8) as a DJI-style JPEG at ``path`` (atomically), with
    the metadata of :func:`dji_metadata` (``metadata``: its keyword options); ``preview``
    appends a quarter-size preview image announced by an MPF APP2 segment, as most DJI
    cameras do (Pillow's MPO writer makes exactly that structure)."""
    from PIL import Image

    exif, xmp = dji_metadata(pose, **metadata)  # type: ignore[arg-type]
    buf = io.BytesIO()
    im = Image.fromarray(np.ascontiguousarray(pixels, dtype=np.uint8), "RGB")
    if preview:
        small = im.resize((max(1, im.width // 4), max(1, im.height // 4)))
        im.save(buf, "MPO", quality=quality, exif=exif, xmp=xmp, save_all=True,
                append_images=[small])
    else:
        im.save(buf, "JPEG", quality=quality, exif=exif, xmp=xmp)
    return write_bytes_atomic(path, buf.getvalue(), fsync=False)
