"""``turbinefit import dji``: DJI photos to georeferenced flight folders
(:func:`turbinefit.jobs.import_dji.import_dji`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def add_parser(sub: Any) -> argparse.ArgumentParser:
    from turbinefit.cli.common import latlonalt, option
    from turbinefit.jobs.import_dji import DEFAULT_MAX_GAP_S, MAX_GAP

    p: argparse.ArgumentParser = sub.add_parser(
        "dji", help="DJI photos (EXIF/XMP metadata) to flight folders",
        description="Make flight folders from DJI photos, reading only their metadata "
        "(EXIF and the XMP drone-dji fields; no pixels decoded). Photos of several cameras "
        "(a payload's wide, zoom and thermal) are refused unless --camera picks one. "
        "Keyframes: one per photo, sorted by time, timestamps in seconds since the "
        "flight's first photo; photos more than --max-gap apart make separate flights "
        "(OUT/flight-1, flight-2, ...). Positions: WGS84 to east-north-up metres about "
        "--origin (default: the first photo's position at ground level), written to "
        "georef.yaml; a photo far from the others (a wrong position) is refused. "
        "Attitude: the gimbal angles (yaw clockwise from north, pitch 0 level and "
        "-90 down, roll about the optical axis) to world_T_cam. camera.yaml: DJI's "
        "calibration (DewarpData, with distortion), else the calibrated intrinsics, else "
        "the table of DJI cameras, else the 35 mm equivalent over the sensor's full frame. "
        "RTK status and accuracies: keyframes_sigma.csv, position priors for fit and "
        "track. images/: hard links to the photos (copies across file systems). "
        "Details: docs/import.md.")
    p.add_argument("inputs", metavar="PHOTOS_OR_DIRS", type=Path, nargs="+",
                   help="DJI JPEG photos, or folders of them (their .jpg/.jpeg files; "
                   "not recursive)")
    p.add_argument("--out", dest="out_dir", metavar="OUT_DIR", type=Path, required=True,
                   help="flight folder to create (with several flights: the folder of "
                   "flight-1, flight-2, ...)")
    p.add_argument("--camera", default=None, metavar="wide|zoom|thermal|MODEL",
                   help="import this camera's photos when the photos are of several (e.g. "
                   "an H20T's _W, _Z and _T photos): a kind, or an EXIF model (ZH20T)")
    p.add_argument("--max-gap", type=option(MAX_GAP), default=DEFAULT_MAX_GAP_S,
                   metavar="SECONDS", help="longest pause between two photos of one flight "
                   f"(default {DEFAULT_MAX_GAP_S:g} s)")
    p.add_argument("--origin", type=latlonalt, default=None, metavar="LAT,LON,ALT",
                   help="origin of the world frame: WGS84 degrees and altitude [m] in the "
                   "photos' datum (default: each flight's first photo at ground level)")
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
                   help="replace OUT_DIR if it exists (only if it holds nothing but what "
                   "import dji writes)")
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
                   overwrite=args.overwrite, camera=args.camera, max_gap_s=args.max_gap)
    if args.quiet:
        return 0
    flights = f"{len(s.flights)} flights" if len(s.flights) > 1 else "one flight"
    print(f"imported {s.num_photos} photos ({s.camera}, {s.image_size[0]}x{s.image_size[1]}) "
          f"to {s.out_dir} in {s.timings['total']:.2f} s: {flights}")
    for note in s.other_cameras:
        print(f"note: not imported (another camera): {note}")
    for f in s.flights:
        o = f.origin
        if len(s.flights) > 1:
            print(f"{f.out_dir}: {f.num_photos} photos from {f.first_photo}, "
                  f"{f.duration_s:.1f} s of flight")
        else:
            print(f"{f.duration_s:.1f} s of flight")
        print(f"camera: {f.intrinsics}")
        if f.crop:
            print(f"note: {f.crop}")
        print(f"origin: {o.latitude:.8f}, {o.longitude:.8f}, {o.altitude:.2f} m "
              f"({f.origin_source})")
        if f.rtk:
            print(f"positions: {f.rtk} (keyframes_sigma.csv: position priors)")
        print(f"images: {f.images}")
        for names, what in ((f.flight_yaw, "no gimbal yaw; used the aircraft's flight yaw"),
                            (f.position_from_exif, "no XMP position; used the EXIF GPS block")):
            if names:
                print(f"note: {len(names)} photo(s) with {what} (first: {names[0]})")
        print(f"turbine.yaml: {f.turbine}" if f.turbine else
              "no turbine.yaml: fit and track will estimate one (or write it first: "
              "turbinefit init FLIGHT_DIR --near-wgs84 LAT,LON --out FLIGHT_DIR/turbine.yaml)")
    return 0
