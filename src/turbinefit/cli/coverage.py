"""``turbinefit coverage``: what each keyframe of a fit shows of each blade and the tower
(:func:`turbinefit.jobs.coverage.coverage_folder`)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

DESCRIPTION = """\
For every keyframe of a fit (or track) output folder: which blade (A, B, C by
their clockwise angle from 12 o'clock seen from upwind) and how much of the
tower it shows, the span in view, the side seen (leading edge, pressure side,
trailing edge, suction side; tower: front, right, back, left), the distance and
the ground sampling distance (mm per pixel) with the photos' camera. Writes
coverage.csv, sides.csv (best resolution per side and span), summary.json and
coverage.png; with --damage, damage.csv: where each box drawn on a photo (a
damage mark) lies on the turbine - part, side, span range, distance and chord;
with --truth too, how well the boxes were located against the known defects.
Details: docs/inspection.md."""


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    from turbinefit.cli.common import DefaultsFormatter, job_option

    p: argparse.ArgumentParser = sub.add_parser(
        "coverage", help=help, description=DESCRIPTION,
        usage="%(prog)s FIT_DIR [--flight FLIGHT_DIR] --out OUT_DIR [--gsd MM] [--damage CSV]",
        formatter_class=DefaultsFormatter)
    p.add_argument("fit_dir", metavar="FIT_DIR", type=Path,
                   help="output folder of fit or track (or a flight folder: its measured poses)")
    p.add_argument("--flight", type=Path, default=None, metavar="FLIGHT_DIR",
                   help="the flight folder (its camera.yaml); default: the one summary.json names")
    p.add_argument("--camera", type=Path, default=None, metavar="CAMERA_YAML",
                   help="the photos' camera (camera_info YAML) instead of the flight's")
    p.add_argument("--out", type=Path, required=True, metavar="OUT_DIR", help="output folder")
    p.add_argument("--gsd", type=job_option("coverage", "GSD_MM"), default=2.0, metavar="MM",
                   help="a side counts as covered at this many mm per pixel or finer")
    p.add_argument("--step", type=job_option("coverage", "STEP"), default=0.5, metavar="M",
                   help="span between samples along blades and tower [m]")
    blade_angle = job_option("coverage", "BLADE_ANGLE_DEG")
    p.add_argument("--blade-pitch", type=blade_angle, default=0.0, metavar="DEG",
                   help="blade pitch [deg] if known (0: flat in the rotor plane)")
    p.add_argument("--blade-twist", type=blade_angle, default=0.0, metavar="DEG",
                   help="blade twist at the root [deg] if known (the pitch's sense)")
    p.add_argument("--damage", type=Path, default=None, metavar="BOXES_CSV",
                   help="boxes drawn on photos (filename,width,height,class,xmin,ymin,xmax,ymax): "
                   "damage.csv says which part, side and span each covers")
    p.add_argument("--damage-photos", type=Path, default=None, metavar="DIR",
                   help="the folder of the photos --damage names (default: the flight's "
                   "images/; originals that import dji linked are found too)")
    p.add_argument("--truth", type=Path, default=None, metavar="DEFECTS_CSV",
                   help="the known defects the --damage boxes show (simulate's "
                   "defects_groundtruth.csv; the boxes name them in a defect column): "
                   "score where they were located (summary.json's damage_score)")
    p.add_argument("--no-plots", action="store_true", help="skip coverage.png")
    p.add_argument("--overwrite", action="store_true", help="replace OUT_DIR's outputs")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    return p


def run(args: argparse.Namespace) -> int:
    from turbinefit.jobs.coverage import coverage_folder

    camera = None
    if args.camera is not None:
        from turbinefit.io.camera_yaml import read_camera_yaml

        camera = read_camera_yaml(args.camera)
    report = coverage_folder(args.fit_dir, args.out, flight_dir=args.flight, camera=camera,
                             step=args.step,
                             max_gsd_mm=args.gsd, blade_pitch=math.radians(args.blade_pitch),
                             blade_twist=math.radians(args.blade_twist),
                             damage=args.damage, damage_photos=args.damage_photos,
                             truth=args.truth, plots=not args.no_plots,
                             overwrite=args.overwrite)
    if args.quiet:
        return 0
    s = report.summary
    print(f"coverage of {s['keyframes']} keyframes in {report.timings['total']:.2f} s; blades "
          + ", ".join(f"{n} at {b['clock_deg']:.1f} deg" for n, b in s["blades"].items())
          + f" clockwise from 12 o'clock (names stable within {s['name_margin_deg']:.1f} deg)")
    print(f"{'part':<10}{'side':<16}{'seen':>7}{'<= ' + format(args.gsd, 'g') + ' mm/px':>14}"
          f"{'best mm/px':>12}")
    for part, sides in s["coverage"].items():
        for side, c in sides.items():
            best = c["median_best_gsd_mm_px"]  # NaN: never seen
            print(f"{part:<10}{side:<16}{100 * c['seen']:6.1f}%{100 * c['covered']:13.1f}%"
                  + (f"{best:12.2f}" if math.isfinite(best) else f"{'-':>12}"))
    for d in report.damage or []:
        loc = d.location
        where = ("not on the turbine" if loc.part is None else
                 f"{loc.part} {loc.side or ''} "
                 + (f"{loc.span_from_m:.1f}-{loc.span_to_m:.1f} m" if loc.span_from_m is not None
                    else "") + f" ({100 * loc.on_part:.0f} % of the box)")
        print(f"damage {d.photo} {d.label}: {where}")
    if report.damage_score is not None:
        print(damage_score_line(report.damage_score.summary()))
    print(f"wrote {args.out}")
    return 0


def damage_score_line(s: dict[str, Any]) -> str:
    """One line of :meth:`turbinefit.eval.damage.DamageScore.summary`'s figures."""
    def pct(v: float | None) -> str:
        return "-" if v is None else f"{100 * v:.0f} %"

    def m(v: float | None, unit: str = " m") -> str:
        return "-" if v is None else f"{v:.2f}{unit}"

    return (f"damage score: {s['defects_seen']} of {s['defects']} defects seen in "
            f"{s['boxes']} boxes; right blade {pct(s['right_part'])}, right blade and side "
            f"{pct(s['right_part_and_side'])}; span error median {m(s['span_error_median_m'])}"
            f", 95th percentile {m(s['span_error_p95_m'])}; chord error median "
            f"{m(s['chord_error_median'], '')}")
