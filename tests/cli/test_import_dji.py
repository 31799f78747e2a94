"""``turbinefit import dji``: the command's output and errors, and the round trip simulator
-> DJI photos -> import -> fit, which must fit exactly as the simulator's own folder does,
with WGS84 outputs consistent with the photos' convention."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from support import (
    DJI_ORIGIN,
    assert_one_line_error,
    dji_test_poses,
    poses_array,
    run,
    write_dji_photos,
)

from turbinefit.geometry.se3 import pose_errors
from turbinefit.io.camera_yaml import read_camera_yaml
from turbinefit.io.georef import Georef, turbine_location, world_T_cam_from_gimbal
from turbinefit.io.tum import read_tum
from turbinefit.io.turbine_yaml import read_turbine_yaml

ORIGIN_ARG = ",".join(str(x) for x in DJI_ORIGIN)


def test_help(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        run(capsys, "import", "dji", "--help")
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for option in ("--out", "--origin", "--turbine-yaml", "--turbine", "--overwrite"):
        assert option in out


def test_import_prints_what_it_made(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_dji_photos(tmp_path / "photos", dji_test_poses(3), np.array([0.0, 1.5, 3.0]),
                     gimbal_yaw=False)
    rc, out, err = run(capsys, "import", "dji", str(tmp_path / "photos"), "--out",
                       str(tmp_path / "flight"))
    assert rc == 0 and err == ""
    lines = out.splitlines()
    assert lines[0].startswith(f"imported 3 photos (DJI FC6310, 64x48) to {tmp_path / 'flight'}")
    assert "the first photo, DJI_0000.JPG, at ground level" in out
    assert "note: 3 photo(s) with no gimbal yaw; used the aircraft's flight yaw" in out
    assert "no turbine.yaml" in lines[-1]


@pytest.mark.parametrize("case", ["not a photo", "no gimbal", "same time",
                                  "turbine position"])
def test_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                               case: str) -> None:
    files = write_dji_photos(tmp_path / "photos", dji_test_poses(3), np.array([0.0, 1.0, 2.0]),
                             gimbal_yaw=case != "no gimbal", xmp_position=True)
    args = [str(tmp_path / "photos")]
    patterns: tuple[str, ...] = ()
    if case == "not a photo":
        Image.new("RGB", (8, 8)).save(tmp_path / "photos" / "DJI_0009.JPG", "PNG")
        patterns = ("DJI_0009.JPG: not a JPEG",)
    elif case == "no gimbal":
        for f in files:  # no gimbal yaw and no flight yaw either
            img = Image.open(f)
            xmp = img.info["xmp"].replace(b"FlightYawDegree", b"FlightYaw")
            exif = img.getexif()
            img.save(tmp_path / "x.jpg", "JPEG", exif=exif, xmp=xmp)
            img.close()
            shutil.move(tmp_path / "x.jpg", f)
        patterns = ("DJI_0000.JPG: no yaw",)
    elif case == "same time":
        shutil.copyfile(files[1], tmp_path / "photos" / "DJI_0001b.JPG")
        patterns = ("DJI_0001b.JPG: taken at the same time as .*DJI_0001.JPG",)
    else:
        args += ["--turbine", "51.455,-2.588"]
        patterns = ("--turbine: ", "cannot determine turbine")
    rc, out, err = run(capsys, "import", "dji", *args, "--out", str(tmp_path / "flight"))
    assert_one_line_error(rc, out, err, *patterns)
    assert not (tmp_path / "flight").exists()


@pytest.mark.parametrize(("option", "value", "pattern"), [
    ("--origin", "95,0,10", r"--origin: latitude 95\.0 deg is out of range"),
    ("--max-gap", "-5", r"--max-gap: gap between flights -5\.0 s is out of range"),
])
def test_bad_options_are_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                      option: str, value: str, pattern: str) -> None:
    write_dji_photos(tmp_path / "photos", dji_test_poses(2), np.array([0.0, 1.0]))
    with pytest.raises(SystemExit) as exc:
        run(capsys, "import", "dji", str(tmp_path / "photos"), "--out",
            str(tmp_path / "flight"), option, value)
    assert exc.value.code == 2
    assert re.search(pattern, capsys.readouterr().err.splitlines()[-1])
    assert not (tmp_path / "flight").exists()


# ------------------------------------------------------------------ the round trip

@pytest.fixture(scope="module")
def round_trip(photo_flight_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The simulator's 6-photo flight twice: ``sim`` (its own folder, PNG photos replaced
    by the JPEGs below, same pixels) and ``imported`` (``import dji`` of DJI-style JPEGs
    written from its keyframe poses, its world frame taken as ENU about DJI_ORIGIN)."""
    from turbinefit.cli import main

    root = tmp_path_factory.mktemp("dji_round_trip")
    t, poses = read_tum(photo_flight_dir / "keyframes.txt")
    pngs = [photo_flight_dir / "images" / f"{x:.6f}.png" for x in t]
    camera = read_camera_yaml(photo_flight_dir / "camera.yaml")
    jpegs = write_dji_photos(root / "photos", poses, t,
                             images=[np.asarray(Image.open(p).convert("RGB")) for p in pngs],
                             camera=camera, quality=95)
    sim = Path(shutil.copytree(photo_flight_dir, root / "sim"))
    shutil.rmtree(sim / "images")
    (sim / "images").mkdir()
    for x, jpeg in zip(t, jpegs, strict=True):
        shutil.copyfile(jpeg, sim / "images" / f"{x:.6f}.jpg")
    assert main(["import", "dji", str(root / "photos"), "--out", str(root / "imported"),
                 "--origin", ORIGIN_ARG, "--turbine-yaml", str(sim / "turbine.yaml"),
                 "--quiet"]) == 0
    for name in ("sim", "imported"):
        assert main(["fit", str(root / name), "--out", str(root / f"fit_{name}"),
                     "--from-images", "--no-plots", "--quiet"]) == 0
    return root


def test_import_gives_the_simulator_s_flight(round_trip: Path, photo_flight_dir: Path) -> None:
    t_sim, sim = poses_array(photo_flight_dir / "keyframes.txt")
    t_imp, imp = poses_array(round_trip / "imported" / "keyframes.txt")
    np.testing.assert_allclose(t_imp, t_sim, atol=1e-9)
    np.testing.assert_allclose(imp[:, 4:], sim[:, 4:], atol=1e-3)  # positions [m]
    np.testing.assert_allclose(imp[:, :4], sim[:, :4], atol=1e-7)  # quaternions
    cam_sim = read_camera_yaml(photo_flight_dir / "camera.yaml")
    cam_imp = read_camera_yaml(round_trip / "imported" / "camera.yaml")
    assert (cam_imp.width, cam_imp.height) == (cam_sim.width, cam_sim.height)
    np.testing.assert_allclose(cam_imp.K, cam_sim.K, atol=1e-6)


def test_fit_of_the_import_equals_the_fit_of_the_simulator_s_folder(round_trip: Path) -> None:
    _, a = poses_array(round_trip / "fit_sim" / "keyframes.txt")
    _, b = poses_array(round_trip / "fit_imported" / "keyframes.txt")
    np.testing.assert_allclose(b[:, 4:], a[:, 4:], atol=1e-3)
    np.testing.assert_allclose(b[:, :4], a[:, :4], atol=1e-6)
    ta = read_turbine_yaml(round_trip / "fit_sim" / "turbine.yaml").to_vector()
    tb = read_turbine_yaml(round_trip / "fit_imported" / "turbine.yaml").to_vector()
    np.testing.assert_allclose(tb, ta, atol=1e-3)
    assert not (round_trip / "fit_sim" / "keyframes_wgs84.csv").exists()


def test_fit_gives_wgs84_in_the_photos_convention(round_trip: Path) -> None:
    fit = round_trip / "fit_imported"
    origin = Georef(*DJI_ORIGIN)
    t, poses = read_tum(fit / "keyframes.txt")
    rows = np.loadtxt(fit / "keyframes_wgs84.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(rows[:, 0], t, atol=1e-6)
    # the rows, read back as import dji reads a photo, are the fitted poses
    back = world_T_cam_from_gimbal(origin, *rows[:, 1:].T)
    dpos, dang = pose_errors(back, poses)
    assert dpos.max() < 1e-3 and np.degrees(dang.max()) < 1e-5
    turbine = read_turbine_yaml(fit / "turbine.yaml")
    lat, lon = turbine_location(fit / "turbine.yaml") or (np.nan, np.nan)
    np.testing.assert_allclose(origin.enu(lat, lon, DJI_ORIGIN[2])[:2],
                               [turbine.base_x, turbine.base_y], atol=1e-3)


def test_fit_s_wgs84_outputs_open_in_gis_tools_as_wgs84_points(round_trip: Path) -> None:
    """keyframes_wgs84.csv opens in GDAL (QGIS's reader; pyogrio here) as EPSG:4326 points
    without open options, from its .csvt and .prj; its GeoJSON twin holds the same points;
    turbine.glb records the origin."""
    import json
    import struct

    pyogrio = pytest.importorskip("pyogrio")
    fit = round_trip / "fit_imported"
    rows = np.loadtxt(fit / "keyframes_wgs84.csv", delimiter=",", skiprows=1)
    for name in ("keyframes_wgs84.csv", "keyframes_wgs84.geojson"):
        info = pyogrio.read_info(fit / name)
        assert info["crs"] in ("EPSG:4326", "EPSG:4979") and info["features"] == len(rows)
        assert info["geometry_type"].startswith("Point")
        _, _, geometry, _ = pyogrio.raw.read(fit / name)
        # WKB points: byte order, type, then x = longitude, y = latitude
        xy = np.array([struct.unpack("<dd", g[5:21]) for g in geometry])
        np.testing.assert_allclose(xy, rows[:, [2, 1]], atol=1e-9)
    data = (fit / "turbine.glb").read_bytes()
    doc = json.loads(data[20:20 + struct.unpack("<I", data[12:16])[0]])
    block = doc["asset"]["extras"]["turbinefit_georeference"]
    assert (block["latitude"], block["longitude"], block["altitude"]) == pytest.approx(DJI_ORIGIN)


def test_track_of_the_import_gives_wgs84(round_trip: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    rc, _, err = run(capsys, "track", str(round_trip / "imported"), "--out",
                     str(round_trip / "track"), "--from-images", "--no-plots", "--quiet")
    assert rc == 0, err
    lines = (round_trip / "track" / "keyframes_wgs84.csv").read_text().splitlines()
    assert len(lines) == 7 and lines[0].startswith("timestamp,latitude")
    assert turbine_location(round_trip / "track" / "turbine.yaml") is not None
