"""Camera files (turbinefit.io.camera_yaml): round trips, OpenCV and ROS layouts,
distortion variants, bad input named by file and field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from support import raises_input_error, tiny_camera

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.io import read_camera_yaml, write_camera_yaml


@pytest.mark.parametrize("distortion", [True, False])
def test_camera_round_trip(tmp_path: Path, distortion: bool) -> None:
    cam = tiny_camera(distortion)
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
    write_camera_yaml(path, tiny_camera(), name="yes: no")
    assert yaml.safe_load(path.read_text())["camera_name"] == "yes: no"
    assert read_camera_yaml(path) == tiny_camera()


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
             model: str | None = "plumb_bob", dist: str | None = "[-0.1, 0.01, 0, 0, 0]",
             drows: int = 1, dcols: int = 5, width: str = "32", extra: str = "") -> str:
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
        ({}, (-0.1, 0.01, 0.0, 0.0, 0.0)),
        # OpenCV's 4 coefficients (no model) padded; a YAML-1.1 "string" number
        ({"model": None, "dist": "[1e-5, 0, 0, 0]", "dcols": 4}, (1e-5, 0.0, 0.0, 0.0, 0.0)),
        ({"model": "none", "dist": "[]", "dcols": 0}, (0.0,) * 5),
        ({"model": "''", "dist": None}, (0.0,) * 5),
        ({"model": "plumb_bob", "dist": "[]", "dcols": 0}, (0.0,) * 5),
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
        ({"K": "[0.0, 0, 15.75, 0, 31.25, 11.5, 0, 0, 1]"}, "camera_matrix", "got 0.0"),
        ({"K": "[30.5, 0, 15.75, 0, 0, 11.5, 0, 0, 1]"}, "camera_matrix", "fy"),
        ({"K": "[30.5, 0, 15.75, 0, 31.25, 11.5, 0, 0, 2]"}, "camera_matrix", "not a camera"),
        ({"K": "[30.5, 0, .nan, 0, 31.25, 11.5, 0, 0, 1]"}, "camera_matrix.data[2]", "finite"),
        ({"K": "[30.5, 0, abc, 0, 31.25, 11.5, 0, 0, 1]"}, "camera_matrix.data[2]",
         "not a number"),
        ({"dist": "[.inf, 0, 0, 0, 0]"}, "distortion_coefficients.data[0]", "finite"),
        # coefficient counts per model, a file cut before its distortion block
        ({"dist": "[0.1, 0.2, 0.3]", "dcols": 3}, "distortion_coefficients",
         "3 distortion coefficients; distortion_model plumb_bob has 0 or 5"),
        ({"model": None, "dist": "[0.1, 0.2, 0.3]", "dcols": 3}, "distortion_coefficients",
         "OpenCV file without distortion_model has 0 or 4 or 5 or 8 or 12 or 14"),
        ({"model": "rational_polynomial"}, "distortion_coefficients", "has 0 or 8"),
        ({"model": None, "dist": None}, "distortion_coefficients", "missing (is the file cut"),
        ({"dist": None}, "distortion_coefficients", "missing"),
        ({"dist": "[1e6, 0, 0, 0, 0]"}, "distortion_coefficients", "coefficient 0 is 1000000.0"),
        # implausible intrinsics
        ({"K": "[30.5, 1e12, 15.75, 0, 31.25, 11.5, 0, 0, 1]"}, "camera_matrix",
         "skew 1000000000000.0 px is implausible"),
        ({"K": "[1e9, 0, 15.75, 0, 1e9, 11.5, 0, 0, 1]"}, "camera_matrix", "not a focal length"),
        ({"K": "[0.1, 0, 15.75, 0, 0.1, 11.5, 0, 0, 1]"}, "camera_matrix", "not a focal length"),
        ({"K": "[30.5, 0, 15.75, 0, 3000, 11.5, 0, 0, 1]"}, "camera_matrix", "fy / fx"),
        ({"K": "[30.5, 0, 1e5, 0, 31.25, 11.5, 0, 0, 1]"}, "camera_matrix",
         "principal point cx = 100000.0 px is far outside"),
        ({"K": "[30.5, 0, 15.75, 0, 31.25, -40, 0, 0, 1]"}, "camera_matrix", "principal point cy"),
        ({"width": "7"}, "image_width, image_height", "7x24 px; each side must be at least 24"),
        ({"width": "100000000"}, "image_width, image_height", "more than the 200 MP limit"),
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


def test_pinhole_from_yaml_equals_constructor(tmp_path: Path) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(ros_yaml(K="[30.5, 0.25, 15.75, 0, 31.25, 11.5, 0, 0, 1]"))
    assert read_camera_yaml(path) == PinholeCamera(32, 24, 30.5, 31.25, 15.75, 11.5, 0.25,
                                                   (-0.1, 0.01, 0.0, 0.0, 0.0))
