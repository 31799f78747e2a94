"""The ``turbinefit`` command line: a thin layer over :mod:`turbinefit.pipeline`.

Every command prints one clear line and exits with status 2 on bad input (no traceback);
heavy modules are imported only by the command that needs them.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from turbinefit.detect import DetectOptions

EXIT_BAD_INPUT = 2

_EPILOG = """\
Flight folder (input of fit and track, output of simulate):
  camera.yaml                 ROS/OpenCV camera_info (image size, camera_matrix, plumb_bob)
  keyframes.txt               TUM 'timestamp tx ty tz qx qy qz qw', initial world_T_cam
  odometry.txt                optional TUM; its consecutive relative poses are the
                              pairwise measurements (default: those of keyframes.txt)
  turbine.yaml                initial turbine parameters (metres, radians)
  heatmaps/<t %.6f>.npy       float32 (7, H, W): point_base, point_tower_top, point_hub,
                              point_blade_tip, line_tower, line_nacelle, line_blade
  images/<t %.6f>.png|.jpg    optional photos; fit detects heat-maps from them when
                              heatmaps/ is absent (or with --from-images)
  groundtruth.txt, turbine_groundtruth.yaml   optional ground truth
  simulation.yaml             written by simulate (its settings); not read by fit
"""


def _whole_number(text: str, minimum: int, why: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < minimum:
        raise argparse.ArgumentTypeError(f"{why}, got {v}")
    return v


def _positive_int(text: str) -> int:
    return _whole_number(text, 1, "must be at least 1")


def _seed(text: str) -> int:
    return _whole_number(text, 0, "must be a non-negative whole number")


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def _positive_float(text: str) -> float:
    v = _float(text)
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return v


def _tip_shift(text: str) -> float:
    from turbinefit.heatmaps.model_info import TIP_SHIFT_TAPER_PX, valid_tip_shift

    v = _float(text)
    if not valid_tip_shift(v):
        raise argparse.ArgumentTypeError(
            f"must be a number of pixels between -{TIP_SHIFT_TAPER_PX:g} and "
            f"{TIP_SHIFT_TAPER_PX:g}, got {text!r}")
    return v


def _channel_weights(text: str) -> tuple[float, ...]:
    """Seven comma-separated non-negative numbers (one loss weight per heat-map channel)."""
    try:
        w = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 7 comma-separated numbers, got {text!r}"
                                         ) from None
    if len(w) != 7 or not all(x >= 0 and math.isfinite(x) for x in w):
        raise argparse.ArgumentTypeError(f"expected 7 comma-separated numbers >= 0, got {text!r}")
    return w


def _widths(text: str) -> tuple[int, int, int, int]:
    """Four comma-separated positive integers (channel widths of the heat-map CNN)."""
    try:
        w = tuple(int(x) for x in text.split(","))
    except ValueError:
        w = ()
    if len(w) != 4 or not all(x >= 1 for x in w):
        raise argparse.ArgumentTypeError(f"expected 4 comma-separated integers >= 1, got {text!r}")
    return w[0], w[1], w[2], w[3]


class _DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends an option's default to its help, unless the help already says it or the
    default is None or a flag's False (nothing worth saying)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if action.default is None or action.default is False or "(default" in text:
            return text
        return super()._get_help_string(action) or text


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="turbinefit",
        description="Simultaneous drone localisation and wind-turbine model fitting from CNN "
        "heat-maps (Moolan-Feroze et al., IROS 2019).",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=_version())
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    # ---- simulate ---------------------------------------------------------------
    s = sub.add_parser(
        "simulate", help="write a simulated flight folder with ground truth",
        description="Simulate an inspection flight around a realistic turbine: ground-truth "
        "poses and turbine, heat-maps as a CNN would give them, drifting GPS/IMU poses and a "
        "noisy initial turbine. Writes a flight folder (see `turbinefit --help`).",
        formatter_class=_DefaultsFormatter)
    s.add_argument("out_dir", metavar="OUT_DIR", type=Path, nargs="?",
                   help="flight folder to create")
    s.add_argument("--keyframes", type=_positive_int, default=200, help="number of keyframes")
    s.add_argument("--seed", type=_seed, default=0,
                   help="random seed, >= 0 (same seed, same flight)")
    s.add_argument("--preset", default="default",
                   help="simulation preset: default, noiseless, exact, hard, distorted "
                   "(see --list-presets)")
    s.add_argument("--turbine", default=None,
                   help="turbine preset name, or 'random' (default: the preset's)")
    s.add_argument("--width", type=_positive_int, default=None, help="heat-map width [px]")
    s.add_argument("--height", type=_positive_int, default=None, help="heat-map height [px]")
    s.add_argument("--drift-m", type=_float, default=None,
                   help="order of the GPS/IMU position drift over the flight [m]")
    s.add_argument("--drift-deg", type=_float, default=None,
                   help="order of the GPS/IMU orientation drift over the flight [deg]")
    s.add_argument("--turbine-noise", type=_float, default=None,
                   help="scale of the initial turbine's noise (1 = the default sigmas "
                   "1 m, 1 m, 2 m, 5 deg, 0.5 m, 5 deg, 2 m; 0 = exact)")
    s.add_argument("--heatmap-noise", type=_float, default=None,
                   help="std. dev. of additive pixel noise on the heat-maps")
    s.add_argument("--second-turbine", action="store_true",
                   help="add a second turbine in view (false responses)")
    s.add_argument("--images", action="store_true",
                   help="also render a photo of every keyframe into images/ (procedural "
                   "scene from the seed)")
    s.add_argument("--list-presets", action="store_true", help="list presets and exit")
    s.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it exists (only if it holds nothing but a flight)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")

    # ---- fit --------------------------------------------------------------------
    from turbinefit.solver.config import FitConfig

    dflt = FitConfig()
    f = sub.add_parser(
        "fit", help="optimise poses and turbine of a flight folder",
        description=(
            "Refine every keyframe pose and the 7 turbine parameters with Levenberg-Marquardt\n"
            "on the heat-maps and the GPS/IMU relative poses: first two correspondence\n"
            "stages (align: the trajectory moves nearly rigidly; match: each keyframe), then\n"
            "the configured cost.\n\n"
            "Writes OUT_DIR/keyframes.txt (TUM), turbine.yaml, summary.json (costs,\n"
            "iterations, timings, and errors before/after when ground truth exists),\n"
            "config.yaml (the resolved options) and plots. Every option of\n"
            "turbinefit.FitConfig can be set in a --config YAML file; command-line options\n"
            "override it."),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    f.add_argument("flight_dir", metavar="FLIGHT_DIR", type=Path, help="flight folder to fit")
    _add_flight_job_options(f, dflt, "paper-best (default), all-interp, all-corr, paper-worst, "
                            "corr-normal, pose-only, turbine-only")
    f.add_argument("--no-warmup", dest="warmup", action="store_const", const=False,
                   default=None, help="skip the correspondence warm-up stages (align, match) "
                   "and start with the configured cost")
    _add_photo_options(f, "detect the heat-maps from images/")
    f.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it exists (only if it holds nothing but fit outputs)")
    f.add_argument("--quiet", action="store_true", help="no progress bar or summary")

    # ---- track ------------------------------------------------------------------
    from turbinefit.solver.tracker import TrackerConfig

    tdf = TrackerConfig()
    k = sub.add_parser(
        "track", help="replay a flight keyframe by keyframe (in-flight tracking)",
        description=(
            "Successive estimation as the drone flies: keyframes are fed in time order to a\n"
            "fixed-lag smoother that refines the last --window keyframe poses and the turbine\n"
            "after each one and folds older keyframes into a prior (marginalisation). A live\n"
            "status line shows the keyframe, its update time and the current turbine.\n\n"
            "Writes OUT_DIR/causal.txt (TUM: each keyframe's estimate when it arrived),\n"
            "keyframes.txt and turbine.yaml (the final estimates, as fit writes them),\n"
            "latency.csv (timestamp,latency_ms), config.yaml, summary.json (latency figures;\n"
            "errors of the causal and final estimates when ground truth exists) and plots\n"
            "(latency.png, errors.png, scene.png). Fit options as for `turbinefit fit`."),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    k.add_argument("flight_dir", metavar="FLIGHT_DIR", type=Path, help="flight folder to replay")
    k.add_argument("--window", type=_whole_nonneg, default=tdf.window, metavar="K",
                   help=f"keyframes in the sliding window, >= 2; 0 keeps them all (the batch "
                   f"problem, per-keyframe work grows) (default: {tdf.window})")
    k.add_argument("--rounds", type=_positive_int, default=tdf.rounds,
                   help=f"correspondence rounds per keyframe (default: {tdf.rounds})")
    k.add_argument("--iterations", type=_positive_int, default=tdf.iterations,
                   help=f"LM iterations per round (default: {tdf.iterations})")
    k.add_argument("--marginal-terms", choices=["corr", "same"], default=tdf.marginal_terms,
                   help="how a keyframe leaving the window is linearised into the prior: as "
                   "correspondences (valid over the whole search range) or as the configured "
                   f"cost (default: {tdf.marginal_terms})")
    k.add_argument("--no-prior", action="store_true",
                   help="no start-up prior on the turbine (default: a prior around the initial "
                   "turbine, removed once the images outweigh it)")
    _add_flight_job_options(k, dflt, "paper-best (default), all-interp, all-corr, "
                            "paper-worst, corr-normal, pose-only", batch=False)
    _add_photo_options(k, "detect each keyframe's heat-maps from images/ as it arrives")
    k.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it exists (only if it holds nothing but track "
                   "outputs)")
    k.add_argument("--quiet", action="store_true", help="no status line or summary")

    # ---- experiment / report ----------------------------------------------------
    e = sub.add_parser(
        "experiment", help="Monte Carlo studies of the paper (simulated flights)",
        description=(
            "Run (or resume) a Monte Carlo study: many simulated flights, each fitted under\n"
            "the study's configurations, one row per (flight, configuration) in\n"
            "OUT_DIR/rows.csv, with sweep.yaml (the resolved sweep), PNG figures, summary.json\n"
            "and report.md (medians and 90th percentiles, figures embedded).\n\n"
            "  unary    the four unary configurations (paper Fig. 4)\n"
            "  joint    joint vs pose-only (Fig. 5)\n"
            "  turbine  recovery of the turbine parameters (Fig. 6)\n"
            "  roll     a wrong blade rotation: false roll of pose-only (Fig. 7)\n"
            "  basin    success rate against the size of the initial errors\n"
            "  quality  heat-map faults, blur and a second turbine in view\n"
            "  length   flight length (25-400 keyframes)\n"
            "  all      all of them, into OUT_DIR/<study>/\n\n"
            "Re-running the same command resumes without redoing finished rows. Flights run\n"
            "on all local cores, or on a Ray cluster with --backend ray (address from\n"
            "RAY_ADDRESS; needs `pip install ray`)."),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    e.add_argument("study", metavar="STUDY", choices=["unary", "joint", "turbine", "roll",
                                                        "basin", "quality", "length", "all"],
                   help="unary, joint, turbine, roll, basin, quality, length or all")
    e.add_argument("--flights", type=_positive_int, default=None,
                   help="simulated flights (default: the study's: 200 for unary, joint and "
                   "turbine, 20 for roll, 120 for basin and quality, 60 for length)")
    e.add_argument("--keyframes", type=_positive_int, default=100, help="keyframes per flight "
                   "(default: 100; the length study draws 25-400)")
    e.add_argument("--seed", type=_seed, default=0, help="sweep seed (default: 0)")
    e.add_argument("--config", type=Path, default=None,
                   help="a sweep YAML (the sweep.yaml of a run) instead of the study's; "
                   "--flights, --keyframes and --seed then do not apply")
    e.add_argument("--out", dest="out_dir", metavar="OUT_DIR", type=Path, default=None,
                   help="output folder (default: experiments/STUDY)")
    e.add_argument("--backend", choices=["local", "ray"], default="local",
                   help="where flights run (default: local processes)")
    e.add_argument("--workers", type=_positive_int, default=None,
                   help="local processes (default: all cores)")
    e.add_argument("--quiet", action="store_true", help="no progress bar or summary")

    r = sub.add_parser(
        "report", help="rebuild an experiment's figures and report from its rows",
        description="Rebuild the figures, summary.json and report.md of an experiment folder "
        "(or of every study folder below it, as `experiment all` writes) from its stored "
        "rows.csv and sweep.yaml, without running anything.")
    r.add_argument("folder", metavar="DIR", type=Path, help="experiment folder")

    # ---- detect -----------------------------------------------------------------
    d = sub.add_parser(
        "detect", help="heat-maps of photos with the CNN (onnxruntime)",
        description="Run the heat-map CNN on photos (JPEG/PNG, any size). For each photo writes "
        "OUT_DIR/<stem>.npy, float32 (7, H, W) at the photo's own size (channels point_base, "
        "point_tower_top, point_hub, point_blade_tip, line_tower, line_nacelle, line_blade; "
        "values in [0, 1]), and OUT_DIR/<stem>.png, the photo with the heat-maps overlaid "
        "(base red, tower top orange, hub yellow, tips magenta, tower cyan, nacelle green, "
        "blades blue). OUT_DIR is written atomically.",
        formatter_class=_DefaultsFormatter)
    d.add_argument("inputs", metavar="IMAGES_OR_DIRS", type=Path, nargs="+",
                   help="photos, or folders of photos (not recursive)")
    d.add_argument("--out", dest="out_dir", metavar="OUT_DIR", type=Path, required=True,
                   help="output folder")
    d.add_argument("--model", type=Path, default=None,
                   help="ONNX model (default: the shipped model)")
    d.add_argument("--threads", type=_positive_int, default=None,
                   help="photos detected at once, one inference thread each "
                   "(default: one per core)")
    _add_detect_options(d)
    d.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it holds only detect outputs")
    d.add_argument("--quiet", action="store_true", help="no progress bar or summary")

    # ---- evaluate ---------------------------------------------------------------
    v = sub.add_parser(
        "evaluate", help="detection metrics of the CNN on labelled photos (COCO keypoints)",
        description="Run the heat-map CNN on photos labelled with COCO keypoints (base, "
        "tower_top, hub, tip_1..3, as CVAT and Label Studio export them; any number of "
        "turbines per photo) and print, per point type, recall, precision and median error "
        "of the detections matched within --match-px, and the IoU of the line channels. "
        "Distances are in pixels of the photos resized to the model's input width (320 px "
        "for the shipped model), as the held-out benchmark measures them. Use it to see how "
        "the shipped model (or a fine-tuned one) does on your own photos.",
        formatter_class=_DefaultsFormatter)
    v.add_argument("--labels", type=Path, required=True, help="COCO keypoint JSON file")
    v.add_argument("--images-dir", type=Path, required=True,
                   help="folder the COCO file_name entries are relative to")
    v.add_argument("--model", type=Path, default=None,
                   help="ONNX model (default: the shipped model)")
    v.add_argument("--match-px", type=_positive_float, default=5.0,
                   help="a detection within this distance of a labelled point matches it")
    v.add_argument("--out", type=Path, default=None, metavar="REPORT.json",
                   help="also write the metrics as JSON (atomically)")
    v.add_argument("--overwrite", action="store_true", help="replace an existing REPORT.json")
    v.add_argument("--threads", type=_positive_int, default=None,
                   help="photos detected at once, one inference thread each "
                   "(default: one per core)")
    _add_detect_options(v)
    v.add_argument("--quiet", action="store_true", help="no progress bar")

    # ---- train ------------------------------------------------------------------
    t = sub.add_parser(
        "train", help="train the heat-map CNN on rendered photos (needs turbinefit[train])",
        description="Render (or reuse) a dataset of procedural turbine photos with exact heat-map "
        "targets, train the compact U-Net-like CNN with PyTorch, evaluate on held-out renders "
        "after each epoch, checkpoint (re-running the same command resumes), calibrate the "
        "detection threshold and export MODEL_DIR/model.onnx (use it with --model) and "
        "weights.npz. With --labels, fine-tunes (from the shipped model unless --init) on "
        "real photos labelled with COCO keypoints base, tower_top, hub, tip_1, tip_2, tip_3 "
        "(CVAT / Label Studio export) together with the renders.",
        formatter_class=_DefaultsFormatter)
    t.add_argument("--out", dest="out_dir", metavar="MODEL_DIR", type=Path, required=True,
                   help="output folder: checkpoint.pt, history.csv, model.onnx, weights.npz, "
                   "data/ (required)")
    t.add_argument("--images", dest="n_images", metavar="N", type=_positive_int, default=20000,
                   help="rendered training images (with --labels they are trained on together "
                   "with the photos, so the net does not forget the renders)")
    t.add_argument("--val-images", metavar="N", type=_whole_nonneg, default=400,
                   help="rendered held-out images")
    t.add_argument("--epochs", metavar="E", type=_positive_int, default=10, help="epochs")
    t.add_argument("--batch", type=_positive_int, default=16, help="batch size")
    t.add_argument("--lr", type=_float, default=2e-3, help="peak learning rate")
    t.add_argument("--seed", type=_seed, default=0, help="seed of renders and training")
    t.add_argument("--threads", type=_positive_int, default=1,
                   help="PyTorch threads (1 keeps a core for rendering and other work; "
                   "raise it on an idle machine)")
    t.add_argument("--workers", type=_positive_int, default=None,
                   help="rendering processes (default: all cores)")
    t.add_argument("--data", dest="data_dir", type=Path, default=None,
                   help="dataset folder to render into / reuse (default: MODEL_DIR/data)")
    t.add_argument("--add-data", action="append", type=Path, default=None, metavar="FOLDER",
                   help="a training set rendered before (e.g. OTHER/data/train-n16384-s9-x2) to "
                   "train on as well; repeat for several")
    t.add_argument("--labels", type=Path, default=None, help="COCO keypoint JSON of real photos")
    t.add_argument("--images-dir", type=Path, default=None,
                   help="folder the COCO file_name entries are relative to")
    t.add_argument("--init", type=Path, default=None,
                   help="weights.npz to start from (default with --labels: the shipped model)")
    t.add_argument("--input-scale", type=int, choices=(1, 2), default=2,
                   help="the net's input photos are this many times its 160x120 heat-maps "
                   "(2: 320x240 photos, as the shipped model; --init weights of a 1 net are lifted "
                   "to 2; fine-tuning the shipped model on --labels keeps its scale)")
    t.add_argument("--pos-weight", type=_float, default=2.0,
                   help="extra loss weight of pixels on the turbine (1 + w x target)")
    t.add_argument("--channel-weights", type=_channel_weights, default=(1.0,) * 7,
                   metavar="W,W,W,W,W,W,W",
                   help="loss weight of each channel (base, tower_top, hub, tip, line_tower, "
                   "line_nacelle, line_blade); the shipped model's last fine-tuning used "
                   "1,1,1,3,1,5,2")
    t.add_argument("--widths", type=_widths, default=None, metavar="W1,W2,W3,W4",
                   help="channel widths of the net at 1/2, 1/4, 1/8, 1/16 of the heat-map "
                   "resolution (default: those of --init, else 32,48,64,112); --init weights "
                   "of a narrower net are widened so that training starts from their heat-maps")
    t.add_argument("--fine", type=_whole_nonneg, default=None, metavar="C",
                   help="channels of a fine branch that corrects the heat-maps at their own "
                   "resolution from the full-resolution features (input scale 2; default: as "
                   "--init, else none); --init weights without one get one that starts out "
                   "adding nothing")
    t.add_argument("--max-steps", type=_positive_int, default=None,
                   help="stop after this many steps (smoke tests)")
    t.add_argument("--quiet", action="store_true", help="no progress bars")
    return p


def _add_flight_job_options(parser: argparse.ArgumentParser, dflt: Any, presets: str,
                            batch: bool = True) -> None:
    """--out, --config | --preset and the fit options (``fit`` and ``track``)."""
    parser.add_argument("--out", dest="out_dir", metavar="OUT_DIR", type=Path, required=True,
                        help="output folder (written atomically; never the input folder)")
    base = parser.add_mutually_exclusive_group()
    base.add_argument("--config", type=Path, default=None,
                      help="YAML file of fit options (e.g. a previous fit's config.yaml)")
    base.add_argument("--preset", default=None, help=f"named configuration: {presets}")
    _add_fit_options(parser, dflt, batch)


def _add_photo_options(parser: argparse.ArgumentParser, what: str) -> None:
    """--from-images, --model, --no-flip, --tip-shift, --no-zoom, --no-plots (``fit`` and
    ``track``)."""
    parser.add_argument("--from-images", action="store_true", default=None,
                        help=f"{what} even if heatmaps/ exists (default: only when heatmaps/ "
                        "is absent)")
    parser.add_argument("--model", type=Path, default=None,
                        help="ONNX heat-map model for detection (default: the shipped one)")
    _add_detect_options(parser)
    parser.add_argument("--no-plots", action="store_true", help="skip the figures")


def _add_detect_options(parser: argparse.ArgumentParser) -> None:
    """--no-flip, --tip-shift and --no-zoom: args.flip and args.zoom are False when given,
    else None; args.tip_shift a number when given, else None (the model's metadata decides
    what is None; :func:`_detect_options` gathers them)."""
    parser.add_argument("--no-flip", dest="flip", action="store_false", default=None,
                        help="run the CNN once per photo instead of averaging its maps with "
                        "those of the mirror image (faster, less accurate; default: as the "
                        "model's metadata says, flip averaging for the shipped model)")
    parser.add_argument("--tip-shift", type=_tip_shift, default=None, metavar="PX",
                        help="move the blade-tip heat-map this many pixels (at the model's "
                        "input width) outward from the detected hub, undoing the net's "
                        "inboard bias; 0 keeps the net's own (default: the value "
                        "calibrated for the model, turbinefit.tip_shift_px in its "
                        "metadata)")
    parser.add_argument("--no-zoom", dest="zoom", action="store_false", default=None,
                        help="no second pass of the CNN on an enlarged crop around small "
                        "turbines to find their blade tips (faster on far views, fewer tips "
                        "found; default: as the model's metadata says, zoom for the shipped "
                        "model)")


def _detect_options(args: argparse.Namespace) -> DetectOptions:
    """The :class:`~turbinefit.detect.DetectOptions` of :func:`_add_detect_options`."""
    from turbinefit.detect import DetectOptions

    return DetectOptions(flip=args.flip, tip_shift=args.tip_shift, zoom=args.zoom)


def _add_fit_options(parser: argparse.ArgumentParser, dflt: Any, batch: bool = True) -> None:
    """The options of :class:`FitConfig`; ``batch=False`` (``track``) leaves out those the
    tracker does not use (turbine-only mode, the batch fit's iteration and round limits)."""
    def opt(flag: str, name: str, help: str, **kw: Any) -> None:
        if not batch and name in ("max_iterations", "max_rounds"):
            return
        parser.add_argument(flag, dest=name, default=None,
                            help=f"{help} (default: {getattr(dflt, name)})", **kw)

    opt("--mode", "mode", "what to optimise",
        choices=["joint", "pose", "turbine"] if batch else ["joint", "pose"])
    opt("--points", "points", "unary cost of the 6 model points",
        choices=["interp", "corr", "none"])
    opt("--lines", "lines", "unary cost of the line samples", choices=["interp", "corr", "none"])
    opt("--samples-per-line", "samples_per_line", "samples on each model line",
        type=_positive_int)
    opt("--line-sampling", "line_sampling", "where line samples go: the visible part of each "
        "line per keyframe, or uniform along it", choices=["visible", "uniform"])
    opt("--lambda-points", "lambda_points", "weight lambda_P of the point term", type=_float)
    opt("--lambda-lines", "lambda_lines", "weight lambda_L of the line term", type=_float)
    opt("--lambda-pair", "lambda_pair", "weight lambda of the pairwise term", type=_float)
    opt("--pixel-sigma", "pixel_sigma", "correspondence noise [px]", type=_float)
    opt("--line-residual", "line_residual", "residual of line correspondences: 2-D distance to "
        "the found point (the paper's) or distance along the search normal",
        choices=["point", "normal"])
    opt("--pair-frame", "pair_frame", "frame of the relative translation: measured (GPS/IMU "
        "attitude: right for GPS positions) or estimated (the paper's: right for body-frame "
        "odometry such as VIO)", choices=["measured", "estimated"])
    opt("--pair-sigma-t", "pair_sigma_t", "relative-pose translation std. dev. [m]",
        type=_float)
    opt("--pair-sigma-t-per-m", "pair_sigma_t_per_m",
        "added relative translation std. dev. per metre of step [m/m]", type=_float)
    opt("--pair-sigma-r", "pair_sigma_r_deg", "relative-pose rotation std. dev. [deg]",
        type=_float)
    opt("--heatmap-floor", "heatmap_floor", "background floor eps of the -log heat-map cost",
        type=_float)
    opt("--robust", "robust", "robust loss on the image terms", choices=["none", "huber", "cauchy"])
    opt("--robust-scale", "robust_scale", "robust loss scale (whitened units)", type=_float)
    opt("--gauge", "gauge", "hold the first pose, or weak absolute GPS position priors",
        choices=["first", "gps"])
    opt("--gps-sigma", "gps_sigma", "std. dev. of the GPS priors [m]", type=_float)
    opt("--max-iterations", "max_iterations", "LM iterations per round", type=_positive_int)
    opt("--max-rounds", "max_rounds", "rounds (correspondences re-found after each)",
        type=_positive_int)


def _whole_nonneg(text: str) -> int:
    return _whole_number(text, 0, "must be >= 0")


def _version() -> str:
    from turbinefit import __version__

    return f"turbinefit {__version__}"


_FIT_OPTIONS = ("mode", "points", "lines", "samples_per_line", "line_sampling", "lambda_points",
                "lambda_lines", "lambda_pair", "pixel_sigma", "line_residual", "pair_frame",
                "pair_sigma_t", "pair_sigma_t_per_m", "pair_sigma_r_deg", "heatmap_floor",
                "robust", "robust_scale", "gauge", "gps_sigma", "warmup", "max_iterations",
                "max_rounds")


def _resolve_fit_config(args: argparse.Namespace) -> Any:
    import dataclasses

    from turbinefit.errors import InputError
    from turbinefit.pipeline import load_fit_config
    from turbinefit.solver.config import PRESETS, FitConfig

    cfg = FitConfig()
    if args.config is not None:
        cfg = load_fit_config(args.config)
    if args.preset is not None:
        if args.preset not in PRESETS:
            raise InputError(f"unknown preset {args.preset!r} (choose from "
                             f"{', '.join(PRESETS)})", field="--preset")
        cfg = PRESETS[args.preset]
    overrides = {k: getattr(args, k) for k in _FIT_OPTIONS if getattr(args, k, None) is not None}
    try:
        return dataclasses.replace(cfg, **overrides)
    except ValueError as exc:
        raise InputError(str(exc), field="fit options") from None


def _cmd_fit(args: argparse.Namespace) -> int:
    from turbinefit.pipeline import fit_folder

    cfg = _resolve_fit_config(args)
    bar = None
    progress = None
    if not args.quiet:
        from tqdm import tqdm

        # disable=None: no bar when stderr is not a terminal (logs, CI)
        bar = tqdm(desc="fit", unit="it", file=sys.stderr, dynamic_ncols=True, leave=False,
                   disable=None)

        def progress(rec: Any) -> None:
            assert bar is not None
            bar.update(1)
            bar.set_postfix_str(f"{rec.stage} round {rec.round} cost {rec.cost:.6g}")

    try:
        report = fit_folder(args.flight_dir, args.out_dir, cfg, plots=not args.no_plots,
                            overwrite=args.overwrite, progress=progress,
                            config_path=args.config, from_images=args.from_images,
                            model=args.model, detect_progress=not args.quiet,
                            detect_options=_detect_options(args))
    finally:
        if bar is not None:
            bar.close()
    if not args.quiet:
        _print_fit_summary(report)
    return 0


def _print_fit_summary(report: Any) -> None:
    r = report.result
    t = report.timings
    print(f"fitted {len(r.world_T_cam)} keyframes in {t['solve']:.2f} s "
          f"(load {t['load']:.2f} s, total {t['total']:.2f} s): {r.iterations} iterations, "
          f"{r.rounds} round(s), {r.termination}")
    print(f"cost {r.initial_cost:.6g} -> {r.final_cost:.6g}")
    th = r.turbine
    print(f"turbine: base ({th.base_x:.2f}, {th.base_y:.2f}) m, tower {th.tower_height:.2f} m, "
          f"heading {_deg(th.heading):.2f} deg, nacelle {th.nacelle_length:.2f} m, "
          f"blade rotation {_deg(th.blade_rotation):.2f} deg, blades {th.blade_length:.2f} m")
    if report.before is not None and report.after is not None:
        b, a = report.before, report.after
        print(f"position error     {b.position_error_m:8.3f} m   -> {a.position_error_m:8.3f} m")
        print(f"orientation error  {b.orientation_error_deg:8.3f} deg -> "
              f"{a.orientation_error_deg:8.3f} deg")
        print(f"model point error  {b.model_point_error_m:8.3f} m   -> "
              f"{a.model_point_error_m:8.3f} m")
    print(f"wrote {report.out_dir}")


def _deg(x: float) -> float:
    import math

    return math.degrees(x)


def _sim_config(args: argparse.Namespace) -> Any:
    import dataclasses
    import math

    from turbinefit.errors import InputError
    from turbinefit.sim.noise import DEFAULT_TURBINE_SIGMA
    from turbinefit.sim.render import HeatmapNoise
    from turbinefit.sim.scenario import PRESETS

    if args.preset not in PRESETS:
        raise InputError(f"unknown preset {args.preset!r} (choose from {', '.join(PRESETS)})",
                         field="--preset")
    base = PRESETS[args.preset]
    over: dict[str, Any] = {"n_keyframes": args.keyframes, "seed": args.seed}
    for name, key in (("width", "width"), ("height", "height"), ("drift_m", "drift_pos_m"),
                      ("drift_deg", "drift_rot_deg"), ("turbine", "turbine")):
        if getattr(args, name) is not None:
            over[key] = getattr(args, name)
    if args.turbine_noise is not None:
        over["turbine_sigma"] = tuple(args.turbine_noise * s for s in DEFAULT_TURBINE_SIGMA)
    if args.heatmap_noise is not None:
        over["heatmap_noise"] = dataclasses.replace(base.heatmap_noise,
                                                    pixel_sigma=args.heatmap_noise)
    if args.second_turbine:
        over["second_turbine"] = True
    for key in ("drift_pos_m", "drift_rot_deg"):
        if key in over and not (math.isfinite(over[key]) and over[key] >= 0):
            raise InputError(f"must be a non-negative number, got {over[key]}", field=key)
    # sim.noise / sim.render would fail (turbine) or silently ignore (heat-maps) these
    for flag, value in (("--turbine-noise", args.turbine_noise),
                        ("--heatmap-noise", args.heatmap_noise)):
        if value is not None and not (math.isfinite(value) and value >= 0):
            raise InputError(f"must be a non-negative number, got {value}", field=flag)
    try:
        cfg = dataclasses.replace(base, **over)
        HeatmapNoise(**dataclasses.asdict(cfg.heatmap_noise))
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), field="simulate options") from None
    return cfg


def _sim_presets_text() -> str:
    from turbinefit.sim.scenario import PRESETS
    from turbinefit.sim.turbines import PRESETS as TURBINES

    lines = ["simulation presets: " + ", ".join(PRESETS),
             "turbine presets:    " + ", ".join([*TURBINES, "random"])]
    return "\n".join(lines)


def _cmd_simulate(args: argparse.Namespace) -> int:
    from turbinefit.pipeline import simulate_folder

    if args.list_presets:
        print(_sim_presets_text())
        return 0
    if args.out_dir is None:
        from turbinefit.errors import InputError

        raise InputError("OUT_DIR is required", field="simulate")
    cfg = _sim_config(args)
    out = simulate_folder(args.out_dir, cfg, overwrite=args.overwrite, progress=not args.quiet,
                          images=args.images)
    if not args.quiet:
        print(f"wrote {cfg.n_keyframes} keyframes to {out}")
    return 0


def _cmd_track(args: argparse.Namespace) -> int:
    import dataclasses

    from turbinefit.errors import InputError
    from turbinefit.pipeline import track_folder
    from turbinefit.solver.tracker import TrackerConfig

    fit_cfg = _resolve_fit_config(args)
    if args.window == 1:
        raise InputError("must be >= 2, or 0 to keep every keyframe", field="--window")
    try:
        cfg = TrackerConfig(fit=fit_cfg, window=args.window or None, rounds=args.rounds,
                            iterations=args.iterations, marginal_terms=args.marginal_terms)
        if args.no_prior:
            cfg = dataclasses.replace(cfg, theta_sigma=None)
    except ValueError as exc:
        raise InputError(str(exc), field="track options") from None
    bar = None
    progress = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(desc="track", unit="kf", file=sys.stderr, dynamic_ncols=True, leave=False,
                   disable=None)

        def progress(est: Any, total: int) -> None:
            assert bar is not None
            if bar.total is None:
                bar.reset(total=total)
            th = est.turbine
            bar.update(1)
            bar.set_postfix_str(
                f"{est.update_s * 1e3:5.1f} ms | base ({th.base_x:.2f}, {th.base_y:.2f}) "
                f"tower {th.tower_height:.2f} heading {_deg(th.heading):.2f} "
                f"rot {_deg(th.blade_rotation):.2f} blades {th.blade_length:.2f}", refresh=False)

    try:
        report = track_folder(args.flight_dir, args.out_dir, cfg, plots=not args.no_plots,
                              overwrite=args.overwrite, progress=progress,
                              config_path=args.config, from_images=args.from_images,
                              model=args.model, detect_options=_detect_options(args))
    finally:
        if bar is not None:
            bar.close()
    if not args.quiet:
        lat = report.summary["latency"]
        print(f"tracked {len(report.estimates)} keyframes: update median {lat['median_ms']:.1f} "
              f"ms, 99th percentile {lat['p99_ms']:.1f} ms, max {lat['max_ms']:.1f} ms, trend "
              f"{lat['slope_ms_per_1000_keyframes']:+.2f} ms per 1000 keyframes")
        th = report.turbine
        print(f"turbine: base ({th.base_x:.2f}, {th.base_y:.2f}) m, tower {th.tower_height:.2f} m, "
              f"heading {_deg(th.heading):.2f} deg, nacelle {th.nacelle_length:.2f} m, "
              f"blade rotation {_deg(th.blade_rotation):.2f} deg, blades {th.blade_length:.2f} m")
        acc = report.summary.get("accuracy")
        if acc is not None:
            for key in ("initial", "causal", "final"):
                a = acc[key]
                print(f"{key:8s} position error {a['position_error_m']:7.3f} m, orientation "
                      f"{a['orientation_error_deg']:6.3f} deg, model points "
                      f"{a['model_point_error_m']:6.3f} m")
        print(f"wrote {report.out_dir}")
    return 0


def _cmd_experiment(args: argparse.Namespace) -> int:
    from turbinefit.errors import InputError
    from turbinefit.experiments import STUDIES, study_config
    from turbinefit.experiments.studies import run_study
    from turbinefit.experiments.sweep import read_sweep_config

    studies = list(STUDIES) if args.study == "all" else [args.study]
    root = args.out_dir or Path("experiments") / args.study
    if args.config is not None:
        if args.study == "all":
            raise InputError("--config runs one sweep: give a study, not all", field="--config")
        configs = {args.study: read_sweep_config(args.config)}
    else:
        configs = {st: study_config(st, args.flights, args.keyframes, args.seed)
                   for st in studies}
    for st, cfg in configs.items():
        out = root / st if args.study == "all" else root
        bar = None
        progress = None
        if not args.quiet:
            from tqdm import tqdm

            bar = tqdm(desc=st, unit="flight", file=sys.stderr, dynamic_ncols=True,
                       disable=None)

            def progress(done: int, total: int, bar: Any = bar) -> None:
                if bar.total != total:
                    bar.reset(total=total)
                bar.n = done
                bar.refresh()

        try:
            rep = run_study(cfg, out, backend=args.backend, workers=args.workers,
                            progress=progress)
        finally:
            if bar is not None:
                bar.close()
        if not args.quiet:
            failed = sum(r["status"] != "ok" for r in rep.rows)
            rate = rep.new_rows / rep.seconds if rep.seconds > 0 else 0.0
            print(f"{st}: {len(rep.rows)} rows ({rep.new_rows} new in {rep.seconds:.0f} s, "
                  f"{rate:.2f} rows/s), {failed} failed; report {out / 'report.md'}")
    if args.study == "all":
        from turbinefit.experiments.studies import write_index

        index = write_index(root)
        if not args.quiet:
            print(f"index {index}")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from turbinefit.errors import InputError
    from turbinefit.experiments import write_report

    folder = args.folder
    if (folder / "sweep.yaml").is_file():
        print(f"wrote {write_report(folder)}")
        return 0
    subs = sorted(p for p in folder.iterdir() if (p / "sweep.yaml").is_file()) \
        if folder.is_dir() else []
    if not subs:
        raise InputError("not an experiment folder (no sweep.yaml in it or its sub-folders)",
                         folder)
    from turbinefit.experiments.studies import write_index

    for p in subs:
        print(f"wrote {write_report(p)}")
    print(f"wrote {write_index(folder)}")
    return 0


def _cmd_detect(args: argparse.Namespace) -> int:
    from turbinefit.pipeline import detect_images

    rep = detect_images(args.inputs, args.out_dir, args.model, overwrite=args.overwrite,
                        progress=not args.quiet, threads=args.threads,
                        detect_options=_detect_options(args))
    if not args.quiet:
        print(f"detected {rep.count} photo(s) in {rep.seconds:.2f} s "
              f"({rep.count / max(rep.seconds, 1e-9):.0f} photos/s with reading and "
              f"writing, {rep.workers} at once); wrote {rep.out_dir}")
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from turbinefit.pipeline import evaluate_labels

    rep = evaluate_labels(args.labels, args.images_dir, args.model, out=args.out,
                          overwrite=args.overwrite, match_px=args.match_px,
                          progress=not args.quiet, threads=args.threads,
                          detect_options=_detect_options(args))
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


def _cmd_train(args: argparse.Namespace) -> int:
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
                      widths=args.widths, fine=args.fine)
    res = train(cfg, progress=not args.quiet, log=print)
    print(f"wrote {res.model} (threshold {res.threshold:.2f}, {res.parameters:,} parameters)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``turbinefit`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from turbinefit.errors import TurbinefitError

    try:
        if args.command == "fit":
            return _cmd_fit(args)
        if args.command == "simulate":
            return _cmd_simulate(args)
        if args.command == "track":
            return _cmd_track(args)
        if args.command == "experiment":
            return _cmd_experiment(args)
        if args.command == "report":
            return _cmd_report(args)
        if args.command == "detect":
            return _cmd_detect(args)
        if args.command == "train":
            return _cmd_train(args)
        if args.command == "evaluate":
            return _cmd_evaluate(args)
    except TurbinefitError as exc:
        print(f"turbinefit: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("turbinefit: interrupted", file=sys.stderr)
        return 130
    parser.error(f"unknown command {args.command}")
    return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
