"""Tests of turbinefit.io: round trips of every format and every bad-input case."""

from __future__ import annotations

import math
import os
import re
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from io_helpers import H, W, camera, leftovers, make_flight, random_poses, timestamps, turbine

import turbinefit.io.flight_folder as flight_folder
from turbinefit.errors import InputError
from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.io import (
    atomic_output_dir,
    heatmap_filename,
    read_camera_yaml,
    read_flight,
    read_heatmaps,
    read_tum,
    read_turbine_yaml,
    write_bytes_atomic,
    write_camera_yaml,
    write_flight,
    write_text_atomic,
    write_tum,
    write_turbine_yaml,
)
from turbinefit.io.atomic import check_output_dir
from turbinefit.turbine.model import TurbineParams


def assert_poses_close(a: SE3, b: SE3, tol: float = 1e-9) -> None:
    assert a.batch_shape == b.batch_shape
    np.testing.assert_allclose(a.wxyz_xyz, b.wxyz_xyz, rtol=0, atol=tol)


def raises_input_error(path: Path, line: int | None = None, field: str | None = None):
    """pytest.raises for an InputError whose message names ``path`` (and line/field)."""
    pattern = "^" + re.escape(str(path))
    pattern += re.escape(f":{line}") if line is not None else r"(?::\d+)?"
    pattern += re.escape(f" [{field}]") if field is not None else r"(?: \[[^\]]*\])?"
    return pytest.raises(InputError, match=pattern + ": ")


# ================================================================================== TUM

def test_tum_round_trip_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    t = timestamps(50)
    poses = random_poses(rng, 50)
    path = tmp_path / "traj.txt"
    write_tum(path, t, poses)
    t2, poses2 = read_tum(path)
    np.testing.assert_allclose(t2, t, rtol=0, atol=1e-9)
    assert_poses_close(poses2, poses)
    assert np.all(poses2.wxyz[:, 0] >= 0)
    assert leftovers(tmp_path) == []


def test_tum_file_order_is_xyzw(tmp_path: Path) -> None:
    # 90 degrees about z: wxyz = (c, 0, 0, s)
    c = math.sqrt(0.5)
    poses = SE3(np.array([[c, 0.0, 0.0, c, 1.0, 2.0, 3.0]]))
    path = tmp_path / "one.txt"
    write_tum(path, [10.5], poses)
    data_lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    cols = [float(x) for x in data_lines[0].split()]
    assert cols[0] == 10.5
    assert cols[1:4] == [1.0, 2.0, 3.0]
    np.testing.assert_allclose(cols[4:], [0.0, 0.0, c, c], atol=1e-12)  # qx qy qz qw

    path.write_text("0.0 1 2 3 0.5 0.5 0.5 0.5\n")
    _, p = read_tum(path)
    np.testing.assert_allclose(p.wxyz_xyz[0], [0.5, 0.5, 0.5, 0.5, 1, 2, 3])


def test_tum_comments_blank_lines_normalisation(tmp_path: Path) -> None:
    path = tmp_path / "t.txt"
    path.write_text(
        "# TUM file\n"
        "\n"
        "1.0 0 0 0 0 0 0 1.0005   # slightly off unit norm\n"
        "   \n"
        "2.0\t1 2 3 0 0 0 -1\n"
        "# end\n")
    t, p = read_tum(path)
    np.testing.assert_array_equal(t, [1.0, 2.0])
    np.testing.assert_allclose(p.wxyz, [[1, 0, 0, 0], [1, 0, 0, 0]], atol=1e-15)  # w >= 0
    np.testing.assert_allclose(p.translation[1], [1, 2, 3])


@pytest.mark.parametrize(
    ("content", "line", "message"),
    [
        ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", 2, "expected 8 columns"),
        ("1 0 0 0 0 0 0 1 5\n", 1, "expected 8 columns"),
        ("1 0 0 0 0 0 0 1\n\n2 0 0 x 0 0 0 1\n", 3, "not a number: 'x'"),
        ("1 0 0 0 0 0 0 1\n2 0 0 1_0 0 0 0 1\n", 2, "not a number"),
        ("1 0 0 nan 0 0 0 1\n", 1, "non-finite"),
        ("1 0 0 0 0 0 0 inf\n", 1, "non-finite"),
        ("# c\n1 0 0 0 0 0 0 0\n", 2, "zero norm"),
        ("1 0 0 0 0 0 0 1.002\n", 1, "norm 1.002"),
        ("1 0 0 0 0.5 0 0 0.5\n", 1, "expected 1"),
        ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n1.5 0 0 0 0 0 0 1\n", 3, "not after"),
        ("1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", 2, "not after"),
    ],
)
def test_tum_bad_input_names_file_and_line(tmp_path: Path, content: str, line: int,
                                           message: str) -> None:
    path = tmp_path / "bad.txt"
    path.write_text(content)
    with raises_input_error(path, line) as info:
        read_tum(path)
    assert message in str(info.value)
    assert info.value.line == line


@pytest.mark.parametrize("content", ["", "# only a comment\n\n"])
def test_tum_empty_file(tmp_path: Path, content: str) -> None:
    path = tmp_path / "empty.txt"
    path.write_text(content)
    with raises_input_error(path) as info:
        read_tum(path)
    assert "no poses" in str(info.value)


def test_tum_missing_file_and_binary(tmp_path: Path) -> None:
    with raises_input_error(tmp_path / "nope.txt"):
        read_tum(tmp_path / "nope.txt")
    path = tmp_path / "bin.txt"
    path.write_bytes(b"\xff\xfe\x00\x81")
    with raises_input_error(path):
        read_tum(path)


def test_write_tum_rejects_bad_data(tmp_path: Path) -> None:
    path = tmp_path / "out.txt"
    poses = random_poses(np.random.default_rng(0), 2)
    with raises_input_error(path, field="timestamps"):
        write_tum(path, [1.0, 1.0000001], poses)  # same microsecond
    with raises_input_error(path, field="poses"):
        write_tum(path, [1.0, 2.0, 3.0], poses)
    bad = SE3(poses.wxyz_xyz * np.array([2.0, 2, 2, 2, 1, 1, 1]))
    with raises_input_error(path, field="poses"):
        write_tum(path, [1.0, 2.0], bad)
    assert not path.exists()
    assert leftovers(tmp_path) == []


# =============================================================================== camera

@pytest.mark.parametrize("distortion", [True, False])
def test_camera_round_trip(tmp_path: Path, distortion: bool) -> None:
    cam = camera(distortion)
    path = tmp_path / "camera.yaml"
    write_camera_yaml(path, cam, name="cam0")
    back = read_camera_yaml(path)
    assert back == cam
    assert back.distortion == cam.distortion
    assert back.has_distortion == distortion
    # ROS tools read it with plain yaml: every value a number, P = [K | 0], R = I
    data = yaml.safe_load(path.read_text())
    assert data["camera_name"] == "cam0"
    assert data["distortion_model"] == "plumb_bob"
    assert all(isinstance(v, float) for v in data["distortion_coefficients"]["data"])
    P = np.array(data["projection_matrix"]["data"]).reshape(3, 4)
    np.testing.assert_array_equal(P[:, :3], cam.K)
    np.testing.assert_array_equal(P[:, 3], 0.0)
    np.testing.assert_array_equal(np.array(data["rectification_matrix"]["data"]).reshape(3, 3),
                                  np.eye(3))


def test_camera_name_needing_quotes(tmp_path: Path) -> None:
    path = tmp_path / "camera.yaml"
    write_camera_yaml(path, camera(), name="yes: no")
    assert yaml.safe_load(path.read_text())["camera_name"] == "yes: no"
    assert read_camera_yaml(path) == camera()


OPENCV_YAML = """%YAML:1.0
---
calibration_time: "Mon 01 Jan 2024 12:00:00 GMT"
image_width: 640
image_height: 480
flags: 0
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 6.5746697810243404e+02, 0., 3.1950000000000000e+02, 0.,
       6.5746697810243404e+02, 2.3950000000000000e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -4.1802327018241026e-01, 5.0715243805833121e-01, 0., 0.,
       -5.7843596847939704e-01 ]
avg_reprojection_error: 3.9e-01
"""


def test_camera_opencv_filestorage(tmp_path: Path) -> None:
    path = tmp_path / "opencv.yaml"
    path.write_text(OPENCV_YAML)
    cam = read_camera_yaml(path)
    assert (cam.width, cam.height) == (640, 480)
    assert cam.fx == pytest.approx(657.46697810243404)
    assert cam.fy == pytest.approx(657.46697810243404)
    assert (cam.cx, cam.cy, cam.skew) == (319.5, 239.5, 0.0)
    assert cam.distortion == pytest.approx(
        (-0.41802327018241026, 0.50715243805833121, 0.0, 0.0, -0.57843596847939704))


def test_camera_opencv_error_line_numbers_kept(tmp_path: Path) -> None:
    path = tmp_path / "opencv.yaml"
    path.write_text(OPENCV_YAML.replace("flags: 0", "flags: [0"))
    with raises_input_error(path, line=7):  # the parser notices at the next key
        read_camera_yaml(path)


def ros_yaml(K: str = "[30.5, 0, 15.75, 0, 31.25, 11.5, 0, 0, 1]", krows: int = 3,
             model: str | None = "plumb_bob", dist: str | None = "[-0.1, 0.01, 0, 0]",
             drows: int = 1, dcols: int = 4, width: str = "32", extra: str = "") -> str:
    text = f"image_width: {width}\nimage_height: 24\ncamera_name: c\n"
    text += f"camera_matrix:\n  rows: {krows}\n  cols: 3\n  data: {K}\n"
    if model is not None:
        text += f"distortion_model: {model}\n"
    if dist is not None:
        text += f"distortion_coefficients:\n  rows: {drows}\n  cols: {dcols}\n  data: {dist}\n"
    return text + extra


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({}, (-0.1, 0.01, 0.0, 0.0, 0.0)),  # 4 coefficients padded
        ({"dist": "[1e-5, 0, 0, 0]"}, (1e-5, 0.0, 0.0, 0.0, 0.0)),  # YAML-1.1 "string" number
        ({"model": "none", "dist": "[]", "dcols": 0}, (0.0,) * 5),
        ({"model": "''", "dist": None}, (0.0,) * 5),
        ({"model": None, "dist": None}, (0.0,) * 5),
        ({"model": "plumb_bob", "dist": "[0, 0, 0, 0, 0]", "dcols": 5}, (0.0,) * 5),
        ({"model": "rational_polynomial", "dist": "[0.1, 0.2, 0.3, 0.4, 0.5, 0, 0, 0]",
          "dcols": 8}, (0.1, 0.2, 0.3, 0.4, 0.5)),
    ],
)
def test_camera_distortion_variants(tmp_path: Path, kwargs: dict, expected: tuple) -> None:
    path = tmp_path / "camera.yaml"
    path.write_text(ros_yaml(**kwargs))
    cam = read_camera_yaml(path)
    assert cam.distortion == expected
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (30.5, 31.25, 15.75,
                                                                         11.5, 32, 24)


@pytest.mark.parametrize(
    ("kwargs", "field", "message"),
    [
        ({"dist": "[0.1, 0.2, 0.3]", "dcols": 4}, "distortion_coefficients", "rows * cols"),
        ({"K": "[30.5, 0, 15.75, 0, 31.25, 11.5, 0, 0]"}, "camera_matrix", "rows * cols"),
        ({"K": "[30.5, 0, 15.75, 0, 31.25, 11.5]", "krows": 2}, "camera_matrix", "3x3"),
        ({"K": "[-30.5, 0, 15.75, 0, 31.25, 11.5, 0, 0, 1]"}, "camera_matrix", "fx"),
        ({"K": "[30.5, 0, 15.75, 0, 0, 11.5, 0, 0, 1]"}, "camera_matrix", "fy"),
        ({"K": "[30.5, 0, 15.75, 0, 31.25, 11.5, 0, 0, 2]"}, "camera_matrix", "not a camera"),
        ({"K": "[30.5, 0, .nan, 0, 31.25, 11.5, 0, 0, 1]"}, "camera_matrix.data[2]", "finite"),
        ({"K": "[30.5, 0, abc, 0, 31.25, 11.5, 0, 0, 1]"}, "camera_matrix.data[2]",
         "not a number"),
        ({"dist": "[.inf, 0, 0, 0]"}, "distortion_coefficients.data[0]", "finite"),
        ({"model": "equidistant"}, "distortion_model", "unsupported"),
        ({"model": "none"}, "distortion_coefficients", "not all zero"),
        ({"model": "rational_polynomial", "dist": "[0.1, 0, 0, 0, 0, 0.2, 0, 0]", "dcols": 8},
         "distortion_coefficients", "only plumb_bob"),
        ({"width": "-32"}, "image_width", "positive"),
        ({"width": "32.5"}, "image_width", "integer"),
        ({"width": "true"}, "image_width", "not a number"),
    ],
)
def test_camera_bad_input_names_file_and_field(tmp_path: Path, kwargs: dict, field: str,
                                               message: str) -> None:
    path = tmp_path / "camera.yaml"
    path.write_text(ros_yaml(**kwargs))
    with raises_input_error(path, field=field) as info:
        read_camera_yaml(path)
    assert message in str(info.value)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("image_width: 32\nimage_height: 24\n", "camera_matrix"),
        ("image_height: 24\ncamera_matrix: {rows: 3, cols: 3, data: [1,0,0,0,1,0,0,0,1]}\n",
         "image_width"),
        ("- 1\n- 2\n", "expected a YAML mapping"),
        ("", "empty"),
        ("image_width: [32\n", "invalid YAML"),
        ("image_width: 32\nimage_width: 33\n", "duplicate key"),
    ],
)
def test_camera_bad_files(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "camera.yaml"
    path.write_text(content)
    with raises_input_error(path) as info:
        read_camera_yaml(path)
    assert message in str(info.value)


# ============================================================================== turbine

def test_turbine_round_trip_exact(tmp_path: Path) -> None:
    params = TurbineParams(1e-7, -3.0000000000000004, 80.1, 1.2345678901234567, 0.0,
                           -0.3, 40.7)
    path = tmp_path / "turbine.yaml"
    write_turbine_yaml(path, params, comment="fitted\nby test")
    assert read_turbine_yaml(path) == params
    text = path.read_text()
    assert text.startswith("# fitted\n# by test\n")
    assert yaml.safe_load(text) == params.to_dict()


TURBINE_TEXT = ("base_x: 1.0\nbase_y: 2.0\ntower_height: 80\nheading: 0.5\n"
                "nacelle_length: 4.0\nblade_rotation: 0.1\nblade_length: 40.0\n")


def test_turbine_read_plain_file(tmp_path: Path) -> None:
    path = tmp_path / "turbine.yaml"
    path.write_text("# a turbine\n" + TURBINE_TEXT.replace("heading: 0.5", "heading: 5e-1"))
    assert read_turbine_yaml(path) == TurbineParams(1.0, 2.0, 80.0, 0.5, 4.0, 0.1, 40.0)


@pytest.mark.parametrize(
    ("old", "new", "field", "message"),
    [
        ("base_y: 2.0\n", "", "base_y", "missing"),
        ("heading: 0.5\n", "heading: 0.5\nrotor_speed: 3\n", "rotor_speed", "unknown key"),
        ("heading: 0.5", "heading: north", "heading", "not a number"),
        ("heading: 0.5", "heading: [0.5]", "heading", "not a number"),
        ("heading: 0.5", "heading: .nan", "heading", "finite"),
        ("base_x: 1.0", "base_x: -.inf", "base_x", "finite"),
        ("tower_height: 80", "tower_height: 0", "tower_height", "> 0"),
        ("blade_length: 40.0", "blade_length: -40.0", "blade_length", "> 0"),
        ("nacelle_length: 4.0", "nacelle_length: -0.1", "nacelle_length", ">= 0"),
    ],
)
def test_turbine_bad_input_names_file_and_key(tmp_path: Path, old: str, new: str, field: str,
                                              message: str) -> None:
    path = tmp_path / "turbine.yaml"
    assert old in TURBINE_TEXT
    path.write_text(TURBINE_TEXT.replace(old, new))
    with raises_input_error(path, field=field) as info:
        read_turbine_yaml(path)
    assert message in str(info.value)


def test_turbine_duplicate_key_and_not_mapping(tmp_path: Path) -> None:
    path = tmp_path / "turbine.yaml"
    path.write_text(TURBINE_TEXT + "heading: 0.7\n")
    with raises_input_error(path, line=8):
        read_turbine_yaml(path)
    path.write_text("just text\n")
    with raises_input_error(path):
        read_turbine_yaml(path)


def test_write_turbine_rejects_out_of_range(tmp_path: Path) -> None:
    path = tmp_path / "turbine.yaml"
    with raises_input_error(path, field="blade_length"):
        write_turbine_yaml(path, TurbineParams(0, 0, 80, 0, 4, 0, -40))
    assert not path.exists()


# ======================================================================= flight folder

def assert_flights_equal(a: Flight, b: Flight) -> None:
    assert a.camera == b.camera
    np.testing.assert_allclose(a.timestamps, b.timestamps, rtol=0, atol=1e-9)
    assert_poses_close(a.world_T_cam, b.world_T_cam)
    assert a.turbine == b.turbine
    assert a.gt_turbine == b.gt_turbine
    for name in ("odometry", "gt_world_T_cam"):
        pa, pb = getattr(a, name), getattr(b, name)
        assert (pa is None) == (pb is None)
        if pa is not None:
            assert_poses_close(pa, pb)
    assert len(a.heatmaps) == len(b.heatmaps)
    for k in range(len(a.heatmaps)):
        np.testing.assert_array_equal(a.heatmaps[k], b.heatmaps[k])


@pytest.mark.parametrize("mmap", [True, False])
def test_flight_round_trip_with_optional_files(tmp_path: Path, mmap: bool) -> None:
    flight = make_flight(optional=True)
    folder = tmp_path / "flight"
    assert write_flight(flight, folder) == folder
    names = sorted(p.name for p in folder.iterdir())
    assert names == ["camera.yaml", "groundtruth.txt", "heatmaps", "keyframes.txt",
                     "odometry.txt", "turbine.yaml", "turbine_groundtruth.yaml"]
    assert sorted(p.name for p in (folder / "heatmaps").iterdir()) == sorted(
        heatmap_filename(t) for t in flight.timestamps)
    assert heatmap_filename(flight.timestamps[0]) == "1567000000.123456.npy"
    assert np.load(folder / "heatmaps" / heatmap_filename(flight.timestamps[0])).dtype == \
        np.float32

    back = read_flight(folder, mmap=mmap)
    assert_flights_equal(back, flight)
    assert back.has_ground_truth
    m = back.heatmaps[2]
    assert m.dtype == np.float32 and m.shape == (7, H, W)
    assert m.flags.writeable is (not mmap)  # memory maps are read-only
    # the costs' access path works on both storages
    kf = np.array([0, 4])
    idx = np.array([[0, 7 * H * W - 1], [5, 123]])
    np.testing.assert_array_equal(
        back.heatmaps.gather(kf, idx), flight.heatmaps.gather(kf, idx))
    assert leftovers(tmp_path) == []


def test_flight_round_trip_minimal(tmp_path: Path) -> None:
    flight = make_flight(n=3, optional=False, distortion=False)
    folder = tmp_path / "a" / "b" / "flight"  # parents are created
    write_flight(flight, folder)
    assert sorted(p.name for p in folder.iterdir()) == ["camera.yaml", "heatmaps",
                                                        "keyframes.txt", "turbine.yaml"]
    back = read_flight(folder)
    assert_flights_equal(back, flight)
    assert back.odometry is None and back.gt_world_T_cam is None and back.gt_turbine is None
    assert not back.camera.has_distortion


def test_flight_heatmaps_converted_to_float32(tmp_path: Path) -> None:
    f32 = make_flight(n=2, optional=False)
    f64 = Flight(f32.camera, f32.timestamps, f32.world_T_cam,
                 HeatmapStack([f32.heatmaps[k].astype(np.float64) for k in range(2)]),
                 f32.turbine)
    write_flight(f64, tmp_path / "f")
    back = read_flight(tmp_path / "f")
    assert back.heatmaps[1].dtype == np.float32
    np.testing.assert_array_equal(back.heatmaps[1], f32.heatmaps[1])


def test_read_flight_1000_heatmaps_is_fast(tmp_path: Path) -> None:
    n, h, w = 1000, 6, 8
    hm = tmp_path / "heatmaps"
    hm.mkdir()
    rng = np.random.default_rng(3)
    t = timestamps(n)
    maps = rng.random((n, 7, h, w), dtype=np.float32)
    for k in range(n):
        np.save(hm / heatmap_filename(t[k]), maps[k])
    t0 = time.perf_counter()
    stack = read_heatmaps(hm, t, h, w, mmap=True)
    elapsed = time.perf_counter() - t0
    assert len(stack) == n
    np.testing.assert_array_equal(stack[999], maps[999])
    assert elapsed < 0.5, elapsed  # ~0.02 s on a laptop; generous for slow CI
    loaded = read_heatmaps(hm, t, h, w, mmap=False)
    np.testing.assert_array_equal(loaded[500], maps[500])


@pytest.fixture
def flight_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "flight"
    write_flight(make_flight(optional=True), folder)
    return folder


def test_read_flight_missing_folder_and_files(tmp_path: Path, flight_dir: Path) -> None:
    with raises_input_error(tmp_path / "nope"):
        read_flight(tmp_path / "nope")
    (tmp_path / "file").write_text("x")
    with raises_input_error(tmp_path / "file"):
        read_flight(tmp_path / "file")
    for name in ("camera.yaml", "keyframes.txt", "turbine.yaml"):
        (flight_dir / name).rename(tmp_path / name)
        with raises_input_error(flight_dir / name) as info:
            read_flight(flight_dir)
        assert "missing" in str(info.value)
        (tmp_path / name).rename(flight_dir / name)
    (flight_dir / "heatmaps").rename(tmp_path / "hm")
    with raises_input_error(flight_dir / "heatmaps"):
        read_flight(flight_dir)


def test_read_flight_heatmaps_not_a_directory(tmp_path: Path, flight_dir: Path) -> None:
    hm = flight_dir / "heatmaps"
    hm.rename(tmp_path / "hm")
    hm.write_text("x")
    with raises_input_error(hm) as info:
        read_flight(flight_dir)
    assert "not a directory" in str(info.value)
    with raises_input_error(hm) as info:
        read_heatmaps(hm, [0.0], H, W)
    assert "not a directory" in str(info.value)


@pytest.mark.parametrize("name", ["camera.yaml", "heatmaps", "odometry.txt", "."])
def test_read_flight_inaccessible_path_is_an_input_error(flight_dir: Path, name: str,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    # what os.stat says below a directory without search (x) permission; as root a chmod
    # would not deny anything, so fake it
    target = flight_dir if name == "." else flight_dir / name
    real_stat = os.stat

    def stat(path, *args, **kwargs):
        if isinstance(path, str | os.PathLike) and Path(path) == target:
            raise PermissionError(13, "Permission denied", str(path))
        return real_stat(path, *args, **kwargs)

    monkeypatch.setattr(flight_folder.os, "stat", stat)
    with raises_input_error(target) as info:
        read_flight(flight_dir)
    assert "cannot access: Permission denied" in str(info.value)


def test_read_flight_errors_inside_files_name_them(flight_dir: Path) -> None:
    kf = flight_dir / "keyframes.txt"
    lines = kf.read_text().splitlines()
    lines[3] = lines[3].replace(" ", " x ", 1)
    kf.write_text("\n".join(lines) + "\n")
    with raises_input_error(kf, line=4):
        read_flight(flight_dir)


def test_read_flight_missing_heatmap_names_file(flight_dir: Path) -> None:
    t = read_tum(flight_dir / "keyframes.txt")[0]
    missing = flight_dir / "heatmaps" / heatmap_filename(t[2])
    missing.unlink()
    with raises_input_error(missing) as info:
        read_flight(flight_dir)
    assert "keyframe 2" in str(info.value)
    assert "keyframes.txt, line" in str(info.value)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: np.save(p, np.zeros((7, H, W + 1), np.float32)), "shape (7, 24, 33)"),
        (lambda p: np.save(p, np.zeros((H, W), np.float32)), "shape (24, 32)"),
        (lambda p: np.save(p, np.zeros((7, H, W), np.float64)), "dtype <f8"),
        (lambda p: np.save(p, np.zeros((7, H, W), ">f4")), "dtype >f4"),
        (lambda p: np.save(p, np.asfortranarray(np.zeros((7, H, W), np.float32))), "Fortran"),
        (lambda p: p.write_bytes(b"this is not a numpy file at all"), "not a .npy"),
        (lambda p: p.write_bytes(b""), "not a .npy"),
        (lambda p: p.write_bytes(b"\x93NUMPY\x01\x00\x10\x00{'descr': garbage"), "header"),
        (lambda p: p.write_bytes(_npy_bytes()[:-10]), "truncated"),
    ],
)
@pytest.mark.parametrize("mmap", [True, False])
def test_read_flight_bad_heatmap_names_file(flight_dir: Path, make, message: str,
                                            mmap: bool) -> None:
    t = read_tum(flight_dir / "keyframes.txt")[0]
    bad = flight_dir / "heatmaps" / heatmap_filename(t[3])
    bad.unlink()
    make(bad)
    with raises_input_error(bad) as info:
        read_flight(flight_dir, mmap=mmap)
    assert message in str(info.value)


def _npy_bytes() -> bytes:
    import io
    buf = io.BytesIO()
    np.save(buf, np.zeros((7, H, W), np.float32))
    return buf.getvalue()


@pytest.mark.parametrize("name", ["odometry.txt", "groundtruth.txt"])
def test_read_flight_timestamp_mismatch(flight_dir: Path, name: str) -> None:
    path = flight_dir / name
    t, poses = read_tum(path)
    t_bad = t.copy()
    t_bad[2] += 2e-6
    write_tum(path, t_bad, poses)
    with raises_input_error(path, line=4) as info:  # a header line, then poses 0, 1, 2
        read_flight(flight_dir)
    assert "keyframe 2" in str(info.value)
    # within the tolerance is fine (edit the text: write_tum prints microseconds)
    write_tum(path, t, poses)
    lines = path.read_text().splitlines()
    _stamp, rest = lines[3].split(" ", 1)
    lines[3] = f"{t[2] + 6e-7:.7f} {rest}"
    path.write_text("\n".join(lines) + "\n")
    back = read_flight(flight_dir)
    assert 3e-7 < abs(read_tum(path)[0][2] - t[2]) < 1e-6
    attr = "odometry" if name == "odometry.txt" else "gt_world_T_cam"
    assert_poses_close(getattr(back, attr), poses)
    write_tum(path, t[:-1], poses[:-1])
    with raises_input_error(path) as info:
        read_flight(flight_dir)
    assert "4 poses but keyframes.txt has 5" in str(info.value)


def test_read_flight_bad_optional_turbine(flight_dir: Path) -> None:
    path = flight_dir / "turbine_groundtruth.yaml"
    path.write_text(path.read_text().replace("tower_height", "height"))
    with raises_input_error(path, field="height"):
        read_flight(flight_dir)


# ============================================================== atomic flight writing

def test_write_flight_refuses_non_empty_folder(tmp_path: Path, flight_dir: Path) -> None:
    before = sorted(p.name for p in flight_dir.iterdir())
    with raises_input_error(flight_dir) as info:
        write_flight(make_flight(seed=5), flight_dir)
    assert "overwrite" in str(info.value)
    assert sorted(p.name for p in flight_dir.iterdir()) == before
    assert leftovers(tmp_path) == []
    # an empty folder is fine
    empty = tmp_path / "empty"
    empty.mkdir()
    write_flight(make_flight(n=2), empty)
    assert len(read_flight(empty).timestamps) == 2
    # a file in the way is refused even with overwrite
    (tmp_path / "file").write_text("x")
    with raises_input_error(tmp_path / "file"):
        write_flight(make_flight(), tmp_path / "file", overwrite=True)


def test_write_flight_overwrite_replaces(tmp_path: Path, flight_dir: Path) -> None:
    new = make_flight(n=3, seed=9, optional=False)
    write_flight(new, flight_dir, overwrite=True)
    assert not (flight_dir / "odometry.txt").exists()
    assert len(list((flight_dir / "heatmaps").iterdir())) == 3
    assert_flights_equal(read_flight(flight_dir), new)
    assert leftovers(tmp_path) == []


def test_write_flight_overwrite_in_place_from_memory_maps(tmp_path: Path,
                                                          flight_dir: Path) -> None:
    original = read_flight(flight_dir, mmap=True)
    changed = Flight(original.camera, original.timestamps, original.world_T_cam,
                     original.heatmaps, turbine(offset=7.0), original.odometry)
    write_flight(changed, flight_dir, overwrite=True)
    back = read_flight(flight_dir, mmap=False)
    assert back.turbine.base_x == turbine().base_x + 7.0
    assert back.gt_turbine is None
    expected = make_flight(optional=True)
    for k in range(len(expected.heatmaps)):
        np.testing.assert_array_equal(back.heatmaps[k], expected.heatmaps[k])
    assert leftovers(tmp_path) == []


def test_write_flight_overwrite_refuses_foreign_folder(tmp_path: Path, flight_dir: Path) -> None:
    (flight_dir / "notes.md").write_text("mine")
    with raises_input_error(flight_dir) as info:
        write_flight(make_flight(), flight_dir, overwrite=True)
    assert "notes.md" in str(info.value)
    assert (flight_dir / "notes.md").read_text() == "mine"
    (flight_dir / "notes.md").unlink()
    (flight_dir / "heatmaps" / "readme.txt").write_text("x")
    with raises_input_error(flight_dir):
        write_flight(make_flight(), flight_dir, overwrite=True)


def test_write_flight_extra_texts_are_written_and_replaceable(tmp_path: Path) -> None:
    folder = tmp_path / "flight"
    write_flight(make_flight(n=2), folder, extra_texts={"simulation.yaml": "seed: 1\n"})
    assert (folder / "simulation.yaml").read_text() == "seed: 1\n"
    assert_flights_equal(read_flight(folder), make_flight(n=2))  # ignored on reading
    # a folder write_flight wrote, simulation.yaml included, is a flight folder to replace
    assert "simulation.yaml" in flight_folder.FLIGHT_ENTRIES
    flight_folder.check_flight_destination(folder, overwrite=True)
    write_flight(make_flight(n=3, seed=1), folder, overwrite=True,
                 extra_texts={"simulation.yaml": "seed: 2\n"})
    assert (folder / "simulation.yaml").read_text() == "seed: 2\n"
    write_flight(make_flight(n=3, seed=1), folder, overwrite=True)  # without one: removed
    assert not (folder / "simulation.yaml").exists()
    assert leftovers(tmp_path) == []
    # only names the guard accepts, and not the flight's own files
    for name in ("notes.txt", "camera.yaml", "heatmaps"):
        with pytest.raises(ValueError, match="extra_texts"):
            write_flight(make_flight(n=2), tmp_path / "other", extra_texts={name: "x"})
    assert not (tmp_path / "other").exists()


def test_check_flight_destination(tmp_path: Path, flight_dir: Path) -> None:
    flight_folder.check_flight_destination(tmp_path / "new")  # missing: fine
    with raises_input_error(flight_dir) as info:
        flight_folder.check_flight_destination(flight_dir, overwrite_hint="use --overwrite")
    assert str(info.value).endswith("not empty (use --overwrite)")
    flight_folder.check_flight_destination(flight_dir, overwrite=True)
    (flight_dir / "notes.md").write_text("mine")
    with raises_input_error(flight_dir) as info:
        flight_folder.check_flight_destination(flight_dir, overwrite=True)
    assert "'notes.md' is not part of a flight folder" in str(info.value)


@pytest.mark.parametrize("existing", [False, True])
def test_write_flight_failure_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                             existing: bool) -> None:
    folder = tmp_path / "flight"
    if existing:
        write_flight(make_flight(n=2, optional=False), folder)
    calls = {"n": 0}
    real_save = np.save

    def failing_save(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError(28, "No space left on device")
        return real_save(*args, **kwargs)

    monkeypatch.setattr(flight_folder.np, "save", failing_save)
    with pytest.raises(InputError, match="No space left"):
        write_flight(make_flight(n=5), folder, overwrite=True)
    assert calls["n"] == 3
    assert leftovers(tmp_path) == []
    if existing:
        assert len(read_flight(folder).timestamps) == 2  # old flight untouched
    else:
        assert not folder.exists()


def test_write_flight_rejects_timestamps_closer_than_a_microsecond(tmp_path: Path) -> None:
    f = make_flight(n=2, optional=False)
    bad = Flight(f.camera, np.array([5.0, 5.0000001]), f.world_T_cam, f.heatmaps, f.turbine)
    with raises_input_error(tmp_path / "f" / "keyframes.txt", field="timestamps"):
        write_flight(bad, tmp_path / "f")
    assert list(tmp_path.iterdir()) == []


# ================================================================================ atomic

def test_write_text_atomic_replaces_and_cleans_up(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "sub" / "a.txt"
    write_text_atomic(path, "one\n")
    write_text_atomic(path, "two\n")
    assert path.read_text() == "two\n"
    write_bytes_atomic(path, b"\x00\x01")
    assert path.read_bytes() == b"\x00\x01"

    def broken_replace(src: str, dst: str) -> None:
        raise OSError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", broken_replace)
    with raises_input_error(path):
        write_text_atomic(path, "three\n")
    monkeypatch.undo()
    assert path.read_bytes() == b"\x00\x01"
    assert leftovers(path.parent) == []
    with raises_input_error(tmp_path / "sub"):
        write_text_atomic(tmp_path / "sub", "x")


def test_atomic_output_dir(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with atomic_output_dir(out) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".out.tmp-")
        assert not out.exists()
        (tmp / "x.txt").write_text("1")
    assert (out / "x.txt").read_text() == "1"

    with pytest.raises(RuntimeError), atomic_output_dir(out, overwrite=True) as tmp:
        (tmp / "y.txt").write_text("2")
        raise RuntimeError("boom")
    assert sorted(p.name for p in out.iterdir()) == ["x.txt"]
    assert leftovers(tmp_path) == []

    with raises_input_error(out), atomic_output_dir(out):
        pass
    with atomic_output_dir(out, overwrite=True) as tmp:
        (tmp / "z.txt").write_text("3")
    assert sorted(p.name for p in out.iterdir()) == ["z.txt"]

    link = tmp_path / "link"
    link.symlink_to(out)
    with raises_input_error(link), atomic_output_dir(link, overwrite=True):
        pass
    assert leftovers(tmp_path) == []


def test_check_output_dir_refuses_what_atomic_output_dir_would(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    check_output_dir(tmp_path / "new" / "deeper")  # missing parents are created later
    (tmp_path / "empty").mkdir()
    check_output_dir(tmp_path / "empty")
    afile = tmp_path / "afile"
    afile.write_text("x")
    with raises_input_error(afile) as info:
        check_output_dir(afile, overwrite=True)
    assert "not a directory" in str(info.value)
    for below in (afile / "out", afile / "a" / "b"):  # the parent is a file: refused up front
        with raises_input_error(afile) as info:
            check_output_dir(below)
        assert "not a directory" in str(info.value)
        with raises_input_error(afile), atomic_output_dir(below):
            pass
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    with raises_input_error(loop) as info:
        check_output_dir(loop, overwrite=True)
    assert "symbolic link" in str(info.value)

    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "a.txt").write_text("1")
    with raises_input_error(busy) as info:
        check_output_dir(busy, overwrite_hint="use --force")
    assert str(info.value).endswith("not empty (use --force)")
    check_output_dir(busy, overwrite=True)

    def unreadable(path: Path) -> str | None:
        raise PermissionError(13, "Permission denied", str(path / "sub"))

    with raises_input_error(busy) as info:
        check_output_dir(busy, overwrite=True, may_replace=unreadable)
    assert "Permission denied" in str(info.value)

    import turbinefit.io.atomic as atomic

    monkeypatch.setattr(atomic.os, "access", lambda path, mode, **kw: False)  # a read-only parent
    with raises_input_error(tmp_path) as info:
        check_output_dir(tmp_path / "new")
    assert "no permission" in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "busy", "empty", "loop"]


def test_input_error_is_one_line_with_path(tmp_path: Path) -> None:
    path = tmp_path / "bad.txt"
    path.write_text("1 2 3\n")
    with pytest.raises(InputError) as info:
        read_tum(path)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}:1: ")
    assert info.value.path == path


def test_pinhole_from_yaml_equals_constructor(tmp_path: Path) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(ros_yaml(K="[30.5, 0.25, 15.75, 0, 31.25, 11.5, 0, 0, 1]"))
    assert read_camera_yaml(path) == PinholeCamera(32, 24, 30.5, 31.25, 15.75, 11.5, 0.25,
                                                   (-0.1, 0.01, 0.0, 0.0, 0.0))


def test_atomic_output_dir_restores_old_dir_when_final_rename_fails(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("old")
    real_rename = os.rename

    def rename(src: str | Path, dst: str | Path) -> None:
        if Path(src).name.startswith(".out.tmp-"):
            raise OSError(18, "Invalid cross-device link")
        real_rename(src, dst)

    monkeypatch.setattr(os, "rename", rename)
    with raises_input_error(out) as info, atomic_output_dir(out, overwrite=True) as tmp:
        (tmp / "new.txt").write_text("new")
    assert "cross-device" in str(info.value)
    assert sorted(p.name for p in out.iterdir()) == ["old.txt"]
    assert leftovers(tmp_path) == []
