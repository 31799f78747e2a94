"""Benchmark: ``turbinefit import dji`` on real DJI photos, checked against an independent
reading of the same tags (``exiftool``).

The photos are not part of turbinefit. The MIT-licensed repository
``SanNianYiSi/thermal_parser`` holds R-JPEGs of nine DJI thermal payloads (Zenmuse XT2,
XTR, XT S, H20T, H20N, H30T, Mavic 2 Enterprise Advanced, Mavic 3 Thermal, M3TD, Matrice 30T,
Matrice 4T; most with the MPF preview that Pillow reads as MPO)::

    git clone --depth 1 https://github.com/SanNianYiSi/thermal_parser
    apt-get install libimage-exiftool-perl        # exiftool, the independent reader
    python benchmarks/bench_dji_real.py thermal_parser/images

Any folder of DJI JPEGs works (searched recursively). Each photo is imported on its own
(``turbinefit import dji PHOTO --origin ...``, in-process) with a fixed origin 100 m east,
100 m north and 30 m below it; then, against exiftool's reading of the same file
(``exiftool -n``: signed decimal degrees, metres):

* **position**: the imported camera position (``keyframes.txt``, ENU about the origin)
  back to WGS84 and the distance to exiftool's ``GPSLatitude``, ``GPSLongitude`` (XMP or
  EXIF) and ``AbsoluteAltitude`` (else ``GPSAltitude``) [m];
* **optical axis**: the imported camera's z axis in east-north-up terms at the photo
  against ``(sin yaw cos pitch, cos yaw cos pitch, sin pitch)`` of exiftool's
  ``GimbalYawDegree`` and ``GimbalPitchDegree`` (DJI's convention) [deg];
* **focal length**: ``camera.yaml``'s fx against the one the photo's own 35 mm equivalent
  (exiftool's ``FocalLengthIn35mmFormat``, over the photo's diagonal: thermal frames are
  their sensor's full frame) implies, and against the one the payload's published field
  of view implies where :data:`PUBLISHED_FOV` has it [relative difference];
* **refusals**: photos without GPS or gimbal attitude must be refused with exit status 2
  and one line naming what is missing.

Prints one line per photo and a summary per camera; writes
``benchmarks/results/bench_dji_real.json``. Never run by ``make test``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from common import RESULTS, write_json

from turbinefit.cli import main
from turbinefit.io.camera_yaml import read_camera_yaml
from turbinefit.io.georef import Georef, read_georef_yaml
from turbinefit.io.tum import read_tum

#: Published fields of view [deg] (DJI's specification pages) of payloads with a fixed
#: lens: (EXIF model, photo width, EXIF focal length [mm]) -> ("diagonal" or "horizontal",
#: degrees).
PUBLISHED_FOV = {
    ("ZH20T", 640, 13.5): ("diagonal", 40.6),  # https://www.dji.com/zenmuse-h20-series/specs
    ("FLIR", 640, 19.0): ("horizontal", 32.0),  # https://www.dji.com/zenmuse-xt2/info#specs
    ("XT S", 640, 19.0): ("horizontal", 32.0),  # https://www.dji.com/zenmuse-xt-s/specs
    ("M30T", 640, 9.1): ("diagonal", 61.0),    # https://www.dji.com/matrice-30/specs
    ("H30T", 1280, 24.0): ("diagonal", 45.2),  # https://enterprise.dji.com/zenmuse-h30-series/specs
}
TAGS = ["Make", "GPSLatitude", "GPSLongitude", "AbsoluteAltitude", "GPSAltitude", "GimbalYawDegree",
        "GimbalPitchDegree", "GimbalRollDegree", "Model", "ImageWidth", "ImageHeight",
        "FocalLength", "FocalLengthIn35mmFormat"]


def exiftool(paths: list[Path]) -> dict[str, dict]:
    """exiftool's reading of the photos (numbers as numbers), by path."""
    if shutil.which("exiftool") is None:
        sys.exit("exiftool not found: apt-get install libimage-exiftool-perl")
    out = subprocess.run(["exiftool", "-j", "-n", *[f"-{t}" for t in TAGS],
                          *map(str, paths)], capture_output=True, text=True, check=False)
    return {str(Path(d["SourceFile"])): d for d in json.loads(out.stdout or "[]")}


def num(value: object) -> float | None:
    """exiftool's value as a float (its XMP numbers are strings, some with a sign)."""
    if value is None or value == "":
        return None
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None


def run(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(argv)
    return rc, err.getvalue().strip()


def measure(photo: Path, tags: dict, work: Path) -> dict:
    row: dict = {"photo": photo.name, "model": str(tags.get("Model", "")),
                 "width": tags.get("ImageWidth")}
    lat, lon = num(tags.get("GPSLatitude")), num(tags.get("GPSLongitude"))
    alt = num(tags.get("AbsoluteAltitude", tags.get("GPSAltitude")))
    has_pose = None not in (lat, lon, alt, num(tags.get("GimbalPitchDegree")),
                            num(tags.get("GimbalRollDegree")))
    origin = None
    if lat is not None and lon is not None and alt is not None:
        here = Georef(float(lat), float(lon), float(alt))
        olat, olon, oalt = here.geodetic([-100.0, -100.0, -30.0])
        origin = f"{float(olat):.10f},{float(olon):.10f},{float(oalt):.4f}"
    out = work / photo.stem
    argv = ["import", "dji", str(photo), "--out", str(out), "--quiet", "--overwrite"]
    rc, err = run(argv + (["--origin", origin] if origin else []))
    row.update(status=rc, error=err if rc else "", expected="import" if has_pose else "refuse")
    if rc != 0:
        row["ok"] = rc == 2 and not has_pose and len(err.splitlines()) == 1
        return row
    georef = read_georef_yaml(out / "georef.yaml")
    _, poses = read_tum(out / "keyframes.txt")
    plat, plon, palt = georef.geodetic(poses.translation[0])
    d = Georef(float(lat), float(lon), float(alt)).enu(plat, plon, palt)
    row["position_error_m"] = float(np.linalg.norm(d))
    # optical axis in the ENU frame at the photo (rotate the origin's frame there)
    z_world = poses.rotation_matrix()[0][:, 2]
    import pymap3d

    u, v, w = pymap3d.enu2uvw(*z_world, georef.latitude, georef.longitude)
    z_local = np.array(pymap3d.uvw2enu(u, v, w, float(lat), float(lon)))
    yaw = math.radians(num(tags["GimbalYawDegree"]) or 0.0)
    pitch = math.radians(num(tags["GimbalPitchDegree"]) or 0.0)
    expect = np.array([math.sin(yaw) * math.cos(pitch), math.cos(yaw) * math.cos(pitch),
                       math.sin(pitch)])
    row["axis_error_deg"] = float(np.degrees(np.arccos(np.clip(z_local @ expect, -1, 1))))
    cam = read_camera_yaml(out / "camera.yaml")
    row["fx"] = cam.fx
    diag = math.hypot(cam.width, cam.height)
    f35 = num(tags.get("FocalLengthIn35mmFormat"))
    if f35:
        row["fx_from_35mm"] = f35 * diag / math.hypot(36, 24)
        row["focal_vs_35mm"] = cam.fx / row["fx_from_35mm"] - 1
    fov = PUBLISHED_FOV.get((row["model"], cam.width, num(tags.get("FocalLength"))))
    if fov is not None:
        across = diag if fov[0] == "diagonal" else cam.width
        row["fx_published"] = across / 2 / math.tan(math.radians(fov[1]) / 2)
        row["focal_vs_published"] = cam.fx / row["fx_published"] - 1
    row["ok"] = has_pose and row["position_error_m"] < 0.01 and row["axis_error_deg"] < 0.01
    return row


def main_(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("photos_dir", type=Path)
    ap.add_argument("--out", type=Path, default=RESULTS / "bench_dji_real.json")
    args = ap.parse_args(argv)
    photos = sorted(p for p in args.photos_dir.rglob("*")
                    if p.suffix.lower() in (".jpg", ".jpeg") and p.is_file())
    tags = exiftool(photos)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for p in photos:
            t = tags.get(str(p), {})
            if str(t.get("Make", "DJI")).upper() != "DJI" and "Model" not in t:
                continue
            row = measure(p, t, Path(tmp))
            row["photo"] = str(p.relative_to(args.photos_dir))
            rows.append(row)
            extra = (f"position {row['position_error_m'] * 1000:.3f} mm, axis "
                     f"{row['axis_error_deg']:.2e} deg, fx {row['fx']:.1f} px"
                     + (f" ({100 * row['focal_vs_35mm']:+.1f} % of the 35 mm equivalent's)"
                        if "focal_vs_35mm" in row else "")
                     + (f" ({100 * row['focal_vs_published']:+.1f} % of the published FOV's)"
                        if "focal_vs_published" in row else "")
                     if row["status"] == 0 else f"exit {row['status']}: {row['error']}")
            print(f"{'ok ' if row['ok'] else 'BAD'} {p.relative_to(args.photos_dir)} "
                  f"[{row['model']}]: {extra}")
    imported = [r for r in rows if r["status"] == 0]
    summary = {
        "photos": len(rows), "imported": len(imported),
        "refused_exit_2": sum(r["status"] == 2 for r in rows),
        "all_as_expected": all(r["ok"] for r in rows),
        "cameras_imported": sorted({r["model"] for r in imported}),
        "max_position_error_m": max((r["position_error_m"] for r in imported), default=None),
        "max_axis_error_deg": max((r["axis_error_deg"] for r in imported), default=None),
        "focal_vs_35mm": {r["photo"]: r.get("focal_vs_35mm") for r in imported},
        "focal_vs_published": {r["photo"]: r["focal_vs_published"] for r in imported
                               if "focal_vs_published" in r},
    }
    print(json.dumps({k: v for k, v in summary.items() if not k.startswith("focal")}, indent=1))
    write_json(args.out, {"summary": summary, "rows": rows})
    return 0 if summary["all_as_expected"] else 1


if __name__ == "__main__":
    sys.exit(main_())
