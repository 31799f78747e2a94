"""``turbinefit plan``: the next flight's waypoints round a fitted turbine
(:func:`turbinefit.jobs.plan.plan_folder`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

DESCRIPTION = """\
Camera waypoints (position, yaw, gimbal pitch) that photograph each blade's four
sides (leading edge, pressure side, trailing edge, suction side) and the tower's
four faces from --standoff metres, ordered into one path that keeps that far from
the rotor (stopped at its fitted blade rotation). The path is checked before it
is written, independently of the planner: every waypoint and every leg between
them keeps --standoff from the blades and the spinner and --tower-clearance from
the tower and the nacelle, else nothing is written (exit 2). Writes waypoints.csv,
keyframes.txt and turbine.yaml (so `turbinefit coverage OUT_DIR --camera ...`
predicts what the flight will show), summary.json, path.png and, for a
georeferenced flight, waypoints_wgs84.csv, waypoints.kml, GeoJSON twins of the
waypoint CSVs and the mission files of --format (DJI WPML, Litchi, QGroundControl,
MAVLink), split into missions --platform takes. The plan keeps the gimbal within
--platform's range (default generic: -90 to +20 deg, what every common DJI gimbal
does). Details: docs/inspection.md."""


#: The mission formats --format takes (:data:`turbinefit.io.platforms.MISSION_FORMATS`).
FORMATS = ("dji-wpml", "litchi", "qgc", "mavlink", "kml")


#: A blade side the planned photos show less of than this share is named.
WELL_COVERED = 0.95


def _shares(covered: dict[str, float], keys: list[str]) -> str:
    return ", ".join(f"{k} {100.0 * covered[k]:.0f} %" for k in keys)


def _formats(text: str) -> tuple[str, ...]:
    names = tuple(f.strip().lower() for f in text.split(","))
    for f in names:
        if f not in FORMATS:
            raise argparse.ArgumentTypeError(
                f"unknown mission format {f!r}; known: {', '.join(FORMATS)}")
    return names


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    from turbinefit.cli.common import DefaultsFormatter, job_option, latlonalt

    p: argparse.ArgumentParser = sub.add_parser(
        "plan", help=help, description=DESCRIPTION,
        usage="%(prog)s FIT_DIR --standoff M [--gsd MM_PER_PX] --out OUT_DIR",
        formatter_class=DefaultsFormatter)
    p.add_argument("fit_dir", metavar="FIT_DIR", type=Path, help="output folder of fit or track")
    p.add_argument("--standoff", type=job_option("plan", "STANDOFF"), required=True, metavar="M",
                   help="camera to the surface photographed, and the least distance from "
                   "the blades and the spinner [m]: 3-100 (3 m: a drone's size, its hovering "
                   "error and the model's; docs/inspection.md)")
    p.add_argument("--gsd", type=job_option("plan", "GSD"), default=None, metavar="MM_PER_PX",
                   help="resolution to reach [mm/px] (refused if the camera cannot at the "
                   "stand-off)")
    p.add_argument("--out", type=Path, required=True, metavar="OUT_DIR", help="output folder")
    p.add_argument("--camera", type=Path, default=None, metavar="CAMERA_YAML",
                   help="the next flight's camera (camera_info YAML); default: the fit's flight's")
    p.add_argument("--flight", type=Path, default=None, metavar="FLIGHT_DIR",
                   help="the fit's flight folder (camera, georef.yaml); default: the one "
                   "summary.json names")
    p.add_argument("--overlap", type=job_option("plan", "OVERLAP"), default=0.3, metavar="F",
                   help="fraction of the footprint neighbouring photos share")
    p.add_argument("--max-gimbal-up", type=job_option("plan", "GIMBAL_UP"), default=None,
                   metavar="DEG", help="the gimbal's largest upward pitch [deg], 0-90 and at "
                   "most the platform's (default: the platform's)")
    p.add_argument("--platform", default=None, metavar="NAME",
                   help="the drone, gimbal and app (src/turbinefit/data/drone_platforms.yaml: "
                   "generic, m300-h20t, m350-h20t, m30t, m3e, mavic2-pro, phantom4-pro, px4, "
                   "ardupilot): its gimbal's range, waypoints per mission, top speed and "
                   "camera (default: generic)")
    p.add_argument("--format", type=_formats, default=None, metavar="LIST", dest="formats",
                   help="mission files to write, comma-separated: dji-wpml, litchi, qgc, "
                   "mavlink, kml (default: kml when georeferenced); they need a "
                   "georeferenced fit or --origin")
    p.add_argument("--origin", type=latlonalt, default=None, metavar="LAT,LON,ALT",
                   help="place a flight without georef.yaml (a simulated one): WGS84 "
                   "position and altitude of its world frame's origin, the take-off point")
    p.add_argument("--speed", type=job_option("plan", "SPEED"), default=3.0, metavar="M_S",
                   help="the missions' cruise speed [m/s], at most the platform's")
    p.add_argument("--tower-clearance", type=job_option("plan", "TOWER_CLEARANCE"), default=None,
                   metavar="M",
                   help="least distance from the tower and the nacelle [m], at least 2 and at "
                   "most the stand-off (default: a quarter of the stand-off, at least 2 m: the "
                   "suction sides of blades pointing down are seen from beside the tower)")
    blade_angle = job_option("plan", "BLADE_ANGLE_DEG")
    p.add_argument("--blade-pitch", type=blade_angle, default=0.0, metavar="DEG",
                   help="the blades' parked pitch [deg] if known, as coverage's (0: flat in "
                   "the rotor plane); the edges are photographed along it")
    p.add_argument("--blade-twist", type=blade_angle, default=0.0, metavar="DEG",
                   help="blade twist at the root [deg] if known (the pitch's sense)")
    p.add_argument("--position-margin", type=job_option("plan", "POSITION_MARGIN"),
                   default=0.0, metavar="M",
                   help="how far off its waypoints the drone may take a photo [m] (about 2 "
                   "on GNSS alone, 0.1 with RTK): the views added where the stations leave a "
                   "side unseen show it from anywhere within it (default 0: flown exactly)")
    p.add_argument("--no-plots", action="store_true", help="skip path.png")
    p.add_argument("--overwrite", action="store_true", help="replace OUT_DIR's outputs")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    return p


def run(args: argparse.Namespace) -> int:
    from turbinefit.jobs.plan import plan_folder

    camera = None
    if args.camera is not None:
        from turbinefit.io.camera_yaml import read_camera_yaml

        camera = read_camera_yaml(args.camera)
    report = plan_folder(args.fit_dir, args.out, standoff=args.standoff, max_gsd_mm=args.gsd,
                         camera=camera, flight_dir=args.flight, overlap=args.overlap,
                         max_gimbal_up_deg=args.max_gimbal_up,
                         tower_clearance=args.tower_clearance,
                         blade_pitch_deg=args.blade_pitch, blade_twist_deg=args.blade_twist,
                         position_margin=args.position_margin, platform=args.platform,
                         formats=args.formats, origin=args.origin, speed=args.speed,
                         plots=not args.no_plots, overwrite=args.overwrite)
    if args.quiet:
        return 0
    s = report.summary
    print(f"planned {s['photos']} photos, {s['waypoints']} waypoints, path {s['length_m']:.0f} m "
          f"at {s['standoff_m']:g} m ({s['gsd_mm_px']:.2f} mm/px); clearance from the rotor "
          f"{s['min_rotor_clearance_m']:.2f} m, from the tower {s['min_tower_clearance_m']:.2f} m")
    print(f"platform {s['platform']}: gimbal up to {s['max_gimbal_up_deg']:g} deg")
    if s["skipped"]:
        print("stations without a clear view: "
              + ", ".join(f"{k} {n}" for k, n in s["skipped"].items()))
    short = {k: v for k, v in s["covered"].items() if v < WELL_COVERED}
    steep = [k for k in short if k in s["beyond_gimbal"]]
    if steep:
        print(f"photographed in part, views beyond the gimbal's {s['max_gimbal_up_deg']:g} "
              f"deg up: {_shares(short, steep)} of the span at {s['covered_mm_px']:.2f} "
              "mm/px (park the rotor with that blade pointing down, or fly a gimbal that "
              "looks further up; docs/inspection.md#platforms)")
    other = [k for k in short if k not in steep]
    if other:
        print(f"photographed in part: {_shares(short, other)} of the span at "
              f"{s['covered_mm_px']:.2f} mm/px")
    for fmt, files in s["missions"]["formats"].items():
        n = len(files)
        print(f"{fmt}: {files[0] if n == 1 else f'{files[0]} .. {files[-1]}'}"
              + ("" if n == 1 else f" ({n} missions)"))
    print(f"wrote {args.out}")
    return 0
