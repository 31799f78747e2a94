"""``import dji`` on the structures real DJI files have, written without any real photo:
an MPF preview appended (Pillow's MPO), FLIR-cored payloads' unsigned XMP and missing 35 mm
equivalent, a 16:9 crop of a 4:3 sensor, DJI's DewarpData (checked against DJI's formula,
written here independently), RTK status, two flights in one folder, a payload's three
cameras, symbolic links; and the impossible positions, angles and cameras of issue 49."""

from __future__ import annotations

import math
import os
import re
import shutil
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from support import DJI_ORIGIN, digest, dji_test_poses, leftovers, write_dji_photos

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.io.camera_yaml import read_camera_yaml
from turbinefit.io.flight_folder import SIGMA_FILE, keyframe_images, read_flight_folder
from turbinefit.io.images import image_size, read_image
from turbinefit.io.tum import read_tum
from turbinefit.jobs.import_dji import import_dji
from turbinefit.sim.dji_photos import dewarp_text

TIMES = np.array([0.0, 2.0, 4.0, 6.0])
POSES = dji_test_poses(4)


def _import(tmp_path: Path, **kw: object) -> object:
    return import_dji([tmp_path / "photos"], tmp_path / "flight", origin=DJI_ORIGIN, **kw)  # type: ignore[arg-type]


def test_mpf_photos_read_as_jpegs(tmp_path: Path) -> None:
    """A JPEG with an MPF APP2 segment and a preview appended (as a Mavic, an H20T or an
    M30T writes it): metadata from the primary image, pixels from the first frame."""
    rng = np.random.default_rng(0)
    pixels = [rng.integers(0, 256, (48, 64, 3), dtype=np.uint8) for _ in TIMES]
    mpo = write_dji_photos(tmp_path / "photos", POSES, TIMES, images=pixels, preview=True)
    plain = write_dji_photos(tmp_path / "plain", POSES, TIMES, images=pixels)
    data = mpo[0].read_bytes()
    assert b"MPF\x00" in data[:2000] and data.count(b"\xff\xd8") >= 2  # APP2 MPF, 2nd image
    s = _import(tmp_path)
    assert s.num_photos == 4  # type: ignore[attr-defined]
    assert image_size(mpo[0]) == (64, 48)
    np.testing.assert_array_equal(read_image(mpo[0]), read_image(plain[0]))
    np.testing.assert_array_equal(read_image(mpo[0], reduce_to=(32, 24)),
                                  read_image(plain[0], reduce_to=(32, 24)))
    _, poses = read_tum(tmp_path / "flight" / "keyframes.txt")
    assert np.abs(poses.translation - POSES.translation).max() < 1e-3


def test_flir_payload_unsigned_without_35mm(tmp_path: Path) -> None:
    """Zenmuse XT2/XTR: Model FLIR, unsigned XMP numbers, a 19 mm lens and neither a 35 mm
    equivalent nor a focal-plane resolution: the pixel pitch comes from the camera table."""
    write_dji_photos(tmp_path / "photos", POSES, TIMES, size=(640, 512), model="FLIR",
                     focal_mm=19.0, focal_35mm=None, signed=False)
    text = (tmp_path / "photos" / "DJI_0000.JPG").read_bytes()
    assert b'GimbalPitchDegree="-' in text and b'="+' not in text
    s = _import(tmp_path)
    cam = read_camera_yaml(tmp_path / "flight" / "camera.yaml")
    assert cam.fx == pytest.approx(19.0 * 640 / (640 * 0.017))  # 17 um pixels
    assert "Zenmuse XT / XT2 / XTR thermal" in s.flights[0].intrinsics  # type: ignore[attr-defined]
    assert s.camera == "DJI FLIR thermal"  # type: ignore[attr-defined]


def test_35mm_equivalent_refers_to_the_full_frame(tmp_path: Path) -> None:
    """A 16:9 photo of a camera not in the table: the 35 mm equivalent is the 4:3 sensor's
    (its diagonal W * 5/4), not the photo's, and the output says the photo is a crop."""
    write_dji_photos(tmp_path / "photos", POSES, TIMES, size=(64, 36), model="FC9999",
                     focal_35mm=26.0)
    s = _import(tmp_path)
    cam = read_camera_yaml(tmp_path / "flight" / "camera.yaml")
    assert cam.fx == pytest.approx(26.0 * 64 * 1.25 / math.hypot(36, 24))
    assert cam.fx > 1.05 * 26.0 * math.hypot(64, 36) / math.hypot(36, 24)
    assert "crop of a 4:3 sensor" in (s.flights[0].crop or "")  # type: ignore[attr-defined]


def test_mavic_pro_16_9_uses_the_table(tmp_path: Path) -> None:
    """The issue's Mavic Pro (FC220) 4000x2250 photo with FocalLengthIn35mmFormat 26: the
    lens's 4.73 mm on the sensor's 6.17 mm width gives 3066 px (the photo's diagonal would
    give 2758 px, 10 % off)."""
    write_dji_photos(tmp_path / "photos", POSES[:2], TIMES[:2], size=(4000, 2250),
                     model="FC220", focal_mm=4.73, focal_35mm=26.0)
    _import(tmp_path)
    cam = read_camera_yaml(tmp_path / "flight" / "camera.yaml")
    assert cam.fx == pytest.approx(3066.45, rel=1e-3)


def _dji_distort(cam: tuple[float, ...], width: int, height: int, x: np.ndarray,
                 y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DJI's model, as its Mavic 3M image processing guide states it (OpenCV's undistort
    with the camera matrix [[fx, 0, W/2 + cx], [0, fy, H/2 + cy], [0, 0, 1]] and the
    coefficients k1, k2, p1, p2, k3), written out here on its own: the pixel of the
    normalised ray (x, y)."""
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = cam
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return fx * xd + width / 2 + cx, fy * yd + height / 2 + cy


def test_dewarp_data_becomes_the_camera(tmp_path: Path) -> None:
    """A P4 Multispectral-like DewarpData (the issue's coefficients) makes camera.yaml:
    its intrinsics and distortion; undistorting a grid of pixels with the written camera
    gives the rays DJI's formula maps to those pixels."""
    w, h = 1600, 1300
    dewarp = "2019-06-25;1943.4,1941.2,-12.5,8.25,-0.409,0.360,0.0004,-0.0003,-0.415"
    write_dji_photos(tmp_path / "photos", POSES[:2], TIMES[:2], size=(w, h), model="FC6360",
                     camera=PinholeCamera(w, h, 1913.3, 1913.3, 800, 650),
                     extra_xmp={"DewarpData": dewarp, "DewarpFlag": "0"})
    s = _import(tmp_path)
    cam = read_camera_yaml(tmp_path / "flight" / "camera.yaml")
    assert "DewarpData" in s.flights[0].intrinsics  # type: ignore[attr-defined]
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (1943.4, 1941.2, 800 - 12.5, 650 + 8.25)
    assert cam.distortion == (-0.409, 0.360, 0.0004, -0.0003, -0.415)
    dji = (1943.4, 1941.2, -12.5, 8.25, -0.409, 0.360, 0.0004, -0.0003, -0.415)
    # a grid of pixels over the central part of the photo (where the model is trusted)
    u, v = np.meshgrid(np.linspace(300, 1300, 9), np.linspace(250, 1050, 7))
    # undistort with the written camera: solve project(ray) = pixel by Newton's method
    x = (u - cam.cx) / cam.fx
    y = (v - cam.cy) / cam.fy
    for _ in range(30):
        pts = np.stack([x.ravel(), y.ravel(), np.ones(x.size)], -1)
        uv = cam.project_unbounded(pts)[0].reshape(*x.shape, 2)
        x = x - (uv[..., 0] - u) / cam.fx
        y = y - (uv[..., 1] - v) / cam.fy
    ud, vd = _dji_distort(dji, w, h, x, y)
    np.testing.assert_allclose(ud, u, atol=1e-6)
    np.testing.assert_allclose(vd, v, atol=1e-6)
    assert np.abs(x - (u - cam.cx) / cam.fx).max() > 0.01  # the distortion is not nothing


def test_dewarped_photos_have_no_distortion(tmp_path: Path) -> None:
    cam = PinholeCamera(640, 480, 500.0, 501.0, 322.0, 238.0,
                        distortion=(-0.2, 0.1, 0.0, 0.0, 0.01))
    write_dji_photos(tmp_path / "photos", POSES[:2], TIMES[:2], size=(640, 480),
                     extra_xmp={"DewarpData": dewarp_text(cam), "DewarpFlag": "1"})
    _import(tmp_path)
    out = read_camera_yaml(tmp_path / "flight" / "camera.yaml")
    assert (out.fx, out.fy, out.cx, out.cy) == pytest.approx((500.0, 501.0, 322.0, 238.0))
    assert out.distortion == (0.0,) * 5


def test_rtk_status_becomes_position_sigmas(tmp_path: Path) -> None:
    """RtkFlag 50 / 34 / 16 / none with their standard deviations: keyframes_sigma.csv,
    each raised to its solution's floor, read back with the flight."""
    photos = []
    for k, (flag, std) in enumerate([("50", "0.012"), ("50", "0.001"), ("34", "0.1"),
                                     ("16", "4.5")]):
        photos += write_dji_photos(
            tmp_path / "photos", POSES[k:k + 1], TIMES[k:k + 1], names=f"DJI_{k:04d}.JPG",
            extra_xmp={"RtkFlag": flag, "RtkStdLon": std, "RtkStdLat": std,
                       "RtkStdHgt": std})
    s = _import(tmp_path)
    assert s.flights[0].rtk == "RTK 2 fixed, 1 float, 1 single"  # type: ignore[attr-defined]
    folder = read_flight_folder(tmp_path / "flight")
    assert folder.position_sigma is not None
    np.testing.assert_allclose(folder.position_sigma, [
        [0.02, 0.02, 0.03], [0.02, 0.02, 0.03], [0.3, 0.3, 0.5], [4.5, 4.5, 5.0]])
    # without RTK fields there is no such file
    write_dji_photos(tmp_path / "plain", POSES, TIMES)
    import_dji([tmp_path / "plain"], tmp_path / "plain_flight", origin=DJI_ORIGIN)
    assert not (tmp_path / "plain_flight" / SIGMA_FILE).exists()
    assert read_flight_folder(tmp_path / "plain_flight").position_sigma is None


def test_two_flights_become_two_folders(tmp_path: Path) -> None:
    """Five photos on two days 13 months apart: two flight folders, each complete."""
    from turbinefit.sim.dji_photos import DEFAULT_START

    poses = dji_test_poses(5)
    write_dji_photos(tmp_path / "photos", poses[:3], np.array([0.0, 1.0, 2.0]))
    later = (DEFAULT_START + timedelta(days=396)) - DEFAULT_START
    write_dji_photos(tmp_path / "photos", poses[3:],
                     np.array([0.0, 3.0]) + later.total_seconds(), names="DJI_{:04d}_b.JPG")
    s = import_dji([tmp_path / "photos"], tmp_path / "out", origin=DJI_ORIGIN)
    assert [f.num_photos for f in s.flights] == [3, 2]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["flight-1", "flight-2"]
    for k, n in ((1, 3), (2, 2)):
        folder = read_flight_folder(tmp_path / "out" / f"flight-{k}")
        assert folder.num_keyframes == n and folder.timestamps[0] == 0.0
        keyframe_images(folder.root, folder.timestamps)
    # a bigger --max-gap makes them one flight; an existing output is replaced only with
    # overwrite, also when it held several flights
    s = import_dji([tmp_path / "photos"], tmp_path / "out", origin=DJI_ORIGIN,
                   max_gap_s=1e8, overwrite=True)
    assert len(s.flights) == 1 and (tmp_path / "out" / "keyframes.txt").exists()


def _refused(tmp_path: Path, pattern: str, inputs: list[Path] | None = None,
             **kw: object) -> str:
    before = digest(tmp_path / "photos")
    with pytest.raises(InputError) as info:
        import_dji(inputs or [tmp_path / "photos"], tmp_path / "flight", **kw)  # type: ignore[arg-type]
    assert re.search(pattern, str(info.value)), info.value
    assert not (tmp_path / "flight").exists() and leftovers(tmp_path) == []
    assert digest(tmp_path / "photos") == before
    return str(info.value)


def test_a_payloads_cameras_are_told_apart(tmp_path: Path) -> None:
    """An H20T capture's _W, _Z and _T photos: refused naming each camera, or one picked
    by --camera."""
    for suffix, size in (("W", (64, 48)), ("Z", (80, 60)), ("T", (64, 52))):
        write_dji_photos(tmp_path / "photos", POSES, TIMES, size=size, model="ZH20T",
                         names="DJI_{:04d}_" + suffix + ".JPG")
    msg = _refused(tmp_path, r"DJI_0000_W\.JPG: photos of 3 cameras: ")
    for cam in ("DJI ZH20T wide 64x48 (4 photos", "DJI ZH20T zoom 80x60", "DJI ZH20T thermal 64x52",
                "--camera"):
        assert cam in msg
    s = _import(tmp_path, camera="thermal")
    assert s.camera == "DJI ZH20T thermal" and s.image_size == (64, 52)  # type: ignore[attr-defined]
    assert len(s.other_cameras) == 2  # type: ignore[attr-defined]
    shutil.rmtree(tmp_path / "flight")
    _refused(tmp_path, r"--camera: photos of 3 cameras", camera="zh20t")
    _refused(tmp_path, r"--camera: no photos of camera 'xt2'", camera="xt2")


def test_symbolic_links(tmp_path: Path) -> None:
    """Relative symbolic links import (images/ links the photos, not the links); a
    dangling link or a loop is refused by name."""
    files = write_dji_photos(tmp_path / "real", POSES, TIMES)
    (tmp_path / "photos").mkdir()
    for f in files:
        os.symlink(os.path.join("..", "real", f.name), tmp_path / "photos" / f.name)
    _import(tmp_path)
    folder = read_flight_folder(tmp_path / "flight")
    for p in keyframe_images(folder.root, folder.timestamps):
        assert not p.is_symlink() and read_image(p).shape == (48, 64, 3)
    shutil.rmtree(tmp_path / "flight")
    os.symlink("nowhere.JPG", tmp_path / "photos" / "DJI_9998.JPG")
    _refused(tmp_path, r"DJI_9998\.JPG: symbolic link to 'nowhere\.JPG', which does not exist")
    os.remove(tmp_path / "photos" / "DJI_9998.JPG")
    os.symlink("DJI_9999.JPG", tmp_path / "photos" / "DJI_9999.JPG")
    _refused(tmp_path, r"DJI_9999\.JPG: symbolic link loop")


def test_concurrent_run_is_told_the_option(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                           ) -> None:
    """The loser of two concurrent runs is told to use --overwrite (not a parameter)."""
    import turbinefit.jobs.import_dji as job

    write_dji_photos(tmp_path / "photos", POSES, TIMES)
    real = job.link_photos

    def racing(*args: object) -> str:
        (tmp_path / "flight").mkdir()
        (tmp_path / "flight" / "camera.yaml").write_text("other run")
        return real(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(job, "link_photos", racing)
    with pytest.raises(InputError, match=r"another process wrote .*\(use --overwrite\)"):
        _import(tmp_path)


# ------------------------------------------------------------------ issue 49: impossible input

def _photos_with(tmp_path: Path, k: int, **meta: object) -> None:
    """Four photos, photo ``k`` written with other metadata (``lat``/``lon``/``alt``
    override its position; the rest are options of dji_metadata)."""
    from turbinefit.io.georef import Georef
    from turbinefit.sim.dji_photos import dji_poses, write_dji_photo

    poses = dji_poses(Georef(*DJI_ORIGIN), POSES, TIMES)
    (tmp_path / "photos").mkdir(exist_ok=True)
    for i, pose in enumerate(poses):
        kw: dict[str, object] = {}
        if i == k:
            over = {key: meta.pop(key) for key in ("latitude", "longitude", "altitude", "time",
                                                   "pitch", "roll") if key in meta}
            from dataclasses import replace

            pose = replace(pose, **over)  # type: ignore[arg-type]
            kw = dict(meta)
        write_dji_photo(tmp_path / "photos" / f"DJI_{i:04d}.JPG",
                        np.full((48, 64, 3), 100, np.uint8), pose, **kw)  # type: ignore[arg-type]


@pytest.mark.parametrize(("k", "meta", "pattern"), [
    (2, {"latitude": 0.0, "longitude": 0.0}, r"DJI_0002\.JPG: at latitude 0, longitude 0"),
    (1, {"latitude": -DJI_ORIGIN[0]}, r"DJI_0001\.JPG: 993\d km from the flight's other"),
    (3, {"longitude": -DJI_ORIGIN[1]}, r"DJI_0003\.JPG: 3[56]\d km from the flight's other"),
    (0, {"altitude": 1e7}, r"DJI_0000\.JPG \[drone-dji:AbsoluteAltitude\]: altitude "
                           r"10000000\.0 m is out of range"),
    (1, {"pitch": 200.0}, r"DJI_0001\.JPG \[drone-dji:GimbalPitchDegree\]: gimbal pitch 200"),
    (2, {"roll": 1e6}, r"DJI_0002\.JPG \[drone-dji:GimbalRollDegree\]: gimbal roll 1000000"),
    (0, {"focal_35mm": 60000.0}, r"DJI_0000\.JPG \[EXIF FocalLengthIn35mmFilm\]"),
    (0, {"extra_xmp": {"CalibratedFocalLength": "50", "CalibratedOpticalCenterX": "1e6"}},
     r"DJI_0000\.JPG \[drone-dji:CalibratedFocalLength\]: principal point cx = 1000000"),
    (0, {"extra_xmp": {"RelativeAltitude": "-1e9"}}, r"RelativeAltitude\]: relative altitude"),
])
def test_impossible_metadata_is_refused(tmp_path: Path, k: int, meta: dict[str, object],
                                        pattern: str) -> None:
    _photos_with(tmp_path, k, **meta)
    _refused(tmp_path, pattern, origin=None)


def test_impossible_flights_are_refused(tmp_path: Path) -> None:
    from turbinefit.sim.dji_photos import DEFAULT_START

    # a clock five years behind: alone in a flight of its own
    _photos_with(tmp_path, 0, time=DEFAULT_START - timedelta(days=5 * 365))
    _refused(tmp_path, r"DJI_0000\.JPG: taken 1825\.\d days from any other photo .*wrong clock")
    shutil.rmtree(tmp_path / "photos")
    # every photo at 0, 0
    for k in range(4):
        _photos_with(tmp_path, k, latitude=0.0, longitude=0.0)
        if k < 3:
            shutil.copyfile(tmp_path / "photos" / f"DJI_{k:04d}.JPG", tmp_path / f"{k}.JPG")
    for k in range(3):
        shutil.copyfile(tmp_path / f"{k}.JPG", tmp_path / "photos" / f"DJI_{k:04d}.JPG")
    _refused(tmp_path, r"every photo of the flight \(4\) is at latitude 0, longitude 0")
    shutil.rmtree(tmp_path / "photos")
    # an origin far from every photo
    _photos_with(tmp_path, 0)
    _refused(tmp_path, r"--origin: 49\d\d km from the photos", origin=(0.0, 0.0, 0.0))
