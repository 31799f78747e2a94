"""``turbinefit import dji`` of 300 DJI-style 20 MP photos (5280 x 3956), end to end.

The photos are made once and reused from ``benchmarks/data/dji_20mp/``: 300 cameras on an
inspection orbit around a turbine (radius 60 m, 20-110 m up, looking at the tower),
converted to WGS84 positions and gimbal angles about a take-off point, written by
:func:`turbinefit.sim.dji_photos.write_dji_photo` (real XMP packet and EXIF, calibrated
intrinsics) over cheap content: one smooth gradient, JPEG quality 90, about 0.4 MB a photo
(a real 20 MP DJI photo is 8-12 MB; only its headers are read, so the size matters only
where photos are copied rather than hard-linked).

Measured, each run a process of its own (``python -m turbinefit.cli``, so the source on
``PYTHONPATH`` is the one measured), warm page cache:

* ``import dji`` into ``benchmarks/data/`` (same file system: ``images/`` are hard
  links), three runs: wall seconds process start to exit, and CPU seconds (user +
  system);
* the same into ``/dev/shm`` when it is another file system (``images/`` are copies);
* in this process: reading one photo's metadata (:func:`turbinefit.io.dji.read_dji_photo`)
  against decoding one photo's pixels, which shows that the import decodes none.

Results go to ``benchmarks/results/bench_import.json``.
Run: ``python benchmarks/bench_import.py`` (about 2 minutes the first time on 2 cores,
most of it making the photos).
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from common import DATA, RESULTS, warm, write_json

W, H = 5280, 3956
N = 300
FOCAL_PX = 3700.0
ORIGIN = (51.4545, -2.5879, 30.0)
PHOTOS = DATA / "dji_20mp"
CLI = [sys.executable, "-m", "turbinefit.cli"]


def _poses():
    from turbinefit.geometry.se3 import world_T_cam_from_angles

    k = np.arange(N, dtype=np.float64)
    angle = 2 * np.pi * k / 100.0
    pos = np.stack([60 * np.cos(angle), 60 * np.sin(angle), 20 + 90 * k / N], axis=-1)
    yaw = angle + np.pi
    pitch = np.arctan2(50.0 - pos[:, 2], 60.0)  # at the tower, 50 m up
    return world_T_cam_from_angles(pos, yaw, pitch, np.zeros(N)), 2.0 * k


def _write(chunk: list[int]) -> None:
    from turbinefit.geometry.camera import PinholeCamera
    from turbinefit.io.georef import Georef
    from turbinefit.sim.dji_photos import dji_poses, write_dji_photo

    y = np.linspace(60, 200, H, dtype=np.float32)[:, None]
    x = np.linspace(0, 40, W, dtype=np.float32)[None, :]
    pixels = np.repeat((y + x).astype(np.uint8)[:, :, None], 3, axis=2)
    camera = PinholeCamera(W, H, FOCAL_PX, FOCAL_PX, (W - 1) / 2, (H - 1) / 2)
    poses, times = _poses()
    meta = dji_poses(Georef(*ORIGIN), poses, times)
    for k in chunk:
        write_dji_photo(PHOTOS / f"DJI_{k + 1:04d}.JPG", pixels, meta[k], camera=camera,
                        model="M3E", quality=90)


def make_photos() -> Path:
    """The 300 photos (made once; ``.complete`` marks a finished set)."""
    if not (PHOTOS / ".complete").exists():
        shutil.rmtree(PHOTOS, ignore_errors=True)
        PHOTOS.mkdir(parents=True)
        print(f"making {N} photos of {W}x{H} in {PHOTOS} ...", flush=True)
        chunks = [list(range(i, N, 2)) for i in range(2)]
        with ProcessPoolExecutor(2) as pool:
            list(pool.map(_write, chunks))
        (PHOTOS / ".complete").write_text("")
    return PHOTOS


def run_import(out: Path) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one ``import dji`` of the photos into ``out``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([*CLI, "import", "dji", str(PHOTOS), "--out", str(out), "--overwrite",
                    "--quiet"], check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def metadata_vs_decode() -> dict[str, float]:
    """Seconds to read one photo's metadata (mean over all) and to decode one photo."""
    from PIL import Image

    from turbinefit.io.dji import read_dji_photo

    photos = sorted(PHOTOS.glob("*.JPG"))
    t0 = time.perf_counter()
    for p in photos:
        read_dji_photo(p)
    read = (time.perf_counter() - t0) / len(photos)
    t0 = time.perf_counter()
    with Image.open(photos[0]) as im:
        im.load()
    return {"metadata_read_ms": read * 1e3, "full_decode_ms": (time.perf_counter() - t0) * 1e3}


def main() -> None:
    make_photos()
    warm(PHOTOS)
    size_mb = sum(p.stat().st_size for p in PHOTOS.glob("*.JPG")) / N / 1e6
    out = DATA / "dji_20mp_flight"
    runs = [run_import(out) for _ in range(3)]
    result: dict[str, object] = {
        "photos": N, "size": [W, H], "mean_photo_mb": round(size_mb, 3),
        "hard_links": {"wall_s": [round(w, 3) for w, _ in runs],
                       "cpu_s": [round(c, 3) for _, c in runs],
                       "median_wall_s": round(float(np.median([w for w, _ in runs])), 3)},
    }
    shm = Path("/dev/shm")
    if shm.is_dir() and os.stat(shm).st_dev != os.stat(DATA).st_dev:
        target = shm / "turbinefit_bench_import"
        try:
            wall, cpu = run_import(target)
            result["copies_to_other_file_system"] = {"wall_s": round(wall, 3),
                                                     "cpu_s": round(cpu, 3)}
        finally:
            shutil.rmtree(target, ignore_errors=True)
    result.update({k: round(v, 2) for k, v in metadata_vs_decode().items()})
    write_json(RESULTS / "bench_import.json", result)
    print(result)


if __name__ == "__main__":
    main()
