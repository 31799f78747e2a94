"""``turbinefit simulate``: write a simulated flight folder with ground truth
(:func:`turbinefit.jobs.simulate.simulate_folder`)."""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from turbinefit.cli.common import (
    DefaultsFormatter,
    number,
    option,
    positive_int,
    seed,
    whole_nonneg,
)
from turbinefit.jobs.simulate import PHOTO_SCALE
from turbinefit.sim.gnss import GNSS_MODELS

if TYPE_CHECKING:
    from turbinefit.sim.scenario import SimConfig


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    s: argparse.ArgumentParser = sub.add_parser(
        "simulate", help=help,
        description="Simulate an inspection flight around a realistic turbine: ground-truth "
        "poses and turbine, heat-maps as a CNN would give them, drifting GPS/IMU poses and a "
        "noisy initial turbine. Writes a flight folder (see `turbinefit --help`).",
        formatter_class=DefaultsFormatter)
    s.add_argument("out_dir", metavar="OUT_DIR", type=Path, nargs="?",
                   help="flight folder to create")
    s.add_argument("--keyframes", type=positive_int, default=200, help="number of keyframes")
    s.add_argument("--seed", type=seed, default=0,
                   help="random seed, >= 0 (same seed, same flight)")
    s.add_argument("--preset", default="default",
                   help="simulation preset: default, noiseless, exact, hard, distorted "
                   "(see --list-presets)")
    s.add_argument("--turbine", default=None,
                   help="turbine preset name, or 'random' (default: the preset's)")
    s.add_argument("--width", type=positive_int, default=None, help="camera (photo) width [px]")
    s.add_argument("--height", type=positive_int, default=None,
                   help="camera (photo) height [px]")
    s.add_argument("--heatmap-size", type=heatmap_size, default=None, metavar="WxH|W",
                   help="heat-map size [px], the camera's scaled (W alone: height to match); "
                   "default: the camera's, at most 320 px wide")
    s.add_argument("--drift-m", type=number, default=None,
                   help="order of the GPS/IMU position drift over the flight [m]")
    s.add_argument("--drift-deg", type=number, default=None,
                   help="order of the GPS/IMU orientation drift over the flight [deg]")
    s.add_argument("--turbine-noise", type=number, default=None,
                   help="scale of the initial turbine's noise (1 = the default sigmas "
                   "1 m, 1 m, 2 m, 5 deg, 0.5 m, 5 deg, 2 m; 0 = exact)")
    s.add_argument("--heatmap-noise", type=number, default=None,
                   help="std. dev. of additive pixel noise on the heat-maps")
    s.add_argument("--odometry", choices=["gps", "vio"], default="gps",
                   help="gps: drifting GPS/IMU keyframe poses; vio: body-frame odometry "
                   "(noisy relative motions chained from the first pose, its world frame "
                   "drifting away) in odometry.txt and keyframes.txt")
    s.add_argument("--second-turbine", action="store_true",
                   help="add a second turbine in view (false responses)")
    s.add_argument("--images", action="store_true",
                   help="also render a photo of every keyframe into images/ (procedural "
                   "scene from the seed)")
    s.add_argument("--path", type=Path, default=None, metavar="POSES_TXT",
                   help="fly these ground-truth camera poses (TUM world_T_cam, timestamps "
                   "from the file; e.g. plan's keyframes.txt) instead of the simulated "
                   "inspection; --keyframes is then their number")
    s.add_argument("--camera", type=Path, default=None, metavar="CAMERA_YAML",
                   help="the photos' camera (camera_info YAML) instead of --width/--height")
    s.add_argument("--photo-scale", type=option(PHOTO_SCALE), default=1.0, metavar="F",
                   help="photos (and camera.yaml) at this fraction of the camera's size, "
                   f"{PHOTO_SCALE.range_text()}")
    s.add_argument("--gnss", choices=list(GNSS_MODELS), default=None,
                   help="record the poses with this GNSS error model (standard: metre-level, "
                   "rtk: centimetre-level; both with a compass yaw error of a few degrees; "
                   "docs/mission.md) instead of the --drift-m/--drift-deg drift (with "
                   "--odometry vio: GNSS keyframes, VIO odometry.txt)")
    defects = s.add_mutually_exclusive_group()
    defects.add_argument("--defects", type=whole_nonneg, default=0, metavar="N",
                         help="draw N known defects on the blades with the seed "
                         "(defects_groundtruth.csv; with --images defect_boxes.csv)")
    defects.add_argument("--defects-file", type=Path, default=None, metavar="DEFECTS_CSV",
                         help="paint these defects (defect,part,side,span_m,chord,size_m"
                         "[,kind]) instead")
    s.add_argument("--list-presets", action="store_true", help="list presets and exit")
    s.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it exists (only if it holds nothing but a flight)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    return s


def heatmap_size(text: str) -> tuple[int, int | None]:
    """``WxH`` or ``W`` [px] (argparse type): (W, H), or (W, None) for the height that
    keeps the camera's aspect ratio."""
    parts = text.lower().split("x")
    try:
        if len(parts) > 2:
            raise ValueError
        w, h = positive_int(parts[0]), positive_int(parts[1]) if len(parts) == 2 else None
    except (ValueError, argparse.ArgumentTypeError):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT or WIDTH in pixels, got "
                                         f"{text!r}") from None
    return w, h


def sim_config(args: argparse.Namespace) -> SimConfig:
    """The :class:`~turbinefit.sim.scenario.SimConfig` of the command line."""
    from turbinefit.errors import InputError
    from turbinefit.sim.noise import DEFAULT_TURBINE_SIGMA
    from turbinefit.sim.render import HeatmapNoise
    from turbinefit.sim.scenario import PRESETS

    if args.preset not in PRESETS:
        raise InputError(f"unknown preset {args.preset!r} (choose from {', '.join(PRESETS)})",
                         field="--preset")
    base = PRESETS[args.preset]
    over: dict[str, Any] = {"n_keyframes": args.keyframes, "seed": args.seed}
    if args.odometry != "gps":
        over["odometry"] = args.odometry
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
    if args.gnss is not None:
        over["gnss"] = args.gnss
    if args.defects:
        over["defects"] = args.defects
    for key in ("drift_pos_m", "drift_rot_deg"):
        if key in over and not (math.isfinite(over[key]) and over[key] >= 0):
            raise InputError(f"must be a non-negative number, got {over[key]}", field=key)
    # sim.noise / sim.render would fail (turbine) or silently ignore (heat-maps) these
    for flag, value in (("--turbine-noise", args.turbine_noise),
                        ("--heatmap-noise", args.heatmap_noise)):
        if value is not None and not (math.isfinite(value) and value >= 0):
            raise InputError(f"must be a non-negative number, got {value}", field=flag)
    if args.heatmap_size is not None:
        w, h = args.heatmap_size
        if h is None:
            cam_w, cam_h = over.get("width", base.width), over.get("height", base.height)
            h = max(1, round(cam_h * w / cam_w))
        over["heatmap_size"] = (w, h)
    try:
        cfg = dataclasses.replace(base, **over)
        HeatmapNoise(**dataclasses.asdict(cfg.heatmap_noise))
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), field="simulate options") from None
    return cfg


def run(args: argparse.Namespace) -> int:
    from turbinefit.errors import InputError
    from turbinefit.jobs.simulate import simulate_folder

    if args.list_presets:
        from turbinefit.sim.scenario import PRESETS
        from turbinefit.sim.turbines import PRESETS as TURBINES

        print("simulation presets: " + ", ".join(PRESETS))
        print("turbine presets:    " + ", ".join([*TURBINES, "random"]))
        return 0
    if args.out_dir is None:
        raise InputError("OUT_DIR is required", field="simulate")
    cfg = sim_config(args)
    camera = None
    if args.camera is not None:
        from turbinefit.io.camera_yaml import read_camera_yaml

        camera = read_camera_yaml(args.camera)
    out = simulate_folder(args.out_dir, cfg, overwrite=args.overwrite, progress=not args.quiet,
                          images=args.images, camera=camera, photo_scale=args.photo_scale,
                          path=args.path, defects_file=args.defects_file)
    if not args.quiet:
        from turbinefit.io.tum import read_tum

        n = len(read_tum(out / "keyframes.txt")[0])
        print(f"wrote {n} keyframes to {out}")
        import yaml

        sim = yaml.safe_load((out / "simulation.yaml").read_text(encoding="utf-8"))
        if "blade_pitch_deg" in sim:  # coverage of these photos needs the blades as drawn
            print(f"blades drawn at coverage --blade-pitch {sim['blade_pitch_deg']:g} "
                  f"--blade-twist {sim['blade_twist_deg']:g}")
    return 0
