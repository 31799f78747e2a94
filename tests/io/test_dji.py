"""Reading DJI photos' metadata: the XMP drone-dji fields as attributes or child elements,
the misspelt longitude, the EXIF GPS fallback, time, focal lengths; non-JPEGs refused."""

from __future__ import annotations

import io
import xml.etree.ElementTree as ET
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, ImageFile
from support import raises_input_error

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.io.dji import list_photos, read_dji_photo
from turbinefit.sim.dji_photos import DRONE_DJI_NS, DjiPose, dji_metadata, write_dji_photo

POSE = DjiPose(datetime(2024, 5, 1, 11, 30, 7, 250000), 51.4545123456, -2.5879654321,
               112.3456, 82.3456, -123.456789, -35.25, 1.5)
GREY = np.full((48, 64, 3), 128, np.uint8)


def test_reads_what_dji_writes(tmp_path: Path) -> None:
    cam = PinholeCamera(64, 48, 51.25, 51.25, 32.1, 23.9)
    p = write_dji_photo(tmp_path / "DJI_0001.JPG", GREY, POSE, camera=cam, model="FC6310R")
    photo = read_dji_photo(p)
    assert (photo.width, photo.height, photo.camera_name) == (64, 48, "DJI FC6310R")
    assert photo.time == POSE.time
    assert (photo.latitude, photo.longitude) == (51.4545123456, -2.5879654321)
    assert photo.position_source == "xmp"
    assert (photo.altitude, photo.relative_altitude) == (112.3456, 82.3456)
    assert (photo.gimbal_yaw, photo.gimbal_pitch, photo.gimbal_roll) == (-123.456789, -35.25, 1.5)
    assert (photo.flight_yaw, photo.flight_pitch, photo.flight_roll) == (-123.456789, 0.0, 0.0)
    assert (photo.calibrated_focal_px, photo.calibrated_cx, photo.calibrated_cy) == (51.25, 32.1,
                                                                                      23.9)
    assert (photo.focal_length_mm, photo.focal_35mm) == (8.8, 24.0)


def test_the_xmp_is_a_real_drone_dji_packet(tmp_path: Path) -> None:
    p = write_dji_photo(tmp_path / "a.jpg", GREY, POSE)
    with Image.open(p) as im:
        root = ET.fromstring(im.info["xmp"])
    desc = root.find(".//{http://www.w3.org/1999/02/22-rdf-syntax-ns#}Description")
    assert desc is not None
    assert desc.get(f"{{{DRONE_DJI_NS}}}GimbalYawDegree") == "-123.456789"
    assert desc.get(f"{{{DRONE_DJI_NS}}}GpsLatitude") == "+51.4545123456"


def test_child_elements_and_the_misspelt_longitude(tmp_path: Path) -> None:
    """Tools that rewrite DJI's XMP put the fields in child elements; some firmware writes
    GpsLongtitude."""
    _, xmp = dji_metadata(POSE, misspelt_longitude=True)
    root = ET.fromstring(xmp)
    rdf_ns = "{http://www.w3.org/1999/02/22-rdf-syntax-ns#}"
    desc = root.find(f".//{rdf_ns}Description")
    assert desc is not None
    for key in [k for k in desc.attrib if k.startswith(f"{{{DRONE_DJI_NS}}}")]:
        ET.SubElement(desc, key).text = desc.attrib.pop(key)
    exif, _ = dji_metadata(POSE)
    buf = io.BytesIO()
    Image.fromarray(GREY).save(buf, "JPEG", exif=exif, xmp=ET.tostring(root))
    (tmp_path / "b.jpg").write_bytes(buf.getvalue())
    photo = read_dji_photo(tmp_path / "b.jpg")
    assert (photo.longitude, photo.gimbal_pitch) == (-2.5879654321, -35.25)


def test_position_from_the_exif_gps_block(tmp_path: Path) -> None:
    south_west = DjiPose(POSE.time, -33.8567812, -70.6503456, 512.25, 30.0, 10.0, -20.0, 0.0)
    p = write_dji_photo(tmp_path / "c.jpg", GREY, south_west, xmp_position=False)
    photo = read_dji_photo(p)
    assert photo.position_source == "exif"
    # EXIF rationals: seconds to ~1e-6 s of arc, i.e. a few centimetres at most
    assert photo.latitude == pytest.approx(-33.8567812, abs=1e-7)
    assert photo.longitude == pytest.approx(-70.6503456, abs=1e-7)
    assert photo.altitude == 512.25  # the XMP AbsoluteAltitude still wins


def test_missing_fields_are_none(tmp_path: Path) -> None:
    buf = io.BytesIO()
    Image.fromarray(GREY).save(buf, "JPEG")
    (tmp_path / "plain.jpg").write_bytes(buf.getvalue())
    photo = read_dji_photo(tmp_path / "plain.jpg")
    assert photo.time is None and photo.latitude is None and photo.gimbal_pitch is None
    assert photo.camera_name == "unknown camera"


def test_a_png_is_not_a_dji_photo(tmp_path: Path) -> None:
    Image.fromarray(GREY).save(tmp_path / "x.jpg", "PNG")
    with raises_input_error(tmp_path / "x.jpg"):
        read_dji_photo(tmp_path / "x.jpg")
    (tmp_path / "notes.jpg").write_text("not a photo")
    with raises_input_error(tmp_path / "notes.jpg"):
        read_dji_photo(tmp_path / "notes.jpg")


def test_a_malformed_value_names_its_field(tmp_path: Path) -> None:
    _, xmp = dji_metadata(POSE)
    exif, _ = dji_metadata(POSE)
    bad = xmp.replace(b'GimbalPitchDegree="-35.250000"', b'GimbalPitchDegree="down"')
    assert bad != xmp
    buf = io.BytesIO()
    Image.fromarray(GREY).save(buf, "JPEG", exif=exif, xmp=bad)
    (tmp_path / "d.jpg").write_bytes(buf.getvalue())
    with raises_input_error(tmp_path / "d.jpg", field="drone-dji:GimbalPitchDegree"):
        read_dji_photo(tmp_path / "d.jpg")


def test_list_photos_takes_the_jpegs_of_a_folder(tmp_path: Path) -> None:
    for name in ("DJI_0002.JPG", "DJI_0001.jpeg"):
        write_dji_photo(tmp_path / name, GREY, POSE)
    (tmp_path / "DJI_0001.MRK").write_text("timestamps")
    (tmp_path / "flight.SRT").write_text("subtitles")
    assert [p.name for p in list_photos([tmp_path])] == ["DJI_0001.jpeg", "DJI_0002.JPG"]
    with raises_input_error(tmp_path / "none"):
        list_photos([tmp_path / "none"])
    (tmp_path / "empty").mkdir()
    with raises_input_error(tmp_path / "empty"):
        list_photos([tmp_path / "empty"])


def test_reading_does_not_decode_the_pixels(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    p = write_dji_photo(tmp_path / "e.jpg", GREY, POSE)

    def no_decode(self: Image.Image) -> None:
        raise AssertionError("pixels decoded")

    monkeypatch.setattr(ImageFile.ImageFile, "load", no_decode)
    assert read_dji_photo(p).gimbal_roll == 1.5


def test_malformed_xmp_of_older_firmware(tmp_path: Path) -> None:
    """A Zenmuse XT S photo's packet: the DJI: prefix declared twice (not well-formed XML,
    which XML parsers refuse), fields unsigned or signed: read field by field."""
    exif, _ = dji_metadata(POSE)
    xmp = (b'<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF '
           b'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
           b'<rdf:Description rdf:about="DJI Meta Data"\nxmlns:DJI="http://www.dji.com"\n'
           b'xmlns:DJI="http://www.dji.com"\nDJI:AbsoluteAltitude="-29.44"\n'
           b'DJI:RelativeAltitude="37.70"\nDJI:GimbalRollDegree="+0.00"\n'
           b'DJI:GimbalYawDegree="91.30"\nDJI:GimbalPitchDegree="+19.90"\nDJI:RtkFlag="0">'
           b'<DJI:BandName><rdf:Seq><rdf:li>LWIR</rdf:li></rdf:Seq></DJI:BandName>'
           b'</rdf:Description></rdf:RDF></x:xmpmeta>')
    Image.fromarray(GREY).save(tmp_path / "xts.jpg", "JPEG", exif=exif, xmp=xmp)
    photo = read_dji_photo(tmp_path / "xts.jpg")
    assert (photo.gimbal_yaw, photo.gimbal_pitch, photo.gimbal_roll) == (91.3, 19.9, 0.0)
    assert (photo.altitude, photo.relative_altitude, photo.rtk_flag) == (-29.44, 37.7, 0)
    assert photo.position_source == "exif"
    assert photo.latitude == pytest.approx(POSE.latitude, abs=1e-9)
