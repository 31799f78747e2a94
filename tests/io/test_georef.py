"""Georeferenced flights: the gimbal-angle convention against hand-checked directions,
exact round trips WGS84 <-> ENU poses, georef.yaml, and the fit outputs' WGS84 files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support import DJI_ORIGIN, NRE, dji_test_poses, raises_input_error

from turbinefit.geometry.se3 import pose_errors
from turbinefit.io.georef import (
    WGS84_HEADER,
    Georef,
    format_georef_yaml,
    gimbal_from_world_T_cam,
    location_text,
    read_georef_yaml,
    turbine_location,
    world_T_cam_from_gimbal,
    write_georef_outputs,
)
from turbinefit.io.turbine_yaml import read_turbine_yaml, write_turbine_yaml

ORIGIN = Georef(*DJI_ORIGIN)


def _axes(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Camera axes (columns x, y, z) in ENU of a camera at the origin."""
    T = world_T_cam_from_gimbal(ORIGIN, [ORIGIN.latitude], [ORIGIN.longitude],
                                [ORIGIN.altitude], [yaw], [pitch], [roll])
    return T.rotation_matrix()[0]


@pytest.mark.parametrize(("yaw", "pitch", "view", "right"), [
    (0.0, 0.0, (0, 1, 0), (1, 0, 0)),      # level, north: image x points east
    (90.0, 0.0, (1, 0, 0), (0, -1, 0)),    # east: image x points south
    (-90.0, 0.0, (-1, 0, 0), (0, 1, 0)),   # west
    (180.0, -90.0, (0, 0, -1), (-1, 0, 0)),  # straight down, top of the image south
])
def test_gimbal_angles_point_the_camera(yaw: float, pitch: float, view: tuple, right: tuple
                                        ) -> None:
    R = _axes(yaw, pitch, 0.0)
    np.testing.assert_allclose(R[:, 2], view, atol=1e-12)
    np.testing.assert_allclose(R[:, 0], right, atol=1e-12)


def test_look_direction_and_roll_sign() -> None:
    yaw, pitch = np.radians(30.0), np.radians(-40.0)
    R = _axes(30.0, -40.0, 0.0)
    expected = [np.sin(yaw) * np.cos(pitch), np.cos(yaw) * np.cos(pitch), np.sin(pitch)]
    np.testing.assert_allclose(R[:, 2], expected, atol=1e-12)
    # positive roll: the image's right side goes down (x turns towards y)
    R = _axes(0.0, 0.0, 10.0)
    assert R[2, 0] < 0 and abs(R[2, 0] + np.sin(np.radians(10.0))) < 1e-12
    np.testing.assert_allclose(R[:, 2], (0, 1, 0), atol=1e-12)


def test_round_trip_is_exact() -> None:
    poses = dji_test_poses(7)
    w = gimbal_from_world_T_cam(ORIGIN, poses)
    back = world_T_cam_from_gimbal(ORIGIN, w.latitude, w.longitude, w.altitude, w.yaw,
                                   w.pitch, w.roll)
    dpos, dang = pose_errors(back, poses)
    assert dpos.max() < 1e-6 and dang.max() < 1e-12
    assert np.all(np.abs(w.yaw) <= 180.0) and np.all(np.abs(w.roll) < 10.0)


def test_far_from_the_origin_the_local_north_turns() -> None:
    """10 km east, a camera looking at local north is turned by the meridians' convergence
    (about 0.07 deg at this latitude), which the conversion keeps."""
    lat, lon = ORIGIN.latitude, ORIGIN.longitude + 0.145
    T = world_T_cam_from_gimbal(ORIGIN, [lat], [lon], [ORIGIN.altitude], [0.0], [0.0], [0.0])
    z = T.rotation_matrix()[0][:, 2]
    turn = np.degrees(np.arctan2(-z[0], z[1]))
    expected = np.degrees(np.radians(0.145) * np.sin(np.radians(lat)))
    assert turn == pytest.approx(expected, rel=0.01)
    w = gimbal_from_world_T_cam(ORIGIN, T)
    assert abs(w.yaw[0]) < 1e-9


def test_georef_yaml_round_trip(tmp_path: Path) -> None:
    g = Georef(51.4545123456789, -2.5879, 31.25, time_origin="2024-05-01T11:30:00.120000")
    (tmp_path / "georef.yaml").write_text(format_georef_yaml(g, "a comment"))
    assert read_georef_yaml(tmp_path / "georef.yaml") == g


@pytest.mark.parametrize(("text", "field"), [
    ("latitude: 91\nlongitude: 0\naltitude: 0\nframe: enu\n", "latitude"),
    ("latitude: 1\nlongitude: 0\naltitude: 1e9\nframe: enu\n", "altitude"),  # as import dji
    ("latitude: 1\nlongitude: 0\naltitude: 0\nframe: ned\n", "frame"),
    ("latitude: 1\nlongitude: 0\nframe: enu\n", "altitude"),
    ("latitude: 1\nlongitude: 0\naltitude: 0\nframe: enu\ndatum: egm96\n", "datum"),
    ("latitude: north\nlongitude: 0\naltitude: 0\nframe: enu\n", "latitude"),
])
def test_bad_georef_yaml(tmp_path: Path, text: str, field: str | None) -> None:
    (tmp_path / "georef.yaml").write_text(text)
    with raises_input_error(tmp_path / "georef.yaml", field=field):
        read_georef_yaml(tmp_path / "georef.yaml")


def test_fit_outputs_gain_wgs84(tmp_path: Path) -> None:
    poses = dji_test_poses(4)
    write_turbine_yaml(tmp_path / "turbine.yaml", NRE, comment="fitted",
                       extra=location_text(ORIGIN, NRE))
    write_georef_outputs(tmp_path, ORIGIN, np.arange(4.0), poses)
    # the turbine file still reads, and says where the base is
    assert read_turbine_yaml(tmp_path / "turbine.yaml") == NRE
    lat, lon = turbine_location(tmp_path / "turbine.yaml") or (0.0, 0.0)
    np.testing.assert_allclose(ORIGIN.enu(lat, lon, ORIGIN.altitude)[:2],
                               [NRE.base_x, NRE.base_y], atol=1e-4)
    lines = (tmp_path / "keyframes_wgs84.csv").read_text().splitlines()
    assert lines[0] == WGS84_HEADER and len(lines) == 5
    rows = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    np.testing.assert_array_equal(rows[:, 0], np.arange(4.0))
    back = world_T_cam_from_gimbal(ORIGIN, *rows[:, 1:].T)
    dpos, dang = pose_errors(back, poses)
    assert dpos.max() < 1e-3 and np.degrees(dang.max()) < 1e-5


def test_no_georef_no_wgs84_outputs(tmp_path: Path) -> None:
    assert location_text(None, NRE) == ""
    write_turbine_yaml(tmp_path / "turbine.yaml", NRE)
    write_georef_outputs(tmp_path, None, np.arange(4.0), dji_test_poses(4))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["turbine.yaml"]


def test_turbine_yaml_checks_its_location(tmp_path: Path) -> None:
    write_turbine_yaml(tmp_path / "t.yaml", NRE)
    with open(tmp_path / "t.yaml", "a") as f:
        f.write("latitude: somewhere\nlongitude: 0\n")
    with raises_input_error(tmp_path / "t.yaml", field="latitude"):
        read_turbine_yaml(tmp_path / "t.yaml")
