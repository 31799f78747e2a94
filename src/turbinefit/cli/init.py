"""``turbinefit init``: the initial turbine of a flight from its heat-maps or photos
(:func:`turbinefit.jobs.init.init_folder`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

DESCRIPTION = """\
Estimate the initial turbine (turbine.yaml) of a flight from its heat-maps (or
photos, through the CNN) and its GPS/IMU poses, with no angle given: the base,
tower top, hub and blade tips are triangulated robustly across keyframes, then
the heading comes from the rotor plane and the hub, the blade rotation from the
tips (modulo 120 deg), the lengths from the points. Prints turbine.yaml (or
writes --out) and a table of how well each parameter is determined.

A parameter the images do not determine needs a prior: --type (a catalogue of
common turbines, --list-types) or --hub-height/--rotor-diameter for the sizes,
--near for the position when other turbines are in view. Details: docs/init.md."""


def _near(text: str) -> tuple[float, ...]:
    from turbinefit.cli.common import option_tuple
    from turbinefit.io.quantities import COORDINATE, named

    return option_tuple(named(COORDINATE, "X"), named(COORDINATE, "Y"),
                        what="X,Y in metres")(text)


def _near_wgs84(text: str) -> tuple[float, ...]:
    from turbinefit.cli.common import option_tuple
    from turbinefit.io.quantities import LATITUDE, LONGITUDE

    return option_tuple(LATITUDE, LONGITUDE, what="LAT,LON in degrees")(text)


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    from turbinefit.cli.common import add_detect_options, number

    p: argparse.ArgumentParser = sub.add_parser(
        "init", help=help, description=DESCRIPTION,
        usage="%(prog)s FLIGHT_DIR [--near X,Y | --near-wgs84 LAT,LON] "
              "[--type NAME | --hub-height M --rotor-diameter M] [--out FILE]",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("flight_dir", metavar="FLIGHT_DIR", type=Path, nargs="?",
                   help="flight folder (its turbine.yaml, if any, is not read)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--near", type=_near, default=None, metavar="X,Y",
                       help="the turbine stands within ~30 m of here (flight frame, metres)")
    where.add_argument("--near-wgs84", type=_near_wgs84, default=None,
                       metavar="LAT,LON", help="the same in WGS84 degrees (needs georef.yaml)")
    p.add_argument("--type", dest="type_name", default=None, metavar="NAME",
                   help="turbine type of the catalogue (--list-types): priors for the sizes")
    p.add_argument("--hub-height", type=number, default=None, metavar="M",
                   help="hub height [m] (overrides the type's)")
    p.add_argument("--rotor-diameter", type=number, default=None, metavar="M",
                   help="rotor diameter [m] (overrides the type's)")
    p.add_argument("--list-types", action="store_true", help="list the catalogue and exit")
    p.add_argument("--from-images", action="store_true", default=None,
                   help="detect the heat-maps from images/ even if heatmaps/ exists")
    p.add_argument("--model", type=Path, default=None,
                   help="ONNX heat-map model for detection (default: the shipped one)")
    add_detect_options(p)
    p.add_argument("--out", type=Path, default=None, metavar="FILE",
                   help="write turbine.yaml here (default: print it)")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.add_argument("--quiet", action="store_true", help="print no table")
    return p


def run(args: argparse.Namespace) -> int:
    from turbinefit.cli.common import detect_options

    if args.list_types:
        from turbinefit.io.turbine_types import turbine_types

        for key, t in turbine_types().items():
            heights = ", ".join(f"{h:g}" for h in t.hub_heights)
            print(f"{key:<28}{t.name}: rotor {t.rotor_diameter:g} m, hub {heights} m")
        return 0
    if args.flight_dir is None:
        from turbinefit.errors import InputError

        raise InputError("FLIGHT_DIR is required (or --list-types)")
    from turbinefit.jobs.init import init_folder, turbine_prior

    prior = turbine_prior(args.flight_dir, near=args.near, near_wgs84=args.near_wgs84,
                          type_name=args.type_name, hub_height=args.hub_height,
                          rotor_diameter=args.rotor_diameter)
    report = init_folder(args.flight_dir, args.out, prior, overwrite=args.overwrite,
                         from_images=args.from_images, model=args.model,
                         detect_options=detect_options(args))
    s = report.summary
    # the table goes to stderr when the YAML goes to stdout
    table = sys.stdout if args.out is not None else sys.stderr
    if not args.quiet:
        print(f"initial turbine from {s.keyframes_seen} of {s.keyframes} keyframes showing it "
              f"in {s.seconds:.2f} s" + (f" ({s.prior})" if s.prior else ""), file=table)
        for row in s.table():
            print(row, file=table)
    if args.out is None:
        sys.stdout.write(report.yaml)
    elif not args.quiet:
        print(f"wrote {args.out}")
    return 0
