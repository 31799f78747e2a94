"""``turbinefit evaluate``: detection metrics of the CNN on photos labelled with COCO
keypoints (:func:`turbinefit.jobs.evaluate.evaluate_labels`), or with boxes or masks
(:func:`turbinefit.jobs.evaluate.evaluate_regions`)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from turbinefit.cli.common import (
    DefaultsFormatter,
    add_model_options,
    detect_options,
    positive_int,
    positive_number,
)


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    v: argparse.ArgumentParser = sub.add_parser(
        "evaluate", help=help,
        description="Run the heat-map CNN on photos labelled with COCO keypoints (base, "
        "tower_top, hub, tip_1..3, as CVAT and Label Studio export them; any number of "
        "turbines per photo) and print, per point type, recall, precision and median error "
        "of the detections matched within --match-px, and the IoU of the line channels. "
        "Distances are in pixels of the photos resized to the model's input width (320 px "
        "for the shipped model), as the held-out benchmark measures them. Use it to see how "
        "the shipped model (or a fine-tuned one) does on your own photos. With --boxes or "
        "--masks instead of --labels, it prints per class the share of the line heat-maps' "
        "mass inside the (grown) boxes or masks, the share of the masks' skeletons covered "
        "by a line response, the photos where anything is found and the point peaks "
        "outside.",
        formatter_class=DefaultsFormatter)
    labels = v.add_mutually_exclusive_group(required=True)
    labels.add_argument("--labels", type=Path, help="COCO keypoint JSON file")
    labels.add_argument("--boxes", type=Path, metavar="BOXES.csv|BOXES.json",
                        help="boxes: a CSV filename,width,height,class,xmin,ymin,xmax,ymax "
                        "(pixel edges; header optional) or a COCO file with bbox annotations "
                        "(segmentation polygons or RLE masks, where given, outline the turbine instead)")
    labels.add_argument("--masks", type=Path, metavar="DIR",
                        help="masks: a folder of label PNGs <stem>.png of the photos "
                        "<stem>.* in --images-dir (any value > 0 = turbine)")
    v.add_argument("--images-dir", type=Path, required=True,
                   help="folder the labels' file names are relative to (box CSV: also "
                   "DIR/<class>/<filename>)")
    v.add_argument("--grow", type=float, default=0.05,
                   help="with --boxes: each side of a box moved out by this share of its size")
    v.add_argument("--sheet", type=Path, default=None, metavar="SHEET.png",
                   help="with --boxes or --masks: write a contact sheet of the worst photos "
                   "(least line mass inside) with their heat-maps and regions overlaid")
    v.add_argument("--worst", type=positive_int, default=12,
                   help="photos on the contact sheet")
    v.add_argument("--match-px", type=positive_number, default=5.0,
                   help="a detection within this distance of a labelled point matches it")
    v.add_argument("--out", type=Path, default=None, metavar="REPORT.json",
                   help="also write the metrics as JSON (atomically)")
    v.add_argument("--overwrite", action="store_true", help="replace an existing REPORT.json")
    add_model_options(v)
    v.add_argument("--quiet", action="store_true", help="no progress bar")
    return v


def run(args: argparse.Namespace) -> int:
    if args.labels is None:
        return run_regions(args)
    from turbinefit.jobs.evaluate import evaluate_labels

    rep = evaluate_labels(args.labels, args.images_dir, args.model, out=args.out,
                          overwrite=args.overwrite, match_px=args.match_px,
                          progress=not args.quiet, threads=args.threads,
                          detect_options=detect_options(args))
    m = rep.summary
    print(f"{rep.photos} photo(s), {int(m['turbines'])} labelled turbine(s); model {rep.model} "
          f"(thresholds {rep.threshold:.2f}, tips {rep.tip_threshold:.2f}, tip shift "
          f"{rep.tip_shift:g} px, flip averaging {'on' if rep.flip else 'off'}, zoom "
          f"{'on' if rep.zoom else 'off'}); distances in "
          f"pixels of the photos resized to {rep.input_width} px wide, matches within "
          f"{args.match_px:g} px")

    def pct(x: float) -> str:
        return "-" if math.isnan(x) else f"{x:.1%}"

    for name in ("base", "tower_top", "hub", "tips"):
        med = m[f"{name}_median_px"]
        print(f"  {name:10s} labelled {int(m[name + '_labelled']):5d}  recall "
              f"{pct(m[name + '_recall'])} (labelled visible: {pct(m[name + '_recall_in_sight'])}), "
              f"precision {pct(m[name + '_precision'])}, median error "
              f"{'-' if math.isnan(med) else f'{med:.2f} px'}")
    print("  IoU        " + ", ".join(
        f"{k} {'-' if math.isnan(m['iou_' + k]) else format(m['iou_' + k], '.2f')} "
        f"({int(m['iou_' + k + '_photos'])} photos)" for k in ("tower", "nacelle", "blade"))
        + " (over the photos with both ends of each such line labelled)")
    if rep.out is not None:
        print(f"wrote {rep.out}")
    return 0


def run_regions(args: argparse.Namespace) -> int:
    """``evaluate --boxes`` / ``--masks``: the figures per class and overall."""
    from turbinefit.jobs.evaluate import evaluate_regions

    rep = evaluate_regions(args.images_dir, boxes=args.boxes, masks=args.masks,
                           model=args.model, out=args.out, sheet=args.sheet,
                           worst=args.worst, grow=args.grow, overwrite=args.overwrite,
                           progress=not args.quiet, threads=args.threads,
                           detect_options=detect_options(args))
    region = "masks" if args.masks is not None else f"boxes grown by {rep.grow:.0%} a side"
    print(f"{rep.photos} photo(s); model {rep.model} (threshold {rep.threshold:.2f}); "
          f"line mass inside the {region}")

    def fmt(x: float, spec: str) -> str:
        return "-" if math.isnan(x) else format(x, spec)

    for name, m in rep.summary.items():
        print(f"  {name:12s} photos {int(m['photos']):5d}  line mass inside "
              f"{fmt(m['line_mass_inside'], '.3f')}, skeleton covered "
              f"{fmt(m['skeleton_covered'], '.3f')}, found {fmt(m['found'], '.1%')}, point "
              f"peaks outside {int(m['peaks_outside'])} of {int(m['peaks'])}")
    for path in (rep.out, rep.sheet):
        if path is not None:
            print(f"wrote {path}")
    return 0
