"""Mission files (:mod:`turbinefit.io.missions`) read back by readers that are not their
writers (:mod:`turbinefit.io.mission_readers`: DJI WPML's required elements with
defusedxml, Litchi's exact header, pymavlink's ``MAVWPLoader``, QGroundControl's plan
keys): a planned path in each format equals the plan to 1 cm and 0.1 deg."""

from __future__ import annotations

import io
import itertools
import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.inspection.plan import PlanOptions, plan_path
from turbinefit.inspection.surface import TurbineSurface
from turbinefit.io import mission_readers as readers
from turbinefit.io import missions as M
from turbinefit.io.georef import Georef
from turbinefit.jobs.mission_files import mission_points
from turbinefit.turbine.model import TurbineParams

TURBINE = TurbineParams(3.0, -2.0, 60.0, math.radians(40.0), 4.0, math.radians(25.0), 30.0)
CAM = PinholeCamera(1200, 900, 2000.0, 2000.0, 599.5, 449.5)
GEOREF = Georef(-35.36, 149.16, 580.0)  # southern and eastern hemispheres: signs matter
SETTINGS = M.MissionSettings("test", GEOREF.latitude, GEOREF.longitude, GEOREF.altitude,
                             3.0, 100.0, {"droneEnumValue": 67, "droneSubEnumValue": 1,
                                          "payloadEnumValue": 53})


@pytest.fixture(scope="module")
def plan():
    return plan_path(TurbineSurface(TURBINE), CAM, PlanOptions(8.0, max_gimbal_up_deg=30.0))


@pytest.fixture(scope="module")
def points(plan) -> list[M.MissionPoint]:
    return mission_points(plan, GEOREF)


def angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


def compare(read: list[readers.ReadPoint], plan, *, heading_tol: float = 0.1) -> None:
    """The read points against the plan's waypoints: positions to 1 cm (in the flight's
    frame), the view's heading and pitch to 0.1 deg at every photo, the photos the same."""
    assert len(read) == len(plan.waypoints)
    enu = GEOREF.enu([p.latitude for p in read], [p.longitude for p in read],
                     [GEOREF.altitude + p.height for p in read])
    xyz = np.array([w.position for w in plan.waypoints])
    assert np.abs(enu - xyz).max() < 0.01
    heading = (90.0 - np.degrees([w.yaw for w in plan.waypoints])) % 360.0
    assert angle([p.heading for p in read], heading).max() <= heading_tol
    photo = np.array([w.photo for w in plan.waypoints])
    assert [p.photo for p in read] == photo.tolist()
    pitch = np.degrees([w.pitch for w in plan.waypoints])[photo]
    assert np.abs(np.array([p.gimbal_pitch for p in read])[photo] - pitch).max() < 0.1
    yaw = np.array([p.gimbal_yaw for p in read])[photo]
    if not np.isnan(yaw).all():
        assert angle(yaw, heading[photo]).max() < 0.1


def test_mavlink_numbers_are_the_protocols() -> None:
    from pymavlink.dialects.v20 import common as mav

    assert M.MAV_CMD_NAV_WAYPOINT == mav.MAV_CMD_NAV_WAYPOINT
    assert M.MAV_CMD_CONDITION_YAW == mav.MAV_CMD_CONDITION_YAW
    assert M.MAV_CMD_DO_CHANGE_SPEED == mav.MAV_CMD_DO_CHANGE_SPEED
    assert M.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW == mav.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
    assert M.MAV_CMD_IMAGE_START_CAPTURE == mav.MAV_CMD_IMAGE_START_CAPTURE
    assert M.MAV_FRAME_GLOBAL_RELATIVE_ALT == mav.MAV_FRAME_GLOBAL_RELATIVE_ALT
    assert M.MAV_FRAME_MISSION == mav.MAV_FRAME_MISSION
    assert M.GIMBAL_MANAGER_FLAGS_YAW_LOCK == mav.GIMBAL_MANAGER_FLAGS_YAW_LOCK
    assert M.MAV_AUTOPILOT_PX4 == mav.MAV_AUTOPILOT_PX4
    assert M.MAV_AUTOPILOT_ARDUPILOTMEGA == mav.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert M.MAV_TYPE_QUADROTOR == mav.MAV_TYPE_QUADROTOR


def test_the_test_plan_looks_up_and_down(plan) -> None:
    pitch = np.degrees([w.pitch for w in plan.photos])
    assert pitch.max() > 10.0 and pitch.min() < -10.0 and pitch.max() <= 30.0 + 1e-9
    assert len(plan.photos) > 50 and len(plan.waypoints) > len(plan.photos)


@pytest.mark.parametrize("fmt", ["litchi", "qgc", "mavlink", "dji-wpml"])
def test_each_format_reads_back_as_the_plan(fmt: str, plan, points, tmp_path: Path) -> None:
    mission = M.Mission(1, points)
    path = tmp_path / "m"
    if fmt == "litchi":
        path.write_text(M.format_litchi_csv(mission, 3.0))
        read = readers.read_litchi_csv(path)
    elif fmt == "qgc":
        path.write_text(M.format_qgc_plan(mission, SETTINGS))
        read = readers.read_qgc_plan(path)
    elif fmt == "mavlink":
        path.write_text(M.format_mavlink_wpl(mission, SETTINGS))
        read = readers.read_mavlink_wpl(path)
    else:
        path.write_bytes(M.wpml_kmz(mission, SETTINGS))
        read = readers.read_wpml_kmz(path)
    # WPML types the aircraft's heading as whole degrees; its gimbal's yaw is exact
    compare(read, plan, heading_tol=0.5 if fmt == "dji-wpml" else 0.1)


def test_split_missions_fly_the_same_path(points) -> None:
    missions = M.split_missions(points, 20)
    assert len(missions) == math.ceil((len(points) - 1) / 19)
    assert all(2 <= len(m.points) <= 20 for m in missions)
    flown = missions[0].points + [p for m in missions[1:] for p in m.points[1:]]
    assert [p.index for p in flown] == [p.index for p in points]
    for a, b in itertools.pairwise(missions):
        assert b.resumed and b.points[0].index == a.points[-1].index
        assert not b.points[0].photo  # the photo is not taken twice
    # every photo taken once
    assert sum(p.photo for m in missions for p in m.points) == sum(p.photo for p in points)
    # MAVLink: items counted, with the home position and the speed
    by_items = M.split_missions(points, 500, lambda p: M.mavlink_items(p), 60, 2)
    for m in by_items:
        assert 2 + sum(M.mavlink_items(p) for p in m.points) <= 60
        items = M.mavlink_mission(m, SETTINGS)
        assert 1 + len(items) == 2 + sum(M.mavlink_items(p) for p in m.points)
    with pytest.raises(ValueError, match="at least two"):
        M.split_missions(points, 1)
    with pytest.raises(ValueError, match="at least two"):
        M.split_missions(points, 99, lambda p: M.mavlink_items(p), 7, 2)


def test_ardupilot_heads_with_condition_yaw(points) -> None:
    import dataclasses

    s = dataclasses.replace(SETTINGS, condition_yaw=True)
    items = M.mavlink_mission(M.Mission(1, points), s)
    yaw = [it for it in items if it.command == M.MAV_CMD_CONDITION_YAW]
    assert len(yaw) == sum(p.photo for p in points)
    assert [it.params[0] for it in yaw] == [p.heading for p in points if p.photo]


def _kmz_without(kmz: bytes, member: str, tag: str) -> bytes:
    src = zipfile.ZipFile(io.BytesIO(kmz))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for name in src.namelist():
            data = src.read(name)
            if name == member:
                text = data.decode()
                start = text.index(f"<wpml:{tag}>")
                end = text.index(f"</wpml:{tag}>") + len(f"</wpml:{tag}>")
                data = (text[:start] + text[end:]).encode()
            z.writestr(name, data)
    return out.getvalue()


@pytest.mark.parametrize("member, tag", [
    ("wpmz/waylines.wpml", "executeHeightMode"), ("wpmz/waylines.wpml", "droneEnumValue"),
    ("wpmz/template.kml", "templateType"), ("wpmz/waylines.wpml", "waypointTurnParam"),
    ("wpmz/template.kml", "gimbalPitchMode"),
])
def test_the_wpml_reader_wants_the_required_elements(member: str, tag: str, points,
                                                     tmp_path: Path) -> None:
    kmz = M.wpml_kmz(M.Mission(1, points[:5]), SETTINGS)
    path = tmp_path / "m.kmz"
    path.write_bytes(kmz)
    assert len(readers.read_wpml_kmz(path)) == 5
    path.write_bytes(_kmz_without(kmz, member, tag))
    with pytest.raises(readers.MissionFileError, match=tag):
        readers.read_wpml_kmz(path)


def test_the_wpml_follows_the_specification(points) -> None:
    import defusedxml.ElementTree as DET

    kmz = M.wpml_kmz(M.Mission(1, points[:6]), SETTINGS)
    z = zipfile.ZipFile(io.BytesIO(kmz))
    assert sorted(z.namelist()) == ["wpmz/template.kml", "wpmz/waylines.wpml"]
    ns = readers.WPML_NS
    w = DET.fromstring(z.read("wpmz/waylines.wpml"))
    folder = w.find("k:Document/k:Folder", ns)
    assert folder.find("wpml:executeHeightMode", ns).text == "relativeToStartPoint"
    marks = folder.findall("k:Placemark", ns)
    assert [m.find("wpml:index", ns).text for m in marks] == [str(i) for i in range(6)]
    for m, p in zip(marks, points[:6], strict=True):
        turn = m.find("wpml:waypointTurnParam/wpml:waypointTurnMode", ns).text
        assert turn == "toPointAndStopWithDiscontinuityCurvature"  # straight legs, as checked
        heading = int(m.find("wpml:waypointHeadingParam/wpml:waypointHeadingAngle", ns).text)
        assert -180 <= heading <= 180
        groups = m.findall("wpml:actionGroup", ns)
        assert len(groups) == int(p.photo)
        if p.photo:
            funcs = [a.find("wpml:actionActuatorFunc", ns).text
                     for a in groups[0].findall("wpml:action", ns)]
            assert funcs == ["gimbalRotate", "takePhoto"]
    cfg = w.find("k:Document/wpml:missionConfig", ns)
    assert cfg.find("wpml:finishAction", ns).text == "noAction"
    assert cfg.find("wpml:droneInfo/wpml:droneSubEnumValue", ns).text == "1"


def test_the_litchi_reader_wants_litchis_header(points, tmp_path: Path) -> None:
    text = M.format_litchi_csv(M.Mission(1, points[:3]), 3.0)
    assert text.splitlines()[0] == readers.LITCHI_HEADER
    assert all(len(r.split(",")) == 46 for r in text.splitlines())
    path = tmp_path / "m.csv"
    path.write_text(text.replace("altitude(m)", "altitude(ft)", 1))
    with pytest.raises(readers.MissionFileError, match="header"):
        readers.read_litchi_csv(path)


def test_the_qgc_plan_is_strict_json_with_its_required_keys(points) -> None:
    text = M.format_qgc_plan(M.Mission(1, points[:4]), SETTINGS)
    plan = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in the JSON"))
    assert plan["fileType"] == "Plan" and plan["mission"]["version"] == 2
    assert plan["mission"]["plannedHomePosition"] == [GEOREF.latitude, GEOREF.longitude,
                                                      GEOREF.altitude]
    pitchyaw = [it for it in plan["mission"]["items"] if it["command"] == 1000]
    assert pitchyaw and all(it["params"][2] is None for it in pitchyaw)  # NaN rates
