"""``turbinefit detect``: heat-maps of photos with the CNN
(:func:`turbinefit.jobs.detect.detect_images`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from turbinefit.cli.common import (
    DefaultsFormatter,
    add_model_options,
    detect_options,
    positive_int,
)


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    d: argparse.ArgumentParser = sub.add_parser(
        "detect", help=help,
        description="Run the heat-map CNN on photos (JPEG/PNG, any size). For each photo writes "
        "OUT_DIR/<stem>.npy, float16 (7, h, w) (channels point_base, point_tower_top, "
        "point_hub, point_blade_tip, line_tower, line_nacelle, line_blade; values in [0, 1]) "
        "at the net's own resolution (160x120 for a 4:3 photo and the shipped model) or "
        "--max-size, and OUT_DIR/<stem>.png, the photo (at most 640 px wide) with the "
        "heat-maps overlaid (base red, tower top orange, hub yellow, tips magenta, tower "
        "cyan, nacelle green, blades blue). Map pixel (j, i) of a WxH photo is photo pixel "
        "u = (j + 0.5) W / w - 0.5, v = (i + 0.5) H / h - 0.5: the photo's camera resized to "
        "w x h, as a flight folder reads maps smaller than its camera.yaml. OUT_DIR is "
        "written atomically.",
        formatter_class=DefaultsFormatter)
    d.add_argument("inputs", metavar="IMAGES_OR_DIRS", type=Path, nargs="+",
                   help="photos, or folders of photos (not recursive)")
    d.add_argument("--out", dest="out_dir", metavar="OUT_DIR", type=Path, required=True,
                   help="output folder")
    add_model_options(d)
    d.add_argument("--max-size", type=positive_int, default=None, metavar="PX",
                   help="write maps PX wide (the photo scaled; at most the photo's size) "
                   "instead of the net's own resolution")
    d.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it holds only detect outputs")
    d.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    return d


def run(args: argparse.Namespace) -> int:
    from turbinefit.jobs.detect import detect_images

    rep = detect_images(args.inputs, args.out_dir, args.model, overwrite=args.overwrite,
                        progress=not args.quiet, threads=args.threads,
                        detect_options=detect_options(args), max_size=args.max_size)
    if not args.quiet:
        print(f"detected {rep.count} photo(s) in {rep.seconds:.2f} s "
              f"({rep.photos_per_second:.0f} photos/s with reading and "
              f"writing, {rep.workers} at once); wrote {rep.out_dir}")
    return 0
