"""``turbinefit import dji``: DJI photos to a georeferenced flight folder
(:func:`turbinefit.jobs.import_dji.import_dji`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def add_parser(sub: Any) -> argparse.ArgumentParser:
    from turbinefit.cli.common import latlonalt

    p: argparse.ArgumentParser = sub.add_parser(
        "dji", help="DJI photos (EXIF/XMP metadata) to a flight folder",
        description="Make a flight folder from DJI photos, reading only their metadata "
        "(EXIF and the XMP drone-dji fields; no pixels decoded). Keyframes: one per photo, "
        "sorted by time, timestamps in seconds since the first photo. Positions: WGS84 to "
        "east-north-up metres about --origin (default: the first photo's position at "
        "ground level, altitude minus relative altitude), written to georef.yaml. "
        "Attitude: the gimbal angles (yaw clockwise from north, pitch 0 level and -90 "
        "down, roll about the optical axis; the flight yaw where the gimbal yaw is "
        "missing) to world_T_cam. camera.yaml: the calibrated XMP intrinsics, else the "
        "35 mm equivalent focal length, principal point at the centre, no distortion. "
        "images/: hard links to the photos (copies across file systems). fit and track "
        "on the folder also write the turbine base and the cameras in WGS84. Details: "
        "docs/import.md.")
    p.add_argument("inputs", metavar="PHOTOS_OR_DIRS", type=Path, nargs="+",
                   help="DJI JPEG photos, or folders of them (their .jpg/.jpeg files; "
                   "not recursive); all from one camera")
    p.add_argument("--out", dest="out_dir", metavar="FLIGHT_DIR", type=Path, required=True,
                   help="flight folder to create")
    p.add_argument("--origin", type=latlonalt, default=None, metavar="LAT,LON,ALT",
                   help="origin of the world frame: WGS84 degrees and altitude [m] in the "
                   "photos' datum (default: the first photo at ground level)")
    turbine = p.add_mutually_exclusive_group()
    turbine.add_argument("--turbine-yaml", type=Path, default=None, metavar="FILE",
                         help="initial turbine to copy in as turbine.yaml (with latitude "
                         "and longitude, as a georeferenced fit writes it, its base is "
                         "moved there in this flight's frame)")
    turbine.add_argument("--turbine", type=_latlon, default=None, metavar="LAT,LON",
                         help="the turbine's position: turbine.yaml is estimated from the "
                         "photos near it (turbinefit init --near; the CNN detects every "
                         "photo)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace FLIGHT_DIR if it exists (only if it holds nothing but a "
                   "flight folder)")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    return p


def _latlon(text: str) -> tuple[float, ...]:
    from turbinefit.cli.common import option_tuple
    from turbinefit.io.quantities import LATITUDE, LONGITUDE

    return option_tuple(LATITUDE, LONGITUDE, what="LAT,LON in degrees")(text)


def run(args: argparse.Namespace) -> int:
    from turbinefit.jobs.import_dji import import_dji

    s = import_dji(args.inputs, args.out_dir, origin=args.origin,
                   turbine_yaml=args.turbine_yaml, turbine_location_deg=args.turbine,
                   overwrite=args.overwrite)
    if args.quiet:
        return 0
    o = s.origin
    print(f"imported {s.num_photos} photos ({s.camera}, {s.image_size[0]}x{s.image_size[1]}) "
          f"to {s.out_dir} in {s.timings['total']:.2f} s: {s.duration_s:.1f} s of flight")
    print(f"camera: {s.intrinsics}")
    print(f"origin: {o.latitude:.8f}, {o.longitude:.8f}, {o.altitude:.2f} m ({s.origin_source})")
    print(f"images: {s.images}")
    for names, what in ((s.flight_yaw, "no gimbal yaw; used the aircraft's flight yaw"),
                        (s.position_from_exif, "no XMP position; used the EXIF GPS block")):
        if names:
            print(f"note: {len(names)} photo(s) with {what} (first: {names[0]})")
    print(f"turbine.yaml: {s.turbine}" if s.turbine else
          "no turbine.yaml: fit and track will estimate one (or write it first: turbinefit "
          "init FLIGHT_DIR --near-wgs84 LAT,LON --out FLIGHT_DIR/turbine.yaml)")
    return 0
