"""``turbinefit mission``: one simulated inspection mission in the loop
(:func:`turbinefit.jobs.mission.mission_folder`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

DESCRIPTION = """\
Simulate an autonomous close-range inspection of a turbine, in the loop: an
approach orbit photographs the whole turbine; the initial turbine is estimated
from it (init, then a fit of the orbit); the inspection is planned (plan) at
--standoff for --gsd; then waypoint by waypoint the drone flies to where it
believes the waypoint is (its true pose is that minus the GNSS error), takes
the photo at its true pose, the tracker updates poses and turbine, the
navigation is corrected by the tracker's estimate, and the rest of the plan is
recomputed whenever the turbine estimate has moved. --open-loop flies the plan
of the typed-in turbine on GNSS alone, as inspections are flown today.

The turbine is a type of the catalogue with its heading, blade rotation and base
drawn from --seed, known defects painted on its blades; the operator's turbine
is the truth off by up to 5 deg in heading and blade rotation, 3 m at the base,
5 % in size. Writes the flight folder of the photos (flight/), the tracker's
estimates (track/), the fit of the photos (fit/), their coverage and the defects
located on the fitted turbine (coverage/), the first plan (plan/), every
position flown (path.csv) and mission.json: coverage of every blade side at the
GSD, the closest true approach to the blades and the tower, replans, the
defects' localisation against the truth. Details: docs/mission.md."""


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    from turbinefit.cli.common import DefaultsFormatter, job_option, seed

    p: argparse.ArgumentParser = sub.add_parser(
        "mission", help=help, description=DESCRIPTION, formatter_class=DefaultsFormatter,
        usage="%(prog)s OUT_DIR [--turbine-type T] [--standoff M] [--gsd MM] "
              "[--gnss standard|rtk] [--camera FILE] [--open-loop] [--seed N]")
    p.add_argument("out_dir", metavar="OUT_DIR", type=Path, help="output folder")
    p.add_argument("--turbine-type", default="nrel5mw", metavar="T",
                   help="turbine type: nrel5mw, v80 or swt93 (simulate --list-presets)")
    p.add_argument("--standoff", type=job_option("mission", "STANDOFF"), default=10.0,
                   metavar="M", help="stand-off of the plan [m]")
    p.add_argument("--gsd", type=job_option("mission", "GSD"), default=2.0, metavar="MM",
                   help="each blade side must be seen at this many mm per pixel or finer")
    p.add_argument("--gnss", choices=("standard", "rtk"), default="standard",
                   help="the drone's GNSS: standard (metre-level, slowly varying) or rtk "
                   "(centimetres); a compass yaw bias of a few degrees either way")
    p.add_argument("--camera", type=Path, default=None, metavar="CAMERA_YAML",
                   help="the inspection camera (camera_info YAML; default: 20 MP, 5280x3956, "
                   "f = 7350 px, a 50 mm lens on a full-frame sensor)")
    p.add_argument("--open-loop", action="store_true",
                   help="fly the plan of the typed-in turbine on GNSS alone (no approach, "
                   "no correction, no replanning)")
    p.add_argument("--seed", type=seed, default=0, help="the mission's random seed")
    p.add_argument("--maps", choices=("photos", "ideal"), default="photos",
                   help="heat-maps of the CNN on the rendered photos, or the simulator's own "
                   "(fast; the loop without the net)")
    p.add_argument("--odometry", choices=("vio", "gnss"), default="vio",
                   help="relative motions between photos from the drone's visual-inertial "
                   "odometry (the GNSS anchoring positions), or from the GNSS poses")
    p.add_argument("--defects", type=job_option("mission", "DEFECTS"), default=12, metavar="N",
                   help="known defects painted on the blades")
    p.add_argument("--photo-width", type=job_option("mission", "PHOTO_WIDTH"), default=320,
                   metavar="PX", help="width the photos are rendered at (the camera scaled; "
                   "coverage and resolution are judged at its full size)")
    p.add_argument("--max-gimbal-up", type=job_option("mission", "GIMBAL_UP"), default=90.0,
                   metavar="DEG", help="the gimbal's largest upward pitch [deg]")
    p.add_argument("--max-photos", type=job_option("mission", "MAX_PHOTOS"), default=None,
                   metavar="N", help="end after this many inspection photos (a short mission)")
    p.add_argument("--width-term", choices=("auto", "on", "off"), default="auto",
                   help="the width term in the tracker and the final fit: the camera's "
                   "distance from a blade measured from how wide it looks in the photo; "
                   "auto: with standard GNSS, not with RTK (docs/mission.md)")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it holds nothing but a mission's outputs")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    return p


def run(args: argparse.Namespace) -> int:
    import math
    import sys

    from turbinefit.errors import InputError
    from turbinefit.jobs.mission import mission_folder
    from turbinefit.mission import MISSION_CAMERA, MissionConfig
    from turbinefit.sim.turbines import PRESETS

    if args.turbine_type not in PRESETS:
        raise InputError(f"unknown turbine type {args.turbine_type!r} (choose from "
                         f"{', '.join(PRESETS)})", field="--turbine-type")
    camera = MISSION_CAMERA
    if args.camera is not None:
        from turbinefit.io.camera_yaml import read_camera_yaml

        camera = read_camera_yaml(args.camera)
    cfg = MissionConfig(
        turbine=args.turbine_type, seed=args.seed, standoff=args.standoff, gsd_mm=args.gsd,
        gnss=args.gnss, camera=camera, closed_loop=not args.open_loop,
        defects=int(args.defects), maps=args.maps, odometry=args.odometry,
        photo_width=min(int(args.photo_width), camera.width),
        max_gimbal_up_deg=args.max_gimbal_up,
        max_photos=int(args.max_photos) if args.max_photos is not None else 100_000,
        width_term=None if args.width_term == "auto" else args.width_term == "on")

    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(desc="mission", unit="photo", disable=None, file=sys.stderr)

    def progress(stage: str, done: int, total: int) -> None:
        if bar is not None:
            bar.set_description(stage)
            bar.total = total
            bar.n = done
            bar.refresh()

    try:
        report = mission_folder(args.out_dir, cfg, overwrite=args.overwrite,
                                plots=not args.no_plots, progress=progress)
    finally:
        if bar is not None:
            bar.close()
    if args.quiet:
        return 0
    s = report.summary
    est = s["estimate"]
    dmg = s["damage"]

    def pct(v: Any) -> str:
        return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{100 * v:.1f} %"

    def m(v: Any) -> str:
        return "-" if v is None else f"{v:.3f} m"

    print(f"mission {'open' if args.open_loop else 'closed'} loop, {s['photos']['orbit']} "
          f"approach + {s['photos']['inspection']} inspection photos, {s['replans']} replans; "
          f"{s['initial_turbine']}")
    print(f"coverage at <= {args.gsd:g} mm/px: least blade side "
          f"{pct(s['least_blade_side_coverage'])}; closest true approach: rotor "
          f"{s['closest_true_approach_m']['rotor']:.2f} m, tower/nacelle "
          f"{s['closest_true_approach_m']['tower_nacelle']:.2f} m (stand-off {args.standoff:g} m)")
    print(f"poses in the turbine's frame: recorded {est['recorded']['turbine_frame_position_m']:.3f}"
          f" m -> fit {est['fit']['turbine_frame_position_m']:.3f} m (verdict "
          f"{est['fit']['verdict']})")
    print(f"defects: {dmg['defects_seen']} of {dmg['defects']} seen; right blade and side "
          f"{pct(dmg['right_part_and_side'])}, span error median {m(dmg['span_error_median_m'])}"
          f", 95th percentile {m(dmg['span_error_p95_m'])} (without turbinefit: right blade "
          f"and side {pct(s['damage_without_turbinefit']['right_part_and_side'])})")
    upd = s["tracker_update_ms"]["median"]
    print(f"tracker update median {upd:.1f} ms (detection included); outputs in {report.out_dir}"
          if upd is not None else f"outputs in {report.out_dir}")
    return 0
