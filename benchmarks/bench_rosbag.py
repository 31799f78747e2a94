"""``turbinefit import rosbag`` on a simulated photo flight: import time, and the fit of the
imported folder against the fit of the flight itself.

A flight (``turbinefit simulate --images --odometry vio``, default 100 keyframes of 640x480,
seed 0; cached in ``benchmarks/data/``) is written as a ROS 1 bag of raw ``rgb8`` images
and a ROS 2 MCAP bag of compressed PNGs, with camera_info and odometry at 10 samples per
image interval (the test helper ``tests/support_rosbag.py``). Each bag is imported by the
real command line with every image as a keyframe (``--every-m 0 --every-deg 0``; wall time
of the process), and the import and the flight are fitted with ``turbinefit fit
--from-images --no-plots``.

Usage::

    python benchmarks/bench_rosbag.py [--keyframes 100] [--size 640x480]

Prints and writes ``benchmarks/results/bench_rosbag.json``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import BIN, DATA, HERE, RESULTS, write_json

sys.path.insert(0, str(HERE.parent / "tests"))
from support_rosbag import IMAGE_TOPIC, ODOM_TOPIC, BagSpec, write_flight_bag

from turbinefit.io import read_tum, read_turbine_yaml


def flight(n: int, width: int, height: int) -> Path:
    out = DATA / f"flight_photos_vio_n{n}_{width}x{height}"
    if not (out / "keyframes.txt").exists():
        DATA.mkdir(exist_ok=True)
        subprocess.run([str(BIN), "simulate", str(out), "--keyframes", str(n), "--seed", "0",
                        "--width", str(width), "--height", str(height), "--images",
                        "--odometry", "vio", "--overwrite", "--quiet"], check=True)
    return out


def timed(argv: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run([str(BIN), *argv], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def fit_difference(a: Path, b: Path) -> dict[str, float]:
    """Largest differences between two fits: poses [m], quaternion entries, turbine."""
    _, pa = read_tum(a / "keyframes.txt")
    _, pb = read_tum(b / "keyframes.txt")
    ta = read_turbine_yaml(a / "turbine.yaml").to_vector()
    tb = read_turbine_yaml(b / "turbine.yaml").to_vector()
    return {"position_m": float(np.abs(pa.translation - pb.translation).max()),
            "quaternion": float(np.abs(pa.wxyz - pb.wxyz).max()),
            "turbine": float(np.abs(np.asarray(ta) - np.asarray(tb)).max())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--keyframes", type=int, default=100)
    ap.add_argument("--size", default="640x480")
    args = ap.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    src = flight(args.keyframes, width, height)
    result: dict = {"keyframes": args.keyframes, "size": args.size, "bags": {}}
    with tempfile.TemporaryDirectory(dir=DATA) as tmp:
        work = Path(tmp)
        base_fit = work / "fit_flight"
        timed(["fit", str(src), "--from-images", "--out", str(base_fit), "--no-plots"])
        for kind, spec in (("ros1_rgb8", BagSpec("ros1", rate=10)),
                           ("mcap_png", BagSpec("mcap", compressed=True, rate=10))):
            bag = work / (kind + (".bag" if spec.kind == "ros1" else ""))
            write_flight_bag(src, bag, spec)
            size = (sum(p.stat().st_size for p in bag.rglob("*")) if bag.is_dir()
                    else bag.stat().st_size)
            common = [str(bag), "--image-topic", IMAGE_TOPIC, "--odometry-topic", ODOM_TOPIC,
                      "--turbine-yaml", str(src / "turbine.yaml")]
            every = work / f"{kind}_every"
            t_every = timed(["import", "rosbag", *common, "--out", str(every),
                             "--every-m", "0", "--every-deg", "0"])
            fit = work / f"{kind}_fit"
            timed(["fit", str(every), "--from-images", "--out", str(fit), "--no-plots"])
            row = {"bag_mb": round(size / 1e6, 1), "import_s": round(t_every, 2),
                   "fit_difference": fit_difference(base_fit, fit)}
            result["bags"][kind] = row
            print(kind, row)
            shutil.rmtree(every)
            bag.unlink() if bag.is_file() else shutil.rmtree(bag)
    write_json(RESULTS / "bench_rosbag.json", result)


if __name__ == "__main__":
    main()
