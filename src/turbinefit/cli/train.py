"""``turbinefit train``: train the heat-map CNN on rendered photos (and labelled real ones)
with PyTorch (:func:`turbinefit.train.trainer.train`; needs ``turbinefit[train]``)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from turbinefit.cli.common import (
    DefaultsFormatter,
    number,
    option,
    positive_int,
    seed,
    whole_nonneg,
)
from turbinefit.eval.holdout import HELD_OUT_FRACTION
from turbinefit.io.quantities import FRACTION, Quantity, named

#: ``--mil-weight``: the multiple-instance term's weight against the per-pixel losses.
MIL_WEIGHT = Quantity("multiple-instance weight", "", 0.0, 100.0)


def channel_weights(text: str) -> tuple[float, ...]:
    """Seven comma-separated non-negative numbers (one loss weight per heat-map channel)."""
    try:
        w = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 7 comma-separated numbers, got {text!r}"
                                         ) from None
    if len(w) != 7 or not all(x >= 0 and math.isfinite(x) for x in w):
        raise argparse.ArgumentTypeError(f"expected 7 comma-separated numbers >= 0, got {text!r}")
    return w


def fraction(text: str) -> float:
    """A number in [0, 1]."""
    try:
        f = float(text)
    except ValueError:
        f = math.nan
    if not 0.0 <= f <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], got {text!r}")
    return f


def widths(text: str) -> tuple[int, int, int, int]:
    """Four comma-separated positive integers (channel widths of the heat-map CNN)."""
    try:
        w = tuple(int(x) for x in text.split(","))
    except ValueError:
        w = ()
    if len(w) != 4 or not all(x >= 1 for x in w):
        raise argparse.ArgumentTypeError(f"expected 4 comma-separated integers >= 1, got {text!r}")
    return w[0], w[1], w[2], w[3]


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    t: argparse.ArgumentParser = sub.add_parser(
        "train", help=help,
        description="Render (or reuse) a dataset of procedural turbine photos with exact heat-map "
        "targets, train the compact U-Net-like CNN with PyTorch, evaluate on held-out renders "
        "after each epoch, checkpoint (re-running the same command resumes), calibrate the "
        "detection threshold and export MODEL_DIR/model.onnx (use it with --model) and "
        "weights.npz. With --labels, fine-tunes (from the shipped model unless --init) on "
        "real photos labelled with COCO keypoints base, tower_top, hub, tip_1, tip_2, tip_3 "
        "(CVAT / Label Studio export) together with the renders. With --boxes and "
        "--negatives, also on real photos labelled only with boxes and on turbine-free "
        "photos (weak losses; src/turbinefit/models/README.md).",
        formatter_class=DefaultsFormatter)
    t.add_argument("--out", dest="out_dir", metavar="MODEL_DIR", type=Path, required=True,
                   help="output folder: checkpoint.pt, history.csv, model.onnx, weights.npz, "
                   "data/ (required)")
    t.add_argument("--images", dest="n_images", metavar="N", type=positive_int, default=20000,
                   help="rendered training images (with --labels they are trained on together "
                   "with the photos, so the net does not forget the renders)")
    t.add_argument("--val-images", metavar="N", type=whole_nonneg, default=400,
                   help="rendered held-out images")
    t.add_argument("--epochs", metavar="E", type=positive_int, default=10, help="epochs")
    t.add_argument("--batch", type=positive_int, default=16, help="batch size")
    t.add_argument("--lr", type=number, default=2e-3, help="peak learning rate")
    t.add_argument("--seed", type=seed, default=0, help="seed of renders and training")
    t.add_argument("--threads", type=positive_int, default=1,
                   help="PyTorch threads (1 keeps a core for rendering and other work; "
                   "raise it on an idle machine)")
    t.add_argument("--workers", type=positive_int, default=None,
                   help="rendering processes (default: all cores)")
    t.add_argument("--data", dest="data_dir", type=Path, default=None,
                   help="dataset folder to render into / reuse (default: MODEL_DIR/data)")
    t.add_argument("--add-data", action="append", type=Path, default=None, metavar="FOLDER",
                   help="a training set rendered before (e.g. OTHER/data/train-n16384-s9-x2) to "
                   "train on as well; repeat for several")
    t.add_argument("--labels", type=Path, default=None, help="COCO keypoint JSON of real photos")
    t.add_argument("--images-dir", type=Path, default=None,
                   help="folder the COCO file_name entries are relative to")
    t.add_argument("--boxes", action="append", type=Path, default=None, metavar="BOXES",
                   help="real photos labelled with boxes (a CSV filename,width,height,class,"
                   "xmin,ymin,xmax,ymax or a COCO JSON with bbox, as evaluate --boxes reads) "
                   "to train on with weak losses: every channel zero outside each box grown by "
                   "--box-margin, some line along each box; repeat for several")
    t.add_argument("--boxes-images", type=Path, default=None, metavar="DIR",
                   help="folder of the --boxes photos (DIR/filename or DIR/class/filename)")
    t.add_argument("--negatives", action="append", type=Path, default=None, metavar="DIR",
                   help="a folder of turbine-free real photos (roads, fields, roofs, pylons) to "
                   "train on with every channel zero; repeat for several")
    t.add_argument("--hold-out", type=option(named(FRACTION, "held-out fraction")),
                   default=HELD_OUT_FRACTION, metavar="F",
                   help="leave out of --boxes and --negatives the photos whose original's name "
                   "hashes below F (turbinefit.eval.holdout; what benchmarks/bench_real.py "
                   "measures on); 0 trains on all")
    t.add_argument("--real-batch", type=positive_int, default=8, metavar="N",
                   help="--boxes / --negatives photos per step, beside --batch renders")
    t.add_argument("--box-margin", type=option(named(FRACTION, "box margin")), default=0.1,
                   metavar="F",
                   help="share of a box's size it is grown by on each side before the outside "
                   "counts as zero (at least 2 heat-map px)")
    t.add_argument("--mil-weight", type=option(MIL_WEIGHT), default=0.05, metavar="W",
                   help="weight of the term asking for some line in each strip of a box")
    t.add_argument("--mil-strips", type=positive_int, default=3, metavar="K",
                   help="strips a box is cut into across its long side, each asked for line")
    t.add_argument("--zero-attached", action="store_true",
                   help="also count as zero the lines the starting net draws outside a box "
                   "that run into it (by default they are left unknown: a tower below a boxed "
                   "blade, blades a box leaves out)")
    t.add_argument("--average-with", type=Path, default=None, metavar="NPZ",
                   help="average the trained weights with these (a net of the same "
                   "architecture, e.g. the one fine-tuned from) before calibrating and "
                   "exporting; the checkpoint keeps the trained ones (how the shipped net "
                   "was made: src/turbinefit/models/README.md)")
    t.add_argument("--average-weight", type=option(named(FRACTION, "average weight")),
                   default=0.5, metavar="W", help="the trained weights' share of that average")
    t.add_argument("--tip-threshold", type=option(named(FRACTION, "tip threshold")),
                   default=None, metavar="T",
                   help="the blade tips' threshold (default: the best F1 on the validation "
                   "renders; the tip shift is measured there either way)")
    t.add_argument("--init", type=Path, default=None,
                   help="weights.npz to start from (default with --labels, --boxes or "
                   "--negatives: the shipped model)")
    t.add_argument("--input-scale", type=int, choices=(1, 2), default=2,
                   help="the net's input photos are this many times its 160x120 heat-maps "
                   "(2: 320x240 photos, as the shipped model; --init weights of a 1 net are lifted "
                   "to 2; fine-tuning the shipped model on --labels keeps its scale)")
    t.add_argument("--pos-weight", type=number, default=2.0,
                   help="extra loss weight of pixels on the turbine (1 + w x target)")
    t.add_argument("--channel-weights", type=channel_weights, default=(1.0,) * 7,
                   metavar="W,W,W,W,W,W,W",
                   help="loss weight of each channel (base, tower_top, hub, tip, line_tower, "
                   "line_nacelle, line_blade); the shipped model's last fine-tuning used "
                   "1,1,1,3,1,5,2")
    t.add_argument("--widths", type=widths, default=None, metavar="W1,W2,W3,W4",
                   help="channel widths of the net at 1/2, 1/4, 1/8, 1/16 of the heat-map "
                   "resolution (default: those of --init, else 32,48,64,112); --init weights "
                   "of a narrower net are widened so that training starts from their heat-maps")
    t.add_argument("--fine", type=whole_nonneg, default=None, metavar="C",
                   help="channels of a fine branch that corrects the heat-maps at their own "
                   "resolution from the full-resolution features (input scale 2; default: as "
                   "--init, else none); --init weights without one get one that starts out "
                   "adding nothing")
    t.add_argument("--closeups", type=fraction, default=0.3, metavar="F",
                   help="share of the rendered views that are close-ups of one blade or the "
                   "tower filling the frame")
    t.add_argument("--max-steps", type=positive_int, default=None,
                   help="stop after this many steps (smoke tests)")
    t.add_argument("--quiet", action="store_true", help="no progress bars")
    return t


def run(args: argparse.Namespace) -> int:
    from turbinefit.errors import InputError

    try:
        import torch  # noqa: F401
    except ImportError:
        raise InputError("training needs PyTorch: pip install 'turbinefit[train]' "
                         "(or torch==2.13.0 for the CPU build)", field="train") from None
    from turbinefit.train.trainer import TrainConfig, train

    cfg = TrainConfig(out_dir=args.out_dir, n_images=args.n_images, val_images=args.val_images,
                      epochs=args.epochs, batch=args.batch, lr=args.lr, seed=args.seed,
                      threads=args.threads, workers=args.workers, data_dir=args.data_dir,
                      add_data=tuple(args.add_data or ()),
                      labels=args.labels, images_dir=args.images_dir, init=args.init,
                      max_steps=args.max_steps, input_scale=args.input_scale,
                      pos_weight=args.pos_weight, channel_weights=args.channel_weights,
                      widths=args.widths, fine=args.fine, closeup_fraction=args.closeups,
                      boxes=tuple(args.boxes or ()), boxes_images=args.boxes_images,
                      negatives=tuple(args.negatives or ()), hold_out=args.hold_out,
                      real_batch=args.real_batch, box_margin=args.box_margin,
                      mil_weight=args.mil_weight, mil_strips=args.mil_strips,
                      zero_attached=args.zero_attached, average_with=args.average_with,
                      average_weight=args.average_weight, tip_threshold=args.tip_threshold)
    res = train(cfg, progress=not args.quiet, log=print)
    print(f"wrote {res.model} (threshold {res.threshold:.2f}, {res.parameters:,} parameters)")
    return 0
