"""The ``plan`` job: the next flight's waypoints round a fitted turbine
(:mod:`turbinefit.inspection.plan`), written as ``waypoints.csv``, the photos' poses
(``keyframes.txt``, TUM, with the fitted ``turbine.yaml``: the folder is one ``coverage``
reads, so the coverage a plan reaches is ``turbinefit coverage PLAN_DIR --camera ...``),
``summary.json`` and ``path.png``; for a georeferenced flight (or one placed with
``origin``) also ``waypoints_wgs84.csv``, the mission files of ``formats``
(:mod:`turbinefit.jobs.mission_files`: ``waypoints.kml``, DJI WPML, Litchi, QGroundControl
and MAVLink missions) and the GeoJSON twins of the waypoint CSVs. The plan keeps within
the ``platform``'s gimbal (:mod:`turbinefit.io.platforms`; ``generic``, within every common
DJI gimbal's range, unless named) and its missions within the waypoints it takes.

The KML is written by hand with :mod:`xml.etree.ElementTree`: it is one ``LineString``
and a ``Point`` per photo, and the KML libraries are either unmaintained (simplekml's last
release is from 2021, pykml's from 2019) or pull in geometry and date libraries for it
(fastkml needs pygeoif and arrow).
"""

from __future__ import annotations

import math
import os
import time
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, world_T_cam_from_angles
from turbinefit.inspection.clearance import LEG_STEP, solid_samples
from turbinefit.inspection.coverage import side_names
from turbinefit.inspection.plan import (
    MIN_STANDOFF,
    MIN_TOWER_CLEARANCE,
    Plan,
    PlanError,
    PlanOptions,
    check_margin,
    plan_path,
)
from turbinefit.inspection.plan import tower_clearance as tower_clearance_of
from turbinefit.inspection.surface import PARTS, SurfaceShape, TurbineSurface
from turbinefit.io.atomic import write_text_atomic
from turbinefit.io.geojson import write_geojson_twin
from turbinefit.io.georef import Georef, gimbal_from_world_T_cam
from turbinefit.io.platforms import DEFAULT_PLATFORM, drone_platform
from turbinefit.io.quantities import Quantity, check_latlonalt
from turbinefit.io.tum import write_tum
from turbinefit.io.turbine_yaml import write_turbine_yaml
from turbinefit.jobs.coverage import BLADE_ANGLE_DEG, read_fit_output
from turbinefit.jobs.mission_files import (
    FILE_PATTERNS,
    check_flyable,
    check_formats,
    mission_points,
    write_mission_files,
)
from turbinefit.jobs.outputs import (
    OutputKind,
    check_not_input,
    plot_error,
    recorded_path,
    summary_json,
)

PLAN_OUTPUTS = OutputKind("plan", frozenset({
    "waypoints.csv", "waypoints_wgs84.csv", "waypoints.kml", "keyframes.txt", "turbine.yaml",
    "summary.json", "path.png", "waypoints.geojson", "waypoints_wgs84.geojson"}),
    patterns=FILE_PATTERNS)
#: ``--standoff`` [m]: at least :data:`~turbinefit.inspection.plan.MIN_STANDOFF` (a
#: drone's size, its hovering error, the model's error), at most 100 m: a photo of a
#: blade from further resolves nothing a survey from the ground would not.
MAX_STANDOFF_M = 100.0
STANDOFF = Quantity("stand-off", "m", MIN_STANDOFF, MAX_STANDOFF_M)
#: ``--tower-clearance`` [m]: at least the drone's radius and hovering error (the tower
#: and nacelle are modelled better than the blades), at most the stand-off's maximum.
TOWER_CLEARANCE = Quantity("tower clearance", "m", MIN_TOWER_CLEARANCE, MAX_STANDOFF_M)
#: ``--gsd`` [mm/px]: finer than 100 mm/px (a photo coarser shows no damage).
GSD = Quantity("resolution", "mm/px", 0.0, 100.0, lo_open=True)
#: ``--overlap``: the share of the footprint neighbouring photos share.
OVERLAP = Quantity("overlap", "", 0.0, 0.9, hi_open=True)
#: ``--max-gimbal-up`` [deg]: from level (a gimbal that only looks down) to straight up
#: (and at most the platform's gimbal).
GIMBAL_UP = Quantity("largest upward gimbal pitch", "deg", 0.0, 90.0)
#: ``--position-margin`` [m]: how far off its waypoints the drone may take a photo (at
#: most the stand-off, checked by the planner).
POSITION_MARGIN = Quantity("position margin", "m", 0.0, MAX_STANDOFF_M)
#: ``--speed`` [m/s]: the missions' cruise speed (and at most the platform's top speed).
SPEED = Quantity("speed", "m/s", 0.5, 15.0)
#: The missions' cruise speed unless given [m/s]: near a structure, slow enough to stop
#: within the hovering error.
DEFAULT_SPEED = 3.0
#: The option of each of :class:`~turbinefit.inspection.plan.PlanOptions`'s fields.
OPTION_NAMES = {"standoff": "--standoff", "max_gsd_mm": "--gsd", "overlap": "--overlap",
                "max_gimbal_up_deg": "--max-gimbal-up", "tower_clearance": "--tower-clearance",
                "min_altitude": "min_altitude", "position_margin": "--position-margin"}

WAYPOINT_COLUMNS = "index,x,y,z,yaw_deg,gimbal_pitch_deg,photo,part,side,span_m"
WGS84_COLUMNS = "index,latitude,longitude,altitude,yaw,gimbal_pitch,photo,part,side,span_m"


@dataclass
class PlanReport:
    """What :func:`plan_folder` did: the plan, the summary written and timings [s]."""

    plan: Plan
    out_dir: Path
    summary: dict[str, Any]
    timings: dict[str, float] = field(default_factory=dict)


def _label(w: Any) -> tuple[str, str, str]:
    if not w.photo:
        return "", "", ""
    return PARTS[w.part], side_names(w.part)[w.side], f"{w.span:.2f}"


def photo_poses(plan: Plan) -> SE3:
    """``world_T_cam`` of the plan's photos (level cameras: no roll)."""
    ph = plan.photos
    return world_T_cam_from_angles(np.array([w.position for w in ph]).reshape(-1, 3),
                                   np.array([w.yaw for w in ph]),
                                   np.array([w.pitch for w in ph]), 0.0)


def format_waypoints_csv(plan: Plan, georef: Georef | None = None) -> str:
    """The text of ``waypoints.csv`` (world frame, yaw from the x axis counter-clockwise);
    with ``georef`` each row ends with its WGS84 ``latitude,longitude,altitude``."""
    rows = [WAYPOINT_COLUMNS + (",latitude,longitude,altitude" if georef else "")]
    if georef is not None:
        lat, lon, alt = georef.geodetic(np.array([w.position for w in plan.waypoints]))
    for i, w in enumerate(plan.waypoints):
        part, side, span = _label(w)
        x, y, z = (float(v) for v in w.position)
        row = (f"{i},{x:.3f},{y:.3f},{z:.3f},{math.degrees(w.yaw):.3f},"
               f"{math.degrees(w.pitch):.3f},{int(w.photo)},{part},{side},{span}")
        if georef is not None:
            row += f",{lat[i]:.10f},{lon[i]:.10f},{alt[i]:.3f}"
        rows.append(row)
    return "\n".join(rows) + "\n"


def _wgs84(plan: Plan, georef: Georef) -> tuple[Any, ...]:
    w = plan.waypoints
    poses = world_T_cam_from_angles(np.array([p.position for p in w]),
                                    np.array([p.yaw for p in w]),
                                    np.array([p.pitch for p in w]), 0.0)
    g = gimbal_from_world_T_cam(georef, poses)
    # the gimbal's yaw is the view's, also looking straight up or down
    yaw = (90.0 - np.degrees([p.yaw for p in w]) + 180.0) % 360.0 - 180.0
    return g.latitude, g.longitude, g.altitude, yaw, np.degrees([p.pitch for p in w])


def format_wgs84_waypoints(plan: Plan, georef: Georef) -> str:
    """The text of ``waypoints_wgs84.csv`` (DJI's gimbal convention: yaw clockwise from
    north, pitch 0 level and -90 down; altitude in the flight's datum)."""
    lat, lon, alt, yaw, pitch = _wgs84(plan, georef)
    rows = [WGS84_COLUMNS]
    for i, w in enumerate(plan.waypoints):
        part, side, span = _label(w)
        rows.append(f"{i},{lat[i]:.10f},{lon[i]:.10f},{alt[i]:.3f},{yaw[i]:.3f},"
                    f"{pitch[i]:.3f},{int(w.photo)},{part},{side},{span}")
    return "\n".join(rows) + "\n"


def format_kml(plan: Plan, georef: Georef, name: str) -> str:
    """The text of ``waypoints.kml``: the path as a ``LineString`` and each photo as a
    ``Point`` (altitude absolute, in the flight's datum), with its gimbal angles."""
    lat, lon, alt, yaw, pitch = _wgs84(plan, georef)
    ns = "http://www.opengis.net/kml/2.2"
    ET.register_namespace("", ns)
    kml = ET.Element(f"{{{ns}}}kml")
    doc = ET.SubElement(kml, f"{{{ns}}}Document")
    ET.SubElement(doc, f"{{{ns}}}name").text = name
    path = ET.SubElement(doc, f"{{{ns}}}Placemark")
    ET.SubElement(path, f"{{{ns}}}name").text = "path"
    line = ET.SubElement(path, f"{{{ns}}}LineString")
    ET.SubElement(line, f"{{{ns}}}altitudeMode").text = "absolute"
    ET.SubElement(line, f"{{{ns}}}coordinates").text = " ".join(
        f"{lon[i]:.9f},{lat[i]:.9f},{alt[i]:.2f}" for i in range(len(plan.waypoints)))
    for i, w in enumerate(plan.waypoints):
        if not w.photo:
            continue
        part, side, span = _label(w)
        pm = ET.SubElement(doc, f"{{{ns}}}Placemark")
        ET.SubElement(pm, f"{{{ns}}}name").text = f"{i} {part} {side} {span} m"
        ET.SubElement(pm, f"{{{ns}}}description").text = (
            f"gimbal yaw {yaw[i]:.1f} deg, pitch {pitch[i]:.1f} deg")
        pt = ET.SubElement(pm, f"{{{ns}}}Point")
        ET.SubElement(pt, f"{{{ns}}}altitudeMode").text = "absolute"
        ET.SubElement(pt, f"{{{ns}}}coordinates").text = f"{lon[i]:.9f},{lat[i]:.9f},{alt[i]:.2f}"
    ET.indent(kml)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode") + "\n"


def plan_folder(fit_dir: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                standoff: float, max_gsd_mm: float | None = None,
                camera: PinholeCamera | None = None,
                flight_dir: str | os.PathLike[str] | None = None, overlap: float = 0.3,
                max_gimbal_up_deg: float | None = None, tower_clearance: float | None = None,
                blade_pitch_deg: float = 0.0, blade_twist_deg: float = 0.0,
                position_margin: float = 0.0, platform: str | None = None,
                formats: Sequence[str] | None = None,
                origin: tuple[float, float, float] | None = None,
                speed: float = DEFAULT_SPEED, plots: bool = True,
                overwrite: bool = False) -> PlanReport:
    """Plan the next flight round the fit in ``fit_dir`` (its fitted turbine, stopped at its
    blade rotation) at ``standoff`` metres with ``camera`` (default: the ``platform``'s,
    else the photos' camera of the flight the fit came from) and write it to ``out_dir``
    (see the module docstring).

    ``platform`` (a name of :mod:`turbinefit.io.platforms`' table, default ``generic``)
    bounds the gimbal's upward pitch (``max_gimbal_up_deg``, default the platform's, may
    only be lower), the cruise ``speed`` and the waypoints of a mission. ``formats``: the
    mission files to write (default: ``kml`` on a georeferenced flight); they need a
    georeferenced flight (``georef.yaml``) or ``origin`` (latitude, longitude, altitude of
    the world frame's origin, the take-off point) for one without.

    ``blade_pitch_deg`` and ``blade_twist_deg`` give the blades' parked pitch and their
    twist at the root (``coverage``'s terms; 0: flat in the rotor plane): the edges'
    views are aimed along the sections they give. ``position_margin`` [m]: how far from a
    waypoint the drone may be when it takes the photo (its navigation's error relative to
    the turbine); the views added where the stations leave a side unseen show it from
    anywhere within it (:class:`~turbinefit.inspection.plan.PlanOptions`).

    The path is checked before anything is written
    (:func:`~turbinefit.inspection.plan.check_plan`, independent of the planner's
    arithmetic): every waypoint and leg keeps ``standoff`` from the blades and the spinner
    and the tower clearance from the tower and the nacelle, the gimbal stays within its
    pitch; the summary's clearances are the check's.

    Raises:
        InputError: a number out of its range (``STANDOFF``, ``GSD``, ``OVERLAP``,
            ``GIMBAL_UP``, ``TOWER_CLEARANCE``, ``SPEED``, ``BLADE_ANGLE_DEG``,
            ``POSITION_MARGIN``, named by its option), an unknown
            platform or format, a format the platform does not fly, a gimbal pitch or speed
            beyond the platform's, mission files without a georeference, ``origin`` on a
            georeferenced flight, a fit folder without poses or turbine, a stand-off that
            meets the rotor, a resolution ``max_gsd_mm`` the camera cannot reach at the
            stand-off, a path that fails its check, a bad ``out_dir``; nothing is written.
    """
    t0 = time.perf_counter()
    standoff = STANDOFF.check(standoff, field="--standoff")
    if max_gsd_mm is not None:
        max_gsd_mm = GSD.check(max_gsd_mm, field="--gsd")
    overlap = OVERLAP.check(overlap, field="--overlap")
    drone = drone_platform(platform or DEFAULT_PLATFORM)
    up_limit = min(drone.gimbal_max_deg, 90.0)
    if max_gimbal_up_deg is None:
        max_gimbal_up_deg = up_limit
    max_gimbal_up_deg = GIMBAL_UP.check(max_gimbal_up_deg, field="--max-gimbal-up")
    if max_gimbal_up_deg > up_limit:
        raise InputError(f"{max_gimbal_up_deg:g} deg is beyond the gimbal of platform "
                         f"{drone.key} ({drone.name}: up to {up_limit:g} deg)",
                         field="--max-gimbal-up")
    speed = SPEED.check(speed, field="--speed")
    blade_pitch_deg = BLADE_ANGLE_DEG.check(blade_pitch_deg, field="--blade-pitch")
    blade_twist_deg = BLADE_ANGLE_DEG.check(blade_twist_deg, field="--blade-twist")
    position_margin = POSITION_MARGIN.check(position_margin, field="--position-margin")
    if speed > drone.max_speed_m_s:
        raise InputError(f"{speed:g} m/s is faster than platform {drone.key} flies missions "
                         f"({drone.max_speed_m_s:g} m/s)", field="--speed")
    asked = formats is not None
    mission_formats = check_formats(formats if formats is not None else ["kml"],
                                    drone if asked else drone_platform("generic"))
    if tower_clearance is not None:
        tower_clearance = TOWER_CLEARANCE.check(tower_clearance, field="--tower-clearance")
    if origin is not None:
        origin = check_latlonalt(*origin, prefix="--origin ")  # type: ignore[assignment]
    fit_dir, out_dir = Path(fit_dir), Path(out_dir)
    inputs = [fit_dir] + ([] if flight_dir is None else [Path(flight_dir)])
    PLAN_OUTPUTS.check(out_dir, inputs, overwrite)
    fit = read_fit_output(fit_dir, flight_dir, need_camera=camera is None and drone.camera is None)
    if fit.flight_dir is not None:
        check_not_input(out_dir, [fit.flight_dir])
    georef, georeference = fit.georef, "georef.yaml" if fit.georef is not None else None
    if origin is not None:
        if georef is not None:
            raise InputError("the flight is georeferenced (its georef.yaml); --origin only "
                             "places a flight without one", field="--origin")
        georef, georeference = Georef(*origin), "--origin"
    if georef is None:
        if asked:
            raise InputError(f"{', '.join(mission_formats)} need a georeferenced fit: a "
                             "flight with georef.yaml (turbinefit import dji), or --origin "
                             "LAT,LON,ALT to place this one", field="--format")
        mission_formats = ()
    if camera is None and drone.camera is not None:
        camera = PinholeCamera(*drone.camera.intrinsics())
    cam = camera or fit.camera
    assert cam is not None
    shape = SurfaceShape(blade_pitch=math.radians(blade_pitch_deg),
                         blade_twist=math.radians(blade_twist_deg))
    surface = TurbineSurface(fit.turbine, fit.geometry, shape=shape)
    samples = solid_samples(surface)
    check_margin_m = check_margin(samples)
    options = PlanOptions(standoff, max_gsd_mm, overlap, max_gimbal_up_deg,
                          tower_clearance=tower_clearance, position_margin=position_margin)
    try:
        plan = plan_path(surface, cam, options, samples)
    except PlanError as exc:
        raise InputError(str(exc), field=OPTION_NAMES.get(exc.option, exc.option)) from None
    points = mission_points(plan, georef) if georef is not None else []
    check_flyable(points, mission_formats, np.array([w.position for w in plan.waypoints]))
    rth = math.ceil(float(surface.hub[2]) + surface.b + standoff + 5.0)
    timings = {"plan": time.perf_counter() - t0, "check": plan.check_s}
    stations = {f"{PARTS[p]}/{side_names(p)[k]}": n for (p, k), n in plan.stations.items()}
    skipped = {f"{PARTS[p]}/{side_names(p)[k]}": n for (p, k), n in plan.skipped.items() if n}
    steep = {f"{PARTS[p]}/{side_names(p)[k]}": n for (p, k), n in plan.beyond_gimbal.items()
             if n}
    summary = {
        "turbinefit_version": __version__, "fit": recorded_path(fit_dir, out_dir),
        "flight": None if fit.flight_dir is None else recorded_path(fit.flight_dir, out_dir),
        "standoff_m": standoff, "max_gsd_mm_px": max_gsd_mm, "gsd_mm_px": round(plan.gsd_mm, 4),
        "camera": {"width": cam.width, "height": cam.height, "fx": cam.fx, "fy": cam.fy},
        "overlap": overlap, "platform": drone.key, "max_gimbal_up_deg": max_gimbal_up_deg,
        "waypoints": len(plan.waypoints), "photos": len(plan.photos),
        "length_m": round(plan.length_m, 2),
        "tower_clearance_m": tower_clearance_of(options),
        "blade_pitch_deg": blade_pitch_deg, "blade_twist_deg": blade_twist_deg,
        "position_margin_m": position_margin,
        "min_rotor_clearance_m": math.floor(plan.min_rotor_clearance * 1000.0) / 1000.0,
        "min_tower_clearance_m": math.floor(plan.min_tower_clearance * 1000.0) / 1000.0,
        "clearance_check": {
            "what": "least distance of every waypoint and every straight leg between them "
                    "from the solid (lower bounds), independent of the planner",
            "margin_m": round(check_margin_m, 3), "leg_step_m": LEG_STEP},
        "stations": stations, "skipped": skipped, "beyond_gimbal": steep,
        "fill": {f"{PARTS[p]}/{side_names(p)[k]}": n for (p, k), n in plan.fill.items()},
        "covered_mm_px": round(plan.goal_mm, 4),
        "covered": {f"{PARTS[p]}/{side_names(p)[k]}": round(v, 4)
                    for (p, k), v in plan.covered.items()},
        "blades": {bl.name: round(bl.clock_deg, 3) for bl in surface.blades},
        "georeferenced": georef is not None, "georeference": georeference,
    }
    poses = photo_poses(plan)
    with PLAN_OUTPUTS.writing(out_dir, overwrite) as tmp:
        write_text_atomic(tmp / "waypoints.csv", format_waypoints_csv(plan, georef), fsync=False)
        write_tum(tmp / "keyframes.txt", np.arange(len(plan.photos), dtype=np.float64), poses,
                  comment="turbinefit plan: the planned photos' world_T_cam (timestamp = "
                  "photo number)")
        write_turbine_yaml(tmp / "turbine.yaml", fit.turbine,
                           comment="turbinefit plan: the fitted turbine planned round")
        missions: dict[str, list[str]] = {}
        if georef is not None:
            wgs84 = format_wgs84_waypoints(plan, georef)
            write_text_atomic(tmp / "waypoints_wgs84.csv", wgs84, fsync=False)
            write_geojson_twin(tmp / "waypoints.csv", format_waypoints_csv(plan, georef))
            write_geojson_twin(tmp / "waypoints_wgs84.csv", wgs84)
            if "kml" in mission_formats:
                write_text_atomic(tmp / "waypoints.kml",
                                  format_kml(plan, georef, f"turbinefit plan of {fit_dir.name}"),
                                  fsync=False)
                missions["kml"] = ["waypoints.kml"]
            missions.update(write_mission_files(
                tmp, points, mission_formats, drone, georef, speed, rth,
                f"turbinefit plan of {fit_dir.name}"))
        summary["missions"] = {
            "formats": missions, "speed_m_s": speed, "rth_height_m": rth,
            "max_waypoints": drone.max_waypoints,
            "heights": "above the take-off point: the georeference's origin"}
        if plots:
            from turbinefit.plots.inspection import plot_path

            try:
                plot_path(tmp / "path.png", plan, surface, georef)
            except OSError as exc:
                raise plot_error(exc, out_dir) from exc
        timings["total"] = time.perf_counter() - t0
        summary["timing_s"] = timings
        write_text_atomic(tmp / "summary.json", summary_json(summary), fsync=False)
    return PlanReport(plan, out_dir, summary, timings)
