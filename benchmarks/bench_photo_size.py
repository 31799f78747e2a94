"""Seconds per simulated inspection photo by photo size: a 20 MP camera at full size and at
fractions of it (``simulate --photo-scale``).

One close-up of a blade with known defects painted on it (the photos of ``simulate --path
... --defects N --images``, which render the photo and the defects' labels in one pass),
10 m from the blade, from a 5472 x 3648 px camera with a 72 deg horizontal field of view
(a 1-inch 20 MP sensor behind an 8.8 mm lens: DJI Zenmuse H20's wide camera, Phantom 4
RTK): 2.6 mm/px at 10 m at full size. Each size is rendered ``--repeat`` times (median
reported; one core, as ``simulate`` renders), and the peak resident memory of the process
after the largest is noted. Writes ``benchmarks/results/bench_photo_size.json``.
Run: ``python benchmarks/bench_photo_size.py`` (about 3 minutes on a free core).
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import time
from pathlib import Path

import numpy as np

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.inspection.defects import Defect, defect_point
from turbinefit.inspection.surface import SurfaceShape, TurbineSurface
from turbinefit.sim.photos import FlightPhotos
from turbinefit.sim.scenario import SimConfig, true_turbine
from turbinefit.turbine.solid import ROOT_TWIST

HERE = Path(__file__).resolve().parent
#: The 20 MP camera (5472 x 3648 px, 72 deg across).
WIDTH, HEIGHT, HFOV_DEG = 5472, 3648, 72.0
SCALES = (1.0, 0.5, 0.25, 0.125)


def look_at(eye: np.ndarray, target: np.ndarray) -> SE3:
    """The camera at ``eye`` looking at ``target`` (y down)."""
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return SE3.from_rotation_translation(np.stack([x, np.cross(z, x), z], -1), eye)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--png", type=Path, default=None,
                    help="also write the full-size photo here (to look at it)")
    args = ap.parse_args()
    turbine = true_turbine(SimConfig(seed=0))
    defects = [Defect("D1", "blade_A", "leading_edge", 48.0, 1.0, 0.4, "erosion"),
               Defect("D2", "blade_A", "pressure_side", 49.0, 0.3, 0.3, "crack"),
               Defect("D3", "blade_A", "pressure_side", 47.0, -0.3, 0.2, "burn"),
               Defect("D4", "blade_A", "pressure_side", 48.5, 0.7, 0.3, "erosion")]
    f = 0.5 * WIDTH / math.tan(math.radians(HFOV_DEG) / 2)
    full = PinholeCamera(WIDTH, HEIGHT, f, f, (WIDTH - 1) / 2, (HEIGHT - 1) / 2)
    rows = []
    for scale in SCALES:
        cam = full.scaled(scale)
        photos = FlightPhotos(cam, turbine, 0, defects=defects)
        surface = TurbineSurface(turbine, shape=SurfaceShape(-photos.scene.blade_pitch,
                                                             -ROOT_TWIST))
        p, n = defect_point(surface, defects[1])
        pose = look_at(p + 10.0 * n, p)
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            photo = photos.photo(0, pose)
            times.append(time.perf_counter() - t0)
        if scale == 1.0 and args.png is not None:
            from turbinefit.io.images import encode_png

            args.png.write_bytes(encode_png(photo.image))
        rows.append({"scale": scale, "width": cam.width, "height": cam.height,
                     "megapixels": round(cam.width * cam.height / 1e6, 2),
                     "mm_per_px_at_10m": round(1000 * 10.0 / cam.fx, 2),
                     "seconds": round(float(np.median(times)), 2),
                     "defects_in_view": len(photo.boxes)})
        print(rows[-1], flush=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    out = {"rows": rows, "peak_rss_bytes": peak}
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "bench_photo_size.json").write_text(json.dumps(out, indent=2) + "\n")
    print(f"peak memory {peak / 2**30:.1f} GiB")


if __name__ == "__main__":
    main()
