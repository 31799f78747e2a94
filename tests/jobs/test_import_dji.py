"""The ``import dji`` job: poses recovered from DJI-style photos to < 1 cm and < 0.01 deg,
origin, time, camera, images and turbine; every bad input refused before anything is
written."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from support import (
    DJI_ORIGIN,
    NRE,
    digest,
    dji_test_poses,
    leftovers,
    raises_input_error,
    write_dji_photos,
)

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import pose_errors
from turbinefit.io.camera_yaml import read_camera_yaml
from turbinefit.io.flight_folder import keyframe_images
from turbinefit.io.georef import Georef, location_lines, read_georef_yaml
from turbinefit.io.tum import read_tum
from turbinefit.io.turbine_yaml import read_turbine_yaml, write_turbine_yaml
from turbinefit.jobs.import_dji import import_dji

TIMES = np.array([0.0, 2.125, 4.5, 6.000001, 9.75])
POSES = dji_test_poses(5)


@pytest.fixture
def photos(tmp_path: Path) -> Path:
    write_dji_photos(tmp_path / "photos", POSES, TIMES)
    return tmp_path / "photos"


def test_import_recovers_the_poses(photos: Path, tmp_path: Path) -> None:
    s = import_dji([photos], tmp_path / "flight", origin=DJI_ORIGIN)

    t, poses = read_tum(tmp_path / "flight" / "keyframes.txt")
    np.testing.assert_allclose(t, TIMES, atol=1e-9)
    dpos, dang = pose_errors(poses, POSES)
    assert dpos.max() < 0.01 and np.degrees(dang.max()) < 0.01
    assert dpos.max() < 1e-4 and np.degrees(dang.max()) < 1e-5  # what the digits allow
    assert read_georef_yaml(tmp_path / "flight" / "georef.yaml") == Georef(
        *DJI_ORIGIN, time_origin="2024-05-01T11:30:00.000000")
    assert (s.num_photos, s.camera, s.image_size, s.flights[0].flight_yaw) == (5, "DJI FC6310", (64, 48),
                                                                     [])
    assert s.flights[0].duration_s == pytest.approx(9.75)
    assert sorted(p.name for p in (tmp_path / "flight").iterdir()) == [
        "camera.yaml", "georef.yaml", "images", "keyframes.txt"]


def test_default_origin_is_the_first_photo_on_the_ground(tmp_path: Path) -> None:
    # the photos arrive out of order: the earliest one still sets the origin
    write_dji_photos(tmp_path / "photos", POSES, TIMES, names="IMG_{:04d}.jpg")
    first = tmp_path / "photos" / "IMG_0000.jpg"
    os.rename(first, tmp_path / "photos" / "IMG_9999.jpg")
    s = import_dji([tmp_path / "photos"], tmp_path / "flight")
    _, poses = read_tum(tmp_path / "flight" / "keyframes.txt")
    # the first camera is straight above the origin, at its height above the take-off point
    np.testing.assert_allclose(poses.translation[0, :2], 0.0, atol=1e-6)
    assert poses.translation[0, 2] == pytest.approx(POSES.translation[0, 2], abs=1e-3)
    assert s.flights[0].origin.altitude == pytest.approx(DJI_ORIGIN[2], abs=1e-3)
    # the frame differs from the truth's by the shift of the origin only (rotation < 0.001 deg)
    shift = poses.translation[0] - POSES.translation[0]
    np.testing.assert_allclose(poses.translation - shift, POSES.translation, atol=0.01)
    assert np.degrees(pose_errors(poses, POSES)[1].max()) < 1e-3


def test_images_are_hard_links_under_their_timestamps(photos: Path, tmp_path: Path) -> None:
    import_dji([photos], tmp_path / "flight", origin=DJI_ORIGIN)
    names = sorted(p.name for p in (tmp_path / "flight" / "images").iterdir())
    assert names == sorted(f"{t:.6f}.jpg" for t in TIMES)
    src = sorted(photos.iterdir())
    for k, name in enumerate(f"{t:.6f}.jpg" for t in TIMES):
        dst = tmp_path / "flight" / "images" / name
        assert os.path.samefile(dst, src[k])
    keyframe_images(tmp_path / "flight", TIMES)  # fit finds every photo


def test_copies_when_links_fail(photos: Path, tmp_path: Path,
                                monkeypatch: pytest.MonkeyPatch) -> None:
    def no_link(src: object, dst: object) -> None:
        raise OSError(18, "Invalid cross-device link")

    monkeypatch.setattr(os, "link", no_link)
    s = import_dji([photos], tmp_path / "flight", origin=DJI_ORIGIN)
    assert s.flights[0].images == "5 copies"
    dst = tmp_path / "flight" / "images" / "0.000000.jpg"
    assert dst.read_bytes() == (photos / "DJI_0000.JPG").read_bytes()
    assert not os.path.samefile(dst, photos / "DJI_0000.JPG")


def test_calibrated_intrinsics_win(tmp_path: Path) -> None:
    cam = PinholeCamera(64, 48, 51.5, 51.5, 31.25, 24.125)
    write_dji_photos(tmp_path / "photos", POSES, TIMES, camera=cam)
    s = import_dji([tmp_path / "photos"], tmp_path / "flight", origin=DJI_ORIGIN)
    assert read_camera_yaml(tmp_path / "flight" / "camera.yaml") == cam
    assert "Calibrated" in s.flights[0].intrinsics


def test_35mm_equivalent_focal_length(photos: Path, tmp_path: Path) -> None:
    import_dji([photos], tmp_path / "flight", origin=DJI_ORIGIN)
    cam = read_camera_yaml(tmp_path / "flight" / "camera.yaml")
    # 24 mm on the 43.27 mm diagonal of 35 mm film: 84.1 deg diagonal field of view
    diag_fov = 2 * np.degrees(np.arctan(np.hypot(64, 48) / 2 / cam.fx))
    assert diag_fov == pytest.approx(2 * np.degrees(np.arctan(np.hypot(36, 24) / 48)))
    assert (cam.cx, cam.cy, cam.fx) == (31.5, 23.5, cam.fy)


def test_flight_yaw_when_the_gimbal_yaw_is_missing(tmp_path: Path) -> None:
    write_dji_photos(tmp_path / "photos", POSES, TIMES, gimbal_yaw=False)
    s = import_dji([tmp_path / "photos"], tmp_path / "flight", origin=DJI_ORIGIN)
    assert len(s.flights[0].flight_yaw) == 5
    _, poses = read_tum(tmp_path / "flight" / "keyframes.txt")
    assert np.degrees(pose_errors(poses, POSES)[1].max()) < 1e-5  # flight yaw = gimbal yaw


def test_turbine_yaml_is_copied_or_placed(photos: Path, tmp_path: Path) -> None:
    write_turbine_yaml(tmp_path / "t.yaml", NRE, comment="from the data sheet")
    import_dji([photos], tmp_path / "a", origin=DJI_ORIGIN, turbine_yaml=tmp_path / "t.yaml")
    assert (tmp_path / "a" / "turbine.yaml").read_bytes() == (tmp_path / "t.yaml").read_bytes()
    # a georeferenced turbine file: its base moves to its latitude/longitude
    other = Georef(DJI_ORIGIN[0] + 0.001, DJI_ORIGIN[1] - 0.002, 10.0)
    with open(tmp_path / "t.yaml", "a") as f:
        f.write(location_lines(other, NRE))
    s = import_dji([photos], tmp_path / "b", origin=DJI_ORIGIN, turbine_yaml=tmp_path / "t.yaml")
    moved = read_turbine_yaml(tmp_path / "b" / "turbine.yaml")
    lat, lon, _ = other.geodetic([NRE.base_x, NRE.base_y, 0.0])
    x, y, _ = Georef(*DJI_ORIGIN).enu(lat, lon, DJI_ORIGIN[2])
    assert (moved.base_x, moved.base_y) == pytest.approx((x, y), abs=1e-3)
    assert abs(moved.base_x - NRE.base_x) > 50  # really moved
    assert moved.tower_height == NRE.tower_height and "base at" in (s.flights[0].turbine or "")


# ------------------------------------------------------------------ bad input

def _refused(inputs: list[Path], out: Path, path: Path | None, **kw: object) -> str:
    """``import_dji`` raises naming ``path`` (None: a command-line option), writes nothing
    and changes no input; returns the message."""
    parent = inputs[0].parent
    before = digest(parent)
    with pytest.raises(InputError) as info:
        import_dji(inputs, out, **kw)  # type: ignore[arg-type]
    if path is not None:
        assert str(info.value).startswith(f"{path}: "), info.value
    assert not out.exists()
    assert digest(parent) == before
    assert leftovers(out.parent) == []
    return str(info.value)


def test_photo_without_gps(tmp_path: Path) -> None:
    write_dji_photos(tmp_path / "photos", POSES, TIMES)
    buf = Image.new("RGB", (64, 48))
    exif = Image.Exif()
    exif.get_ifd(0x8769)[0x9003] = "2024:05:01 11:31:00"
    buf.save(tmp_path / "photos" / "DJI_0007.JPG", "JPEG", exif=exif)
    _refused([tmp_path / "photos"], tmp_path / "flight", tmp_path / "photos" / "DJI_0007.JPG")


def test_photo_without_gimbal(tmp_path: Path) -> None:
    write_dji_photos(tmp_path / "photos", POSES, TIMES)
    from turbinefit.sim.dji_photos import dji_metadata, dji_poses

    pose = dji_poses(Georef(*DJI_ORIGIN), POSES[:1], [0.0])[0]
    exif, xmp = dji_metadata(pose)
    xmp = xmp.replace(b"GimbalPitchDegree", b"CameraPitchDegree")
    Image.new("RGB", (64, 48)).save(tmp_path / "photos" / "DJI_0100.JPG", "JPEG", exif=exif,
                                    xmp=xmp)
    _refused([tmp_path / "photos"], tmp_path / "flight", tmp_path / "photos" / "DJI_0100.JPG")


def test_non_jpeg_among_the_photos(tmp_path: Path) -> None:
    files = write_dji_photos(tmp_path / "photos", POSES, TIMES)
    Image.new("RGB", (64, 48)).save(tmp_path / "photos" / "map.png")
    _refused([*files, tmp_path / "photos" / "map.png"], tmp_path / "flight",
             tmp_path / "photos" / "map.png")


def test_two_photos_at_one_time(tmp_path: Path) -> None:
    files = write_dji_photos(tmp_path / "photos", POSES, TIMES)
    shutil.copyfile(files[2], tmp_path / "photos" / "DJI_0002_copy.JPG")
    msg = _refused([tmp_path / "photos"], tmp_path / "flight", None)
    assert "DJI_0002.JPG" in msg and "DJI_0002_copy.JPG" in msg and "same time" in msg


def test_mixed_cameras_name_two_photos(tmp_path: Path) -> None:
    write_dji_photos(tmp_path / "photos", POSES, TIMES)
    write_dji_photos(tmp_path / "photos", POSES[:1], np.array([20.0]), size=(80, 60),
                     names="ZOOM_{:04d}.JPG")
    msg = _refused([tmp_path / "photos"], tmp_path / "flight",
                   tmp_path / "photos" / "ZOOM_0000.JPG")
    assert re.search(r"photos of 2 cameras: DJI FC6310 64x48 \(5 photos, first .*DJI_0000\.JPG\); "
                     r"DJI FC6310 80x60 \(1 photos, .*--camera", msg), msg


def test_turbine_by_position_not_in_the_photos_is_refused(photos: Path, tmp_path: Path) -> None:
    """``--turbine`` estimates turbine.yaml from the photos (turbinefit init near it):
    photos that do not show it are refused, naming what cannot be determined."""
    msg = _refused([photos], tmp_path / "flight", None, origin=DJI_ORIGIN,
                   turbine_location_deg=(DJI_ORIGIN[0] + 0.0005, DJI_ORIGIN[1]))
    assert re.match(r"--turbine: .*flight: cannot determine turbine: it is seen in 0 ", msg), msg
    assert "--turbine-yaml" in msg


def test_output_inside_the_photos_is_refused(photos: Path) -> None:
    _refused([photos], photos / "flight", photos / "flight")


def test_existing_flight_is_replaced_only_with_overwrite(photos: Path, tmp_path: Path) -> None:
    import_dji([photos], tmp_path / "flight", origin=DJI_ORIGIN)
    with raises_input_error(tmp_path / "flight"):
        import_dji([photos], tmp_path / "flight", origin=DJI_ORIGIN)
    import_dji([photos], tmp_path / "flight", overwrite=True)
    (tmp_path / "flight" / "notes.txt").write_text("mine")
    with raises_input_error(tmp_path / "flight"):
        import_dji([photos], tmp_path / "flight", overwrite=True)
