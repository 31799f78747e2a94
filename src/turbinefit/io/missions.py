"""Mission files that drones fly: a planned path as DJI WPML (KMZ), Litchi CSV, a
QGroundControl ``.plan`` and a MAVLink mission (QGC WPL 110).

A mission is a list of :class:`MissionPoint` in WGS84: position, height above the
take-off point, the aircraft's heading, the gimbal's pitch and yaw, and whether a photo is
taken there. :func:`split_missions` cuts a path into missions a platform takes (each after
the first starts where the previous one ended, without a photo there). Every format flies
straight legs between waypoints and stops at each (the path was checked for straight legs),
and heights are relative to the take-off point:

* **DJI WPML** (:func:`wpml_kmz`): ``wpmz/template.kml`` and ``wpmz/waylines.wpml`` in a
  KMZ (zip), per DJI's WPML specification (DJI Cloud API, "DJI WPML":
  https://developer.dji.com/doc/cloud-api-tutorial/en/api-reference/dji-wpml/overview.html,
  ``template-kml.html``, ``waylines-wpml.html``, ``common-element.html``), for DJI Pilot 2
  and FlightHub 2. Height mode ``relativeToStartPoint``; turn mode
  ``toPointAndStopWithDiscontinuityCurvature`` (straight, stopping at each point); heading
  ``smoothTransition`` to the waypoint's ``waypointHeadingAngle`` (whole degrees, as the
  specification types it); at each photo an action group (``reachPoint``) of
  ``gimbalRotate`` (``absoluteAngle``: pitch, and yaw from north, to 0.01 deg) and
  ``takePhoto``. ``finishAction`` is ``noAction`` (hover: a return home from beside a
  blade is the pilot's), and ``flyToWaylineMode`` ``safely`` (climb, then level).
* **Litchi** (:func:`format_litchi_csv`): Litchi's mission CSV (the column header Litchi's
  Mission Hub exports), altitude mode 0 (above the take-off point), heading per waypoint,
  gimbal mode 2 (interpolate) with its pitch, at each photo the actions "stay for" 1000 ms
  and "take photo". Litchi keeps the mission's global settings out of the CSV: after
  importing, set Heading Mode to Custom, Path Mode to Straight Lines and Finish Action to
  None.
* **QGroundControl** (:func:`format_qgc_plan`, JSON, QGroundControl's "Plan File Format")
  and **MAVLink** (:func:`format_mavlink_wpl`, the plain-text "QGC WPL 110" of MAVLink's
  file formats page): the home position, ``MAV_CMD_DO_CHANGE_SPEED``, then per waypoint
  ``MAV_CMD_NAV_WAYPOINT`` (frame ``MAV_FRAME_GLOBAL_RELATIVE_ALT``, the heading in
  param 4, a second's hold at a photo) and at a photo ``MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW``
  (pitch, yaw from north with ``GIMBAL_MANAGER_FLAGS_YAW_LOCK``) and
  ``MAV_CMD_IMAGE_START_CAPTURE`` (one photo, numbered); PX4 and ArduPilot 4.3+ take all
  three in missions. ArduCopter ignores a waypoint's heading, so for it (``condition_yaw``)
  ``MAV_CMD_CONDITION_YAW`` follows each photo's waypoint (PX4 refuses that command).

Written by hand with :mod:`xml.etree.ElementTree`, :mod:`json` and :mod:`zipfile`: each
format is a few fixed elements or columns per waypoint, and no maintained Python library
writes WPML or Litchi CSV. pymavlink's ``MAVWPLoader.save`` would write the WPL text but
with six decimals (0.1 m of latitude), and it is the independent reader the tests read
these files back with (:mod:`turbinefit.io.mission_readers`), so it must not be the
writer too. The MAVLink numbers below are the protocol's (``common.xml``), checked
against pymavlink's in the tests.
"""

from __future__ import annotations

import io
import json
import math
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass

#: KML's and DJI WPML's XML namespaces (WPML 1.0.2, the version of the specification's
#: samples).
KML_NS = "http://www.opengis.net/kml/2.2"
WPML_NS = "http://www.dji.com/wpmz/1.0.2"
#: The header of Litchi's mission CSV (metric), as Litchi's Mission Hub exports it.
LITCHI_HEADER = ",".join(
    ["latitude", "longitude", "altitude(m)", "heading(deg)", "curvesize(m)", "rotationdir",
     "gimbalmode", "gimbalpitchangle"]
    + [f"{k}{i}" for i in range(1, 16) for k in ("actiontype", "actionparam")]
    + ["altitudemode", "speed(m/s)", "poi_latitude", "poi_longitude", "poi_altitude(m)",
       "poi_altitudemode", "photo_timeinterval", "photo_distinterval"])
#: Litchi's action types and gimbal mode used here.
LITCHI_STAY, LITCHI_PHOTO, LITCHI_NONE, LITCHI_INTERPOLATE = 0, 1, -1, 2
#: Litchi's altitude range above the take-off point [m] (its CSV's valid range).
LITCHI_ALTITUDE = (-200.0, 500.0)

# MAVLink (common.xml)
MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_CONDITION_YAW = 115
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW = 1000
MAV_CMD_IMAGE_START_CAPTURE = 2000
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
GIMBAL_MANAGER_FLAGS_YAW_LOCK = 16
MAV_AUTOPILOT_GENERIC, MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_PX4 = 0, 3, 12
MAV_TYPE_QUADROTOR = 2
#: Seconds a MAVLink mission holds at a photo waypoint before the gimbal and the photo.
PHOTO_HOLD_S = 1.0


@dataclass(frozen=True)
class MissionPoint:
    """One waypoint of a mission.

    Attributes:
        index: the waypoint's index in the plan (``waypoints.csv``).
        latitude, longitude: WGS84 [deg].
        altitude: [m], in the flight's altitude datum (that of ``georef.yaml``).
        height: above the take-off point [m] (the georeference's origin).
        heading: the aircraft's heading, clockwise from north [deg], in [0, 360).
        gimbal_pitch: [deg], 0 level, positive up.
        photo: whether a photo is taken here.
        name: what the photo shows (``blade_A leading_edge 12.30 m``), empty for transit.
    """

    index: int
    latitude: float
    longitude: float
    altitude: float
    height: float
    heading: float
    gimbal_pitch: float
    photo: bool
    name: str = ""

    @property
    def signed_heading(self) -> float:
        """:attr:`heading` in (-180, 180] (DJI's range)."""
        return self.heading - 360.0 if self.heading > 180.0 else self.heading


@dataclass(frozen=True)
class MissionSettings:
    """What every mission of a plan shares.

    Attributes:
        name: the missions' name (files, WPML's author).
        home_latitude, home_longitude, home_altitude: the take-off point (WGS84, altitude
            in the flight's datum) the heights are relative to.
        speed: cruise speed [m/s].
        rth_height: the height above the take-off point a return home climbs to first [m]
            (above the turbine).
        wpml: DJI's enumeration values of the aircraft and payload (WPML only).
        autopilot: ``MAV_AUTOPILOT`` of the QGC plan (0 generic, 3 ArduPilot, 12 PX4).
        condition_yaw: add ``MAV_CMD_CONDITION_YAW`` after each photo waypoint (ArduPilot).
    """

    name: str
    home_latitude: float
    home_longitude: float
    home_altitude: float
    speed: float
    rth_height: float
    wpml: dict[str, int]
    autopilot: int = MAV_AUTOPILOT_GENERIC
    condition_yaw: bool = False


@dataclass(frozen=True)
class Mission:
    """Part of a plan flown as one mission: its number (from 1) and points; ``resumed``:
    its first point is where the previous mission ended (no photo there)."""

    number: int
    points: list[MissionPoint]
    resumed: bool = False


def mavlink_items(point: MissionPoint, condition_yaw: bool = False) -> int:
    """How many MAVLink mission items ``point`` takes (:func:`mavlink_mission`)."""
    return 1 + (2 + int(condition_yaw)) * int(point.photo)


def split_missions(points: Sequence[MissionPoint], max_waypoints: int,
                   cost: Callable[[MissionPoint], int] | None = None,
                   max_cost: int | None = None, overhead: int = 0) -> list[Mission]:
    """``points`` cut into missions of at most ``max_waypoints`` points and, with ``cost``,
    at most ``max_cost`` (less ``overhead`` per mission) of its sum. Each mission after the
    first starts at the point where the previous one ended, without its photo (the drone
    hovers there between them), so the legs flown are the plan's.

    Raises:
        ValueError: limits that leave room for fewer than two points.
    """
    pts = list(points)
    cost = cost or (lambda p: 1)
    budget = math.inf if max_cost is None else max_cost - overhead
    if max_waypoints < 2 or budget < 2 * max((cost(p) for p in pts), default=1):
        raise ValueError("a mission must take at least two waypoints")
    out: list[Mission] = []
    start, resumed = 0, False
    while True:
        first = pts[start]
        if resumed:
            first = MissionPoint(first.index, first.latitude, first.longitude, first.altitude,
                                 first.height, first.heading, first.gimbal_pitch, False, "")
        chunk, used = [first], cost(first)
        end = start + 1
        while end < len(pts) and len(chunk) < max_waypoints and used + cost(pts[end]) <= budget:
            chunk.append(pts[end])
            used += cost(pts[end])
            end += 1
        out.append(Mission(len(out) + 1, chunk, resumed))
        if end >= len(pts):
            return out
        start, resumed = end - 1, True


def mission_file_name(stem: str, mission: Mission, count: int, suffix: str) -> str:
    """``stem.suffix`` for a single mission, else ``stem_01.suffix`` ... (numbered from 1)."""
    if count == 1:
        return f"{stem}{suffix}"
    return f"{stem}_{mission.number:0{max(2, len(str(count)))}d}{suffix}"


# --------------------------------------------------------------------------- Litchi

def format_litchi_csv(mission: Mission, speed: float) -> str:
    """The text of a Litchi mission CSV (module docstring)."""
    rows = [LITCHI_HEADER]
    for p in mission.points:
        actions = [LITCHI_NONE, 0] * 15
        if p.photo:
            actions[:4] = [LITCHI_STAY, 1000, LITCHI_PHOTO, 0]
        rows.append(",".join([
            f"{p.latitude:.9f}", f"{p.longitude:.9f}", f"{p.height:.3f}", f"{p.heading:.3f}",
            "0", "0", str(LITCHI_INTERPOLATE), f"{p.gimbal_pitch:.3f}",
            *(str(a) for a in actions), "0", f"{speed:g}", "0", "0", "0", "0", "-1", "-1"]))
    return "\n".join(rows) + "\n"


# --------------------------------------------------------------------------- DJI WPML

def _sub(parent: ET.Element, tag: str, text: object | None = None) -> ET.Element:
    ns, name = (WPML_NS, tag[5:]) if tag.startswith("wpml:") else (KML_NS, tag)
    el = ET.SubElement(parent, f"{{{ns}}}{name}")
    if text is not None:
        el.text = str(text)
    return el


def _num(x: float, digits: int = 3) -> str:
    """``x`` with at most ``digits`` decimals, no trailing zeros (``-0`` as ``0``)."""
    s = f"{x:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _mission_config(doc: ET.Element, mission: Mission, s: MissionSettings,
                    template: bool) -> None:
    cfg = _sub(doc, "wpml:missionConfig")
    _sub(cfg, "wpml:flyToWaylineMode", "safely")
    _sub(cfg, "wpml:finishAction", "noAction")
    _sub(cfg, "wpml:exitOnRCLost", "executeLostAction")
    _sub(cfg, "wpml:executeRCLostAction", "hover")
    first = mission.points[0].height
    _sub(cfg, "wpml:takeOffSecurityHeight", _num(min(max(first, 2.0), 1500.0), 2))
    if template:
        _sub(cfg, "wpml:takeOffRefPoint", f"{s.home_latitude:.9f},{s.home_longitude:.9f},"
             f"{s.home_altitude:.3f}")
    _sub(cfg, "wpml:globalTransitionalSpeed", _num(s.speed))
    _sub(cfg, "wpml:globalRTHHeight", _num(s.rth_height, 1))
    drone = _sub(cfg, "wpml:droneInfo")
    _sub(drone, "wpml:droneEnumValue", s.wpml["droneEnumValue"])
    _sub(drone, "wpml:droneSubEnumValue", s.wpml["droneSubEnumValue"])
    payload = _sub(cfg, "wpml:payloadInfo")
    _sub(payload, "wpml:payloadEnumValue", s.wpml["payloadEnumValue"])
    _sub(payload, "wpml:payloadPositionIndex", 0)


def _heading_param(parent: ET.Element, tag: str, p: MissionPoint) -> None:
    h = _sub(parent, tag)
    _sub(h, "wpml:waypointHeadingMode", "smoothTransition")
    angle = round(p.signed_heading)
    _sub(h, "wpml:waypointHeadingAngle", -180 if angle == 180 else angle)
    _sub(h, "wpml:waypointHeadingPathMode", "followBadArc")


def _actions(pm: ET.Element, p: MissionPoint, index: int, group: int) -> None:
    g = _sub(pm, "wpml:actionGroup")
    _sub(g, "wpml:actionGroupId", group)
    _sub(g, "wpml:actionGroupStartIndex", index)
    _sub(g, "wpml:actionGroupEndIndex", index)
    _sub(g, "wpml:actionGroupMode", "sequence")
    _sub(_sub(g, "wpml:actionTrigger"), "wpml:actionTriggerType", "reachPoint")
    rotate = _sub(g, "wpml:action")
    _sub(rotate, "wpml:actionId", 0)
    _sub(rotate, "wpml:actionActuatorFunc", "gimbalRotate")
    par = _sub(rotate, "wpml:actionActuatorFuncParam")
    for tag, text in (("gimbalHeadingYawBase", "north"), ("gimbalRotateMode", "absoluteAngle"),
                      ("gimbalPitchRotateEnable", 1),
                      ("gimbalPitchRotateAngle", _num(p.gimbal_pitch, 2)),
                      ("gimbalRollRotateEnable", 0), ("gimbalRollRotateAngle", 0),
                      ("gimbalYawRotateEnable", 1),
                      ("gimbalYawRotateAngle", _num(p.signed_heading, 2)),
                      ("gimbalRotateTimeEnable", 0), ("gimbalRotateTime", 0),
                      ("payloadPositionIndex", 0)):
        _sub(par, f"wpml:{tag}", text)
    photo = _sub(g, "wpml:action")
    _sub(photo, "wpml:actionId", 1)
    _sub(photo, "wpml:actionActuatorFunc", "takePhoto")
    par = _sub(photo, "wpml:actionActuatorFuncParam")
    _sub(par, "wpml:fileSuffix", p.name.replace(" ", "_") or f"wp{p.index}")
    _sub(par, "wpml:payloadPositionIndex", 0)
    _sub(par, "wpml:useGlobalPayloadLensIndex", 0)


def _placemarks(folder: ET.Element, mission: Mission,
                fill: Callable[[ET.Element, MissionPoint], None]) -> None:
    """A ``Placemark`` per point in ``folder``: its ``Point`` and ``wpml:index``, what
    ``fill`` adds, then at a photo its action group."""
    group = 0
    for i, p in enumerate(mission.points):
        pm = _sub(folder, "Placemark")
        _sub(_sub(pm, "Point"), "coordinates", f"{p.longitude:.10f},{p.latitude:.10f}")
        _sub(pm, "wpml:index", i)
        fill(pm, p)
        if p.photo:
            _actions(pm, p, i, group)
            group += 1


def _xml(root: ET.Element) -> bytes:
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8",
                                                                     xml_declaration=False) + b"\n"


def _document() -> tuple[ET.Element, ET.Element]:
    ET.register_namespace("", KML_NS)
    ET.register_namespace("wpml", WPML_NS)
    kml = ET.Element(f"{{{KML_NS}}}kml")
    return kml, _sub(kml, "Document")


def wpml_template(mission: Mission, s: MissionSettings) -> bytes:
    """``wpmz/template.kml``: a waypoint template whose points carry their heights, headings
    and gimbal pitches (``usePointSetting``) and their actions."""
    kml, doc = _document()
    _sub(doc, "wpml:author", "turbinefit")
    _mission_config(doc, mission, s, template=True)
    folder = _sub(doc, "Folder")
    _sub(folder, "wpml:templateType", "waypoint")
    _sub(folder, "wpml:templateId", 0)
    sys_param = _sub(folder, "wpml:waylineCoordinateSysParam")
    _sub(sys_param, "wpml:coordinateMode", "WGS84")
    _sub(sys_param, "wpml:heightMode", "relativeToStartPoint")
    _sub(folder, "wpml:autoFlightSpeed", _num(s.speed))
    _sub(folder, "wpml:globalHeight", _num(mission.points[0].height))
    _sub(folder, "wpml:gimbalPitchMode", "usePointSetting")
    _heading_param(folder, "wpml:globalWaypointHeadingParam", mission.points[0])
    _sub(folder, "wpml:globalWaypointTurnMode", "toPointAndStopWithDiscontinuityCurvature")
    _sub(folder, "wpml:globalUseStraightLine", 1)

    def fill(pm: ET.Element, p: MissionPoint) -> None:
        _sub(pm, "wpml:ellipsoidHeight", _num(p.altitude))
        _sub(pm, "wpml:height", _num(p.height))
        _sub(pm, "wpml:useGlobalHeight", 0)
        _sub(pm, "wpml:useGlobalSpeed", 1)
        _sub(pm, "wpml:useGlobalHeadingParam", 0)
        _heading_param(pm, "wpml:waypointHeadingParam", p)
        _sub(pm, "wpml:useGlobalTurnParam", 1)
        _sub(pm, "wpml:gimbalPitchAngle", _num(p.gimbal_pitch, 2))

    _placemarks(folder, mission, fill)
    return _xml(kml)


def wpml_waylines(mission: Mission, s: MissionSettings) -> bytes:
    """``wpmz/waylines.wpml``: the executable wayline (heights above the take-off point)."""
    kml, doc = _document()
    _mission_config(doc, mission, s, template=False)
    folder = _sub(doc, "Folder")
    _sub(folder, "wpml:templateId", 0)
    _sub(folder, "wpml:executeHeightMode", "relativeToStartPoint")
    _sub(folder, "wpml:waylineId", 0)
    _sub(folder, "wpml:autoFlightSpeed", _num(s.speed))

    def fill(pm: ET.Element, p: MissionPoint) -> None:
        _sub(pm, "wpml:executeHeight", _num(p.height))
        _sub(pm, "wpml:waypointSpeed", _num(s.speed))
        _heading_param(pm, "wpml:waypointHeadingParam", p)
        turn = _sub(pm, "wpml:waypointTurnParam")
        _sub(turn, "wpml:waypointTurnMode", "toPointAndStopWithDiscontinuityCurvature")
        _sub(turn, "wpml:waypointTurnDampingDist", 0)
        _sub(pm, "wpml:useStraightLine", 1)

    _placemarks(folder, mission, fill)
    return _xml(kml)


def wpml_kmz(mission: Mission, s: MissionSettings) -> bytes:
    """The KMZ (zip) of ``wpmz/template.kml`` and ``wpmz/waylines.wpml``."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in (("wpmz/template.kml", wpml_template(mission, s)),
                           ("wpmz/waylines.wpml", wpml_waylines(mission, s))):
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, data)
    return buf.getvalue()


# --------------------------------------------------------------------------- MAVLink

@dataclass(frozen=True)
class MavlinkItem:
    """One MAVLink mission item: command, frame and the seven parameters (NaN: unset)."""

    command: int
    frame: int
    params: tuple[float, float, float, float, float, float, float]


def mavlink_mission(mission: Mission, s: MissionSettings) -> list[MavlinkItem]:
    """The mission's items after the home position (module docstring)."""
    nan = math.nan
    items = [MavlinkItem(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION,
                         (1.0, s.speed, -1.0, 0.0, 0.0, 0.0, 0.0))]
    photo = 0
    for p in mission.points:
        items.append(MavlinkItem(MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                 (PHOTO_HOLD_S if p.photo else 0.0, 0.0, 0.0, p.heading,
                                  p.latitude, p.longitude, p.height)))
        if not p.photo:
            continue
        if s.condition_yaw:
            items.append(MavlinkItem(MAV_CMD_CONDITION_YAW, MAV_FRAME_MISSION,
                                     (p.heading, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)))
        photo += 1
        items.append(MavlinkItem(MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, MAV_FRAME_MISSION,
                                 (p.gimbal_pitch, p.signed_heading, nan, nan,
                                  float(GIMBAL_MANAGER_FLAGS_YAW_LOCK), 0.0, 0.0)))
        items.append(MavlinkItem(MAV_CMD_IMAGE_START_CAPTURE, MAV_FRAME_MISSION,
                                 (0.0, 0.0, 1.0, float(photo), 0.0, 0.0, 0.0)))
    return items


def _wpl_number(x: float) -> str:
    return "nan" if math.isnan(x) else repr(float(x))


def format_mavlink_wpl(mission: Mission, s: MissionSettings) -> str:
    """The text of a QGC WPL 110 mission: the home position (seq 0, absolute altitude) and
    :func:`mavlink_mission`'s items, tab-separated, numbers to full precision."""
    rows = ["QGC WPL 110",
            "\t".join(["0", "1", str(MAV_FRAME_GLOBAL), str(MAV_CMD_NAV_WAYPOINT), "0", "0",
                       "0", "0", _wpl_number(s.home_latitude), _wpl_number(s.home_longitude),
                       _wpl_number(s.home_altitude), "1"])]
    for seq, it in enumerate(mavlink_mission(mission, s), start=1):
        rows.append("\t".join([str(seq), "0", str(it.frame), str(it.command),
                               *(_wpl_number(v) for v in it.params), "1"]))
    return "\n".join(rows) + "\n"


def format_qgc_plan(mission: Mission, s: MissionSettings) -> str:
    """The text of a QGroundControl ``.plan`` (JSON; NaN parameters as ``null``)."""
    items = []
    for k, it in enumerate(mavlink_mission(mission, s), start=1):
        item: dict[str, object] = {
            "autoContinue": True, "command": it.command, "doJumpId": k, "frame": it.frame,
            "params": [None if math.isnan(v) else v for v in it.params], "type": "SimpleItem"}
        if it.frame == MAV_FRAME_GLOBAL_RELATIVE_ALT:
            item.update({"AMSLAltAboveTerrain": None, "Altitude": it.params[6],
                         "AltitudeMode": 1})
        items.append(item)
    plan = {
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {"version": 2, "firmwareType": s.autopilot, "vehicleType": MAV_TYPE_QUADROTOR,
                    "globalPlanAltitudeMode": 1, "cruiseSpeed": s.speed,
                    "hoverSpeed": s.speed, "items": items,
                    "plannedHomePosition": [s.home_latitude, s.home_longitude,
                                            s.home_altitude]},
    }
    return json.dumps(plan, indent=2) + "\n"
