"""Reading mission files back, independently of their writers
(:mod:`turbinefit.io.missions`): what a drone app would take from each file, to check a
written mission against the plan (the tests and ``benchmarks/bench_missions.py``).

* DJI WPML: the KMZ is unzipped and both files parsed with defusedxml; the elements DJI's
  WPML specification marks as required (:data:`WPML_REQUIRED`) must be there, the
  waypoint indices run from 0 and both files give the same points.
* Litchi: the header must be Litchi's exactly (:func:`read_litchi_csv`).
* MAVLink WPL: pymavlink's ``mavwp.MAVWPLoader`` (a test dependency) parses the file.
* QGroundControl ``.plan``: :mod:`json`, with QGroundControl's required keys.

Each returns the waypoints as :class:`ReadPoint`: position, height above the take-off
point, the aircraft's heading, the gimbal's pitch and yaw where the file gives them, and
whether a photo is taken there.
"""

from __future__ import annotations

import csv
import io
import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

WPML_NS = {"k": "http://www.opengis.net/kml/2.2", "wpml": "http://www.dji.com/wpmz/1.0.2"}
#: Elements DJI's WPML specification marks as required, by where they sit.
WPML_REQUIRED = {
    "missionConfig": ("flyToWaylineMode", "finishAction", "exitOnRCLost",
                      "takeOffSecurityHeight", "globalTransitionalSpeed", "droneInfo",
                      "payloadInfo"),
    "droneInfo": ("droneEnumValue",),
    "payloadInfo": ("payloadEnumValue", "payloadPositionIndex"),
    "template_folder": ("templateType", "templateId", "autoFlightSpeed", "gimbalPitchMode",
                        "globalWaypointTurnMode", "globalHeight"),
    "template_placemark": ("index", "useGlobalHeight", "ellipsoidHeight", "height",
                           "useGlobalSpeed", "useGlobalHeadingParam", "useGlobalTurnParam",
                           "gimbalPitchAngle"),
    "waylines_folder": ("templateId", "waylineId", "autoFlightSpeed", "executeHeightMode"),
    "waylines_placemark": ("index", "executeHeight", "waypointSpeed", "waypointHeadingParam",
                           "waypointTurnParam"),
    "actionGroup": ("actionGroupId", "actionGroupStartIndex", "actionGroupEndIndex",
                    "actionGroupMode", "actionTrigger"),
    "action": ("actionId", "actionActuatorFunc"),
}


#: Litchi's mission CSV header (metric), written out as Litchi's Mission Hub exports it
#: (not taken from the writer).
LITCHI_HEADER = (
    "latitude,longitude,altitude(m),heading(deg),curvesize(m),rotationdir,gimbalmode,"
    "gimbalpitchangle,actiontype1,actionparam1,actiontype2,actionparam2,actiontype3,"
    "actionparam3,actiontype4,actionparam4,actiontype5,actionparam5,actiontype6,actionparam6,"
    "actiontype7,actionparam7,actiontype8,actionparam8,actiontype9,actionparam9,actiontype10,"
    "actionparam10,actiontype11,actionparam11,actiontype12,actionparam12,actiontype13,"
    "actionparam13,actiontype14,actionparam14,actiontype15,actionparam15,altitudemode,"
    "speed(m/s),poi_latitude,poi_longitude,poi_altitude(m),poi_altitudemode,"
    "photo_timeinterval,photo_distinterval")


class MissionFileError(ValueError):
    """A mission file that does not follow its format."""


@dataclass(frozen=True)
class ReadPoint:
    """A waypoint read back: WGS84 [deg], height above take-off [m], the aircraft's heading
    [deg, clockwise from north], the gimbal's pitch and yaw [deg] (yaw from north; NaN
    where the file gives none) and whether a photo is taken."""

    latitude: float
    longitude: float
    height: float
    heading: float
    gimbal_pitch: float
    gimbal_yaw: float
    photo: bool


def _need(el: Any, names: tuple[str, ...], where: str) -> None:
    for n in names:
        if el.find(f"wpml:{n}", WPML_NS) is None:
            raise MissionFileError(f"{where}: no wpml:{n}")


def _text(el: Any, path: str) -> str:
    found = el.find(path, WPML_NS)
    if found is None or found.text is None:
        raise MissionFileError(f"no {path}")
    return str(found.text).strip()


def _coords(pm: Any) -> tuple[float, float]:
    lon, lat = (float(v) for v in _text(pm, "k:Point/k:coordinates").split(",")[:2])
    return lat, lon


def read_wpml_kmz(path: str | Path) -> list[ReadPoint]:
    """The waypoints of a DJI WPML KMZ (``waylines.wpml``'s, checked against
    ``template.kml``'s).

    Raises:
        MissionFileError: a missing file or required element, indices not 0, 1, ...,
            the two files disagreeing.
    """
    import defusedxml.ElementTree as DET

    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
        for need in ("wpmz/template.kml", "wpmz/waylines.wpml"):
            if need not in names:
                raise MissionFileError(f"no {need} in the KMZ")
        template = DET.fromstring(z.read("wpmz/template.kml"))
        waylines = DET.fromstring(z.read("wpmz/waylines.wpml"))
    points: dict[str, list[ReadPoint]] = {}
    for which, root in (("template", template), ("waylines", waylines)):
        if root.tag != f"{{{WPML_NS['k']}}}kml":
            raise MissionFileError(f"{which}: the root is not KML 2.2's kml")
        doc = root.find("k:Document", WPML_NS)
        cfg = doc.find("wpml:missionConfig", WPML_NS) if doc is not None else None
        if cfg is None:
            raise MissionFileError(f"{which}: no Document/wpml:missionConfig")
        _need(cfg, WPML_REQUIRED["missionConfig"], f"{which} missionConfig")
        _need(cfg.find("wpml:droneInfo", WPML_NS), WPML_REQUIRED["droneInfo"], "droneInfo")
        _need(cfg.find("wpml:payloadInfo", WPML_NS), WPML_REQUIRED["payloadInfo"],
              "payloadInfo")
        folder = doc.find("k:Folder", WPML_NS)
        if folder is None:
            raise MissionFileError(f"{which}: no Folder")
        _need(folder, WPML_REQUIRED[f"{which}_folder"], f"{which} Folder")
        out = []
        for i, pm in enumerate(folder.findall("k:Placemark", WPML_NS)):
            _need(pm, WPML_REQUIRED[f"{which}_placemark"], f"{which} Placemark {i}")
            if int(_text(pm, "wpml:index")) != i:
                raise MissionFileError(f"{which}: Placemark {i} has wpml:index "
                                       f"{_text(pm, 'wpml:index')}")
            lat, lon = _coords(pm)
            height = float(_text(pm, "wpml:height" if which == "template"
                                 else "wpml:executeHeight"))
            head = pm.find("wpml:waypointHeadingParam", WPML_NS)
            heading = float(_text(head, "wpml:waypointHeadingAngle")) \
                if head is not None else math.nan
            pitch = yaw = math.nan
            photo = False
            for group in pm.findall("wpml:actionGroup", WPML_NS):
                _need(group, WPML_REQUIRED["actionGroup"], f"{which} actionGroup {i}")
                if _text(group, "wpml:actionTrigger/wpml:actionTriggerType") != "reachPoint":
                    continue
                for action in group.findall("wpml:action", WPML_NS):
                    _need(action, WPML_REQUIRED["action"], f"{which} action {i}")
                    func = _text(action, "wpml:actionActuatorFunc")
                    par = action.find("wpml:actionActuatorFuncParam", WPML_NS)
                    if func == "takePhoto":
                        photo = True
                    elif func == "gimbalRotate" and par is not None:
                        if _text(par, "wpml:gimbalRotateMode") != "absoluteAngle":
                            raise MissionFileError("gimbalRotate not absoluteAngle")
                        if _text(par, "wpml:gimbalPitchRotateEnable") == "1":
                            pitch = float(_text(par, "wpml:gimbalPitchRotateAngle"))
                        if _text(par, "wpml:gimbalYawRotateEnable") == "1":
                            yaw = float(_text(par, "wpml:gimbalYawRotateAngle"))
            if which == "template":
                pitch = float(_text(pm, "wpml:gimbalPitchAngle"))
            out.append(ReadPoint(lat, lon, height, heading % 360.0, pitch,
                                 yaw % 360.0 if math.isfinite(yaw) else yaw, photo))
        points[which] = out
    t, w = points["template"], points["waylines"]
    if len(t) != len(w) or any(
            (a.latitude, a.longitude, a.height, a.heading, a.photo)
            != (b.latitude, b.longitude, b.height, b.heading, b.photo) for a, b in zip(t, w, strict=True)):
        raise MissionFileError("template.kml and waylines.wpml give different waypoints")
    return w


def read_litchi_csv(path: str | Path) -> list[ReadPoint]:
    """The waypoints of a Litchi mission CSV (its exact header required).

    Raises:
        MissionFileError: another header, a row of another length or an altitude mode other
            than 0 (above the take-off point).
    """
    text = Path(path).read_text(encoding="utf-8")
    rows = list(csv.reader(io.StringIO(text)))
    if not rows or ",".join(rows[0]) != LITCHI_HEADER:
        raise MissionFileError("not Litchi's mission CSV header")
    col = {name: i for i, name in enumerate(rows[0])}
    out = []
    for r in rows[1:]:
        if len(r) != len(rows[0]):
            raise MissionFileError(f"a row of {len(r)} fields, not {len(rows[0])}")
        if r[col["altitudemode"]] != "0":
            raise MissionFileError("altitude mode is not 0 (above take-off)")
        actions = {int(float(r[col[f"actiontype{i}"]])) for i in range(1, 16)}
        out.append(ReadPoint(float(r[col["latitude"]]), float(r[col["longitude"]]),
                             float(r[col["altitude(m)"]]), float(r[col["heading(deg)"]]),
                             float(r[col["gimbalpitchangle"]]), math.nan, 1 in actions))
    return out


def _from_items(items: list[tuple[int, int, list[float]]]) -> list[ReadPoint]:
    """Waypoints from MAVLink items ``(command, frame, params)`` after the home position:
    a waypoint's heading is its param 4; a following gimbal command sets its gimbal, an
    image capture makes it a photo."""
    out: list[dict[str, Any]] = []
    for command, frame, p in items:
        if command == 16:
            if frame != 3:
                raise MissionFileError(f"a waypoint in frame {frame}, not 3 (relative alt.)")
            out.append({"latitude": p[4], "longitude": p[5], "height": p[6],
                        "heading": p[3] % 360.0, "gimbal_pitch": math.nan,
                        "gimbal_yaw": math.nan, "photo": False})
        elif command == 1000 and out:
            if int(p[4]) & 16 == 0:
                raise MissionFileError("a gimbal command without yaw lock")
            out[-1]["gimbal_pitch"], out[-1]["gimbal_yaw"] = p[0], p[1] % 360.0
        elif command == 2000 and out:
            if p[2] != 1:
                raise MissionFileError("an image capture of other than one photo")
            out[-1]["photo"] = True
    return [ReadPoint(**d) for d in out]


def read_mavlink_wpl(path: str | Path) -> list[ReadPoint]:
    """The waypoints of a QGC WPL 110 file, parsed by pymavlink's ``MAVWPLoader``."""
    from pymavlink import mavwp

    loader = mavwp.MAVWPLoader()
    loader.load(str(path))
    items = [loader.wp(i) for i in range(loader.count())]
    if not items or items[0].seq != 0:
        raise MissionFileError("no home position (seq 0)")
    return _from_items([(w.command, w.frame, [w.param1, w.param2, w.param3, w.param4,
                                              w.x, w.y, w.z]) for w in items[1:]])


def read_qgc_plan(path: str | Path) -> list[ReadPoint]:
    """The waypoints of a QGroundControl ``.plan`` (its required keys checked)."""
    plan = json.loads(Path(path).read_text(encoding="utf-8"))
    if plan.get("fileType") != "Plan" or plan.get("version") != 1:
        raise MissionFileError("not a QGroundControl plan (fileType Plan, version 1)")
    mission = plan.get("mission")
    need = ("version", "firmwareType", "globalPlanAltitudeMode", "vehicleType", "cruiseSpeed",
            "hoverSpeed", "items", "plannedHomePosition")
    if not isinstance(mission, dict) or any(k not in mission for k in need):
        raise MissionFileError("mission lacks a required key")
    items = []
    for it in mission["items"]:
        if it.get("type") != "SimpleItem" or len(it.get("params", [])) != 7:
            raise MissionFileError("an item that is not a SimpleItem of 7 parameters")
        items.append((it["command"], it["frame"],
                      [math.nan if v is None else float(v) for v in it["params"]]))
    return _from_items(items)
