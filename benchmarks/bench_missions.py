"""``turbinefit plan``'s mission files read back by readers that are not their writers.

The default 200-keyframe flight of ``make demo`` (seed 1; heat-maps, no photos), fitted by
``turbinefit fit``, placed at ``--origin 51.45,-2.51,40`` and planned at 10 m: for the
default platform (``generic``: Litchi, QGroundControl and MAVLink missions), ``m30t``
(DJI WPML) and ``unlimited`` (no gimbal limit, for the photos' pitches). Every mission file
is read back (:mod:`turbinefit.io.mission_readers`: defusedxml with WPML's required
elements, Litchi's exact header, pymavlink's ``MAVWPLoader``, QGroundControl's plan keys),
the numbered missions joined, and compared with ``waypoints.csv``: the largest position
difference [cm] (in the flight's east-north-up frame), heading and gimbal pitch and yaw
differences [deg] (``waypoints.csv``'s own rounding, 1 mm and 0.001 deg, included).

Usage::

    python benchmarks/bench_missions.py

Prints a table and writes ``benchmarks/results/bench_missions.json``.
"""

from __future__ import annotations

import csv
import json
import platform
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from common import RESULTS, run_command, simulate, write_json

from turbinefit.io import mission_readers as R
from turbinefit.io.georef import Georef

ORIGIN = (51.45, -2.51, 40.0)
READERS = {"litchi": ("litchi*.csv", R.read_litchi_csv),
           "qgc": ("mission*.plan", R.read_qgc_plan),
           "mavlink": ("mission*.waypoints", R.read_mavlink_wpl),
           "dji-wpml": ("dji*.kmz", R.read_wpml_kmz)}


def _angle(a: Any, b: Any) -> np.ndarray:
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


def read_back(out: Path, fmt: str) -> dict[str, Any]:
    """The missions of ``fmt`` in plan folder ``out`` against its waypoints.csv."""
    pattern, reader = READERS[fmt]
    files = sorted(out.glob(pattern))
    points: list[R.ReadPoint] = []
    for k, path in enumerate(files):
        read = reader(path)
        points += read if k == 0 else read[1:]
    rows = list(csv.DictReader((out / "waypoints.csv").open()))
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    heading = (90.0 - np.array([float(r["yaw_deg"]) for r in rows])) % 360.0
    pitch = np.array([float(r["gimbal_pitch_deg"]) for r in rows])
    photo = np.array([r["photo"] == "1" for r in rows])
    georef = Georef(*ORIGIN)
    enu = georef.enu([p.latitude for p in points], [p.longitude for p in points],
                     [ORIGIN[2] + p.height for p in points])
    yaw = np.array([p.gimbal_yaw for p in points])[photo]
    return {"files": len(files), "waypoints": len(points), "rows": len(rows),
            "photos_match": [p.photo for p in points] == photo.tolist(),
            "max_position_cm": float(100 * np.abs(enu - xyz).max()),
            "max_heading_deg": float(_angle([p.heading for p in points], heading).max()),
            "max_gimbal_pitch_deg": float(np.abs(np.array(
                [p.gimbal_pitch for p in points])[photo] - pitch[photo]).max()),
            "max_gimbal_yaw_deg": None if np.isnan(yaw).all() else float(
                _angle(yaw, heading[photo]).max())}


def main() -> None:
    flight = simulate(200, 1)
    out: dict[str, Any] = {"machine": platform.platform(), "formats": {}}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        fit = root / "fit"
        run_command(["fit", str(flight), "--out", str(fit), "--no-plots", "--quiet"])
        origin = ",".join(f"{v:g}" for v in ORIGIN)
        for name, formats in (("generic", "litchi,qgc,mavlink,kml"), ("m30t", "dji-wpml"),
                              ("unlimited", "kml")):
            plan = root / name
            run_command(["plan", str(fit), "--standoff", "10", "--origin", origin,
                         "--platform", name, "--format", formats, "--out", str(plan),
                         "--no-plots", "--quiet"])
            summary = json.loads((plan / "summary.json").read_text())
            rows = list(csv.DictReader((plan / "waypoints.csv").open()))
            pitch = np.array([float(r["gimbal_pitch_deg"]) for r in rows if r["photo"] == "1"])
            out[name] = {"photos": summary["photos"], "waypoints": summary["waypoints"],
                         "photos_above_20_deg": int((pitch > 20.0).sum()),
                         "max_gimbal_pitch_deg": float(pitch.max()),
                         "beyond_gimbal": summary["beyond_gimbal"]}
            for fmt in formats.split(","):
                if fmt in READERS:
                    out["formats"][fmt] = read_back(plan, fmt) | {"platform": name}
    print("plan of the demo's flight (seed 1, 200 keyframes) at 10 m, placed at "
          f"{ORIGIN}; mission files read back and compared with waypoints.csv")
    for name in ("generic", "m30t", "unlimited"):
        p = out[name]
        print(f"{name:<10} {p['photos']} photos, {p['waypoints']} waypoints, gimbal up to "
              f"{p['max_gimbal_pitch_deg']:.1f} deg ({p['photos_above_20_deg']} photos above "
              "20 deg)")
    print(f"{'format':<10}{'files':>6}{'waypoints':>10}{'position':>11}{'heading':>9}"
          f"{'pitch':>8}{'gimbal yaw':>11}")
    for fmt, r in out["formats"].items():
        yaw = "-" if r["max_gimbal_yaw_deg"] is None else f"{r['max_gimbal_yaw_deg']:.3f}"
        print(f"{fmt:<10}{r['files']:>6}{r['waypoints']:>10}{r['max_position_cm']:>8.2f} cm"
              f"{r['max_heading_deg']:>9.3f}{r['max_gimbal_pitch_deg']:>8.3f}{yaw:>11}")
    write_json(RESULTS / "bench_missions.json", out)


if __name__ == "__main__":
    main()
