"""``turbinefit view``: one self-contained, interactive HTML page of a fit or a mission
(:func:`turbinefit.jobs.view.view_page`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

DESCRIPTION = """\
Write one HTML file that opens offline by double-click (no server, no network:
three.js is inside it) and shows in 3-D the fitted turbine, the camera frusta
and paths of the optimised, initial and ground-truth estimates, the planned path
and the coverage colours on the blades' sides. Clicking a camera shows its photo
with the fitted (green) and initial (red) model reprojected over it.

FIT_OR_MISSION_DIR is a fit (or track) output folder, or a mission folder
holding fit/ (or track/) and optionally plan/ and coverage/; --plan and
--coverage name such folders explicitly. Without a coverage folder, coverage is
computed from the fit and its flight's camera (--no-coverage: none).
Details: docs/view.md."""


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    from turbinefit.cli.common import DefaultsFormatter, job_option

    p: argparse.ArgumentParser = sub.add_parser(
        "view", help=help, description=DESCRIPTION,
        usage="%(prog)s FIT_OR_MISSION_DIR --out VIEW.html [--plan DIR] [--coverage DIR]",
        formatter_class=DefaultsFormatter)
    p.add_argument("source", metavar="FIT_OR_MISSION_DIR", type=Path,
                   help="output folder of fit or track, or a mission folder (fit/, plan/, "
                   "coverage/)")
    p.add_argument("--out", type=Path, required=True, metavar="VIEW.html",
                   help="the page to write")
    p.add_argument("--flight", type=Path, default=None, metavar="FLIGHT_DIR",
                   help="the fit's flight folder (camera, initial poses, ground truth, "
                   "photos); default: the one summary.json names")
    p.add_argument("--plan", type=Path, default=None, metavar="PLAN_DIR",
                   help="a plan output folder: its path and photos")
    p.add_argument("--coverage", type=Path, default=None, metavar="COVERAGE_DIR",
                   help="a coverage output folder: its colours on the blades and tower")
    p.add_argument("--no-coverage", action="store_true",
                   help="without a coverage folder, do not compute coverage")
    p.add_argument("--gsd", type=job_option("view", "GSD_MM"), default=None, metavar="MM",
                   help="coverage counts a side covered at this many mm per pixel or finer "
                   "(default: the coverage folder's, else 2)")
    p.add_argument("--photos", type=job_option("view", "PHOTOS"), default=200, metavar="N",
                   help="keyframes drawn as frusta with their photo embedded, spread evenly "
                   "(0: no photos, 200 frusta)")
    p.add_argument("--thumbnail", type=job_option("view", "THUMBNAIL"), default=400,
                   metavar="PX", help="width of the embedded photos [px] (JPEG; never "
                   "wider than the photos)")
    p.add_argument("--title", default=None, help="the page's title (default: the folder's name)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace VIEW.html (only a page turbinefit view wrote)")
    p.add_argument("--quiet", action="store_true", help="print nothing")
    return p


def run(args: argparse.Namespace) -> int:
    from turbinefit.jobs.view import view_page

    report = view_page(args.source, args.out, flight_dir=args.flight, plan_dir=args.plan,
                       coverage_dir=args.coverage, coverage=not args.no_coverage,
                       max_gsd_mm=args.gsd, thumbnail=int(args.thumbnail),
                       photos=int(args.photos), title=args.title, overwrite=args.overwrite)
    if args.quiet:
        return 0
    parts = [f"{report.keyframes} keyframes", f"{report.shown} frusta",
             f"{report.photos} photos"]
    if report.inputs.plan_dir is not None:
        parts.append(f"plan {report.inputs.plan_dir}")
    if report.coverage is not None:
        parts.append(f"coverage {report.coverage}")
    print(f"view of {report.inputs.fit_dir}: " + ", ".join(parts)
          + (f"; verdict {report.verdict}" if report.verdict else ""))
    for note in report.notes:
        print(f"note: {note}")
    print(f"wrote {args.out} ({report.size_bytes / 1e6:.1f} MB) in "
          f"{report.timings['total']:.2f} s")
    return 0
