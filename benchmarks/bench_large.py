"""Real camera sizes: ``detect``, ``simulate`` and ``fit --from-images`` at 20 MP.

A 20 MP inspection camera (5280 x 3956) is the case measured:

* ``simulate --width 5280 --height 3956``: bytes of heat-maps written per keyframe (the
  maps are 320 x 240 whatever the camera; ``--images`` renders the same maps);
* a 300-keyframe flight of 20 MP JPEG photos: the flight is simulated with the 5280 x
  3956 camera; each keyframe's photo is rendered by turbinefit's renderer at a tenth of
  the size (528 x 396, camera resized to it; rendering at 20 MP takes about 90 s a
  photo), enlarged to 5280 x 3956, given sensor-like noise (Gaussian, sigma 5 grey
  levels, one fixed pattern) so that it does not compress like a smooth render, and
  saved as JPEG quality 90 (``images/<t>.jpg``, about 3.5 MB each). Made once, then
  reused from ``benchmarks/data/``;
* ``detect`` on those photos (all, and the first 30): photos per second, peak memory
  (maximum resident set size of the command's process) and bytes written per photo; the
  CPU seconds per photo too (user + system), which say the rate on two free cores when
  other work shares the machine;
* ``fit --from-images`` (the defaults for photos) of the whole flight, end to end
  (process start to exit), and its errors against the ground truth.

Every command runs as its own process (the installed ``turbinefit``); its peak memory is
its ``ru_maxrss`` (``os.wait4`` in a small process that starts it). Results go to
``benchmarks/results/bench_large.json``.
Run: ``python benchmarks/bench_large.py`` (about 5 minutes the first time on 2 cores, most
of it making the photos; ``--keyframes`` for a smaller flight).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from common import BIN, DATA, RAN, RESULTS, warm, write_json

W, H = 5280, 3956
RENDER_W, RENDER_H = 528, 396
NOISE_SIGMA = 5.0
JPEG_QUALITY = 90
SEED = 1


#: Runs a command and prints its wall time, peak memory and CPU time as JSON (its stdout
#: goes to the file named first). A small process of its own: Linux counts the memory of
#: the process a command is forked from into the command's peak (ru_maxrss survives
#: exec), so the command must not be forked from this script, which holds photos.
_MEASURE = """
import json, os, subprocess, sys, time
t0 = time.perf_counter()
with open(sys.argv[1], "w") as out:
    proc = subprocess.Popen(sys.argv[2:], stdout=out)
    _, status, ru = os.wait4(proc.pid, 0)
print(json.dumps({"rc": os.waitstatus_to_exitcode(status), "seconds": time.perf_counter() - t0,
                  "maxrss_kb": ru.ru_maxrss, "cpu": ru.ru_utime + ru.ru_stime}))
"""


def run_measured(argv: list[str]) -> tuple[float, int, str, float]:
    """Run a command; (wall seconds, its peak memory [bytes], its stdout, its CPU seconds
    (user + system)), measured by a small process of its own (:data:`_MEASURE`)."""
    out_path = DATA / "large_stdout.txt"
    done = subprocess.run([sys.executable, "-c", _MEASURE, str(out_path), *argv],
                          stdout=subprocess.PIPE, text=True, check=True)
    m = json.loads(done.stdout)
    if m["rc"] not in RAN:
        raise SystemExit(f"{' '.join(argv)} failed (exit status {m['rc']})")
    return m["seconds"], m["maxrss_kb"] * 1024, out_path.read_text(), m["cpu"]


_NOISE: np.ndarray | None = None


def _photo(args: tuple[np.ndarray, str]) -> int:
    """Enlarge a rendered photo to 20 MP, add the noise pattern, save it as JPEG."""
    from PIL import Image

    from turbinefit.io.images import resize_image

    global _NOISE
    small, path = args
    if _NOISE is None:
        rng = np.random.default_rng(0)
        _NOISE = np.clip(rng.normal(0, NOISE_SIGMA, (H, W, 3)), -127, 127).astype(np.int16)
    big = resize_image(small, W, H).astype(np.int16)
    big += _NOISE
    np.clip(big, 0, 255, out=big)
    Image.fromarray(big.astype(np.uint8)).save(path, quality=JPEG_QUALITY)
    return Path(path).stat().st_size


def make_flight(n: int) -> Path:
    """The n-keyframe flight with 20 MP JPEG photos (module docstring), made once."""
    from turbinefit.io.flight_folder import read_flight_folder
    from turbinefit.io.heatmap_files import keyframe_stem
    from turbinefit.jobs.simulate import simulate_folder
    from turbinefit.sim.images import render_flight_images
    from turbinefit.sim.scenario import SimConfig

    out = DATA / f"large_flight_n{n}_s{SEED}"
    if (out / "images").is_dir() and len(list((out / "images").iterdir())) == n:
        return out
    DATA.mkdir(exist_ok=True)
    cfg = SimConfig(n_keyframes=n, seed=SEED, width=W, height=H)
    simulate_folder(out, cfg, overwrite=True)
    folder = read_flight_folder(out)
    assert folder.gt_world_T_cam is not None and folder.gt_turbine is not None
    small_cam = folder.camera.resized(RENDER_W, RENDER_H)
    tmp = out / "images.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    photos = render_flight_images(small_cam, folder.gt_world_T_cam,
                                  folder.gt_turbine.to_vector(), cfg.seed, cfg.geometry,
                                  progress=True)
    jobs = ((img, str(tmp / (keyframe_stem(t) + ".jpg")))
            for t, img in zip(folder.timestamps.tolist(), photos, strict=True))
    with ProcessPoolExecutor(2) as ex:
        sizes = list(ex.map(_photo, jobs))
    os.replace(tmp, out / "images")
    print(f"made {n} photos of {W}x{H}, JPEG {np.mean(sizes) / 1e6:.1f} MB on average",
          flush=True)
    return out


def folder_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def bench_simulate(work: Path, keyframes: int = 10) -> dict:
    out = work / "sim"
    seconds, rss, _, _ = run_measured([str(BIN), "simulate", str(out), "--width", str(W),
                                    "--height", str(H), "--keyframes", str(keyframes),
                                    "--overwrite", "--quiet"])
    maps = folder_bytes(out / "heatmaps")
    shape = np.load(next((out / "heatmaps").iterdir()), mmap_mode="r").shape
    return {"command": f"turbinefit simulate OUT --width {W} --height {H} "
                       f"--keyframes {keyframes}",
            "heatmap_shape": list(shape), "heatmap_bytes_per_keyframe": maps / keyframes,
            "seconds": seconds, "peak_rss_mb": rss / 1e6}


def bench_detect(flight: Path, work: Path, count: int | None) -> dict:
    photos = sorted((flight / "images").iterdir())
    if count is not None:
        photos = photos[:count]
    out = work / f"det{len(photos)}"
    inputs = [str(flight / "images")] if count is None else [str(p) for p in photos]
    warm(flight / "images")
    seconds, rss, text, cpu = run_measured([str(BIN), "detect", *inputs, "--out", str(out),
                                            "--overwrite"])
    m = re.search(r"detected (\d+) photo\(s\) in ([0-9.]+) s", text)
    assert m is not None, text
    written = folder_bytes(out)
    maps = np.load(out / (photos[0].stem + ".npy"), mmap_mode="r").shape
    from PIL import Image

    with Image.open(out / (photos[0].stem + ".png")) as im:
        overlay = im.size
    return {"command": f"turbinefit detect {'IMAGES_DIR' if count is None else 'PHOTOS'} "
                       f"--out OUT ({len(photos)} photos)",
            "photos": len(photos), "job_seconds": float(m.group(2)),
            "photos_per_second": len(photos) / float(m.group(2)),
            "wall_seconds": seconds, "photos_per_second_wall": len(photos) / seconds,
            "cpu_seconds_per_photo": cpu / len(photos),
            "photos_per_second_2_free_cores": 2 * len(photos) / cpu,
            "peak_rss_mb": rss / 1e6, "bytes_per_photo": written / len(photos),
            "map_shape": list(maps), "overlay_size": list(overlay)}


def bench_fit(flight: Path, work: Path) -> dict:
    out = work / "fit"
    warm(flight / "images")
    seconds, rss, _, cpu = run_measured([str(BIN), "fit", str(flight), "--from-images",
                                         "--out", str(out), "--no-plots", "--overwrite"])
    summary = json.loads((out / "summary.json").read_text())
    return {"command": "turbinefit fit FLIGHT --from-images --out OUT --no-plots",
            "keyframes": summary.get("num_keyframes"), "wall_seconds": seconds,
            "cpu_seconds": cpu, "peak_rss_mb": rss / 1e6, "timings": summary.get("timing_s"),
            "accuracy": summary.get("accuracy")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keyframes", type=int, default=300, help="photos of the 20 MP flight")
    args = ap.parse_args()
    work = DATA / "large_work"
    work.mkdir(parents=True, exist_ok=True)
    result: dict = {"camera": [W, H], "python": sys.version.split()[0],
                    "cpus": os.cpu_count()}
    result["simulate"] = bench_simulate(work)
    print("simulate:", result["simulate"], flush=True)
    flight = make_flight(args.keyframes)
    result["flight"] = {"keyframes": args.keyframes, "photo_jpeg_mb": folder_bytes(
        flight / "images") / args.keyframes / 1e6, "rendered_at": [RENDER_W, RENDER_H]}
    result["detect_30"] = bench_detect(flight, work, 30)
    print("detect 30:", result["detect_30"], flush=True)
    result["detect_all"] = bench_detect(flight, work, None)
    print("detect all:", result["detect_all"], flush=True)
    result["fit"] = bench_fit(flight, work)
    print("fit:", result["fit"], flush=True)
    write_json(RESULTS / "bench_large.json", result)
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
