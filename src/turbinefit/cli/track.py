"""``turbinefit track``: replay a flight keyframe by keyframe through the in-flight tracker
(:func:`turbinefit.jobs.track.track_folder`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from turbinefit.cli.common import (
    VERDICT_EPILOG,
    add_flight_job_options,
    add_photo_options,
    degrees,
    detect_options,
    fit_base_and_options,
    init_line,
    pair_frame_report,
    positive_int,
    turbine_line,
    verdict_line,
    verdict_status,
    whole_nonneg,
)

DESCRIPTION = """\
Successive estimation as the drone flies: keyframes are fed in time order to a
fixed-lag smoother that refines the last --window keyframe poses and the turbine
after each one and folds older keyframes into a prior (marginalisation). A live
status line shows the keyframe, its update time and the current turbine.

Writes OUT_DIR/causal.txt (TUM: each keyframe's estimate when it arrived),
keyframes.txt, turbine.yaml and turbine.glb (the final estimates, as fit writes
them),
latency.csv (timestamp,latency_ms), config.yaml, summary.json (latency figures;
errors of the causal and final estimates when ground truth exists) and plots
(latency.png, errors.png, scene.png). Fit options as for `turbinefit fit`."""


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    from turbinefit.solver.tracker import TrackerConfig

    tdf = TrackerConfig()
    k: argparse.ArgumentParser = sub.add_parser(
        "track", help=help, description=DESCRIPTION,
        usage="%(prog)s FLIGHT_DIR --out OUT_DIR [--window K] [--config FILE | --preset NAME] "
        "[options]",
        epilog=VERDICT_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    k.add_argument("flight_dir", metavar="FLIGHT_DIR", type=Path, help="flight folder to replay")
    k.add_argument("--window", type=whole_nonneg, default=tdf.window, metavar="K",
                   help=f"keyframes in the sliding window, >= 2; 0 keeps them all (the batch "
                   f"problem, per-keyframe work grows) (default: {tdf.window})")
    k.add_argument("--rounds", type=positive_int, default=tdf.rounds,
                   help=f"correspondence rounds per keyframe (default: {tdf.rounds})")
    k.add_argument("--iterations", type=positive_int, default=tdf.iterations,
                   help=f"LM iterations per round (default: {tdf.iterations})")
    k.add_argument("--marginal-terms", choices=["corr", "same"], default=tdf.marginal_terms,
                   help="how a keyframe leaving the window is linearised into the prior: as "
                   "correspondences (valid over the whole search range) or as the configured "
                   f"cost (default: {tdf.marginal_terms})")
    k.add_argument("--no-prior", action="store_true",
                   help="no start-up prior on the turbine (default: a prior around the initial "
                   "turbine, removed once the images outweigh it)")
    add_flight_job_options(k, batch=False)
    add_photo_options(k, "detect each keyframe's heat-maps from images/ as it arrives")
    k.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it exists (only if it holds nothing but track "
                   "outputs)")
    k.add_argument("--quiet", action="store_true", help="no status line or summary")
    return k


def run(args: argparse.Namespace) -> int:

    from turbinefit.errors import InputError
    from turbinefit.jobs.track import TrackReport, track_folder
    from turbinefit.solver.tracker import TrackerConfig

    base, options = fit_base_and_options(args)
    if args.window == 1:
        raise InputError("must be >= 2, or 0 to keep every keyframe", field="--window")
    tracker_options: dict[str, Any] = {
        "window": args.window or None, "rounds": args.rounds, "iterations": args.iterations,
        "marginal_terms": args.marginal_terms}
    if args.no_prior:
        tracker_options["theta_sigma"] = None
    try:
        config = None if base is None else TrackerConfig(fit=base)
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
                f"tower {th.tower_height:.2f} heading {degrees(th.heading):.2f} "
                f"rot {degrees(th.blade_rotation):.2f} blades {th.blade_length:.2f}",
                refresh=False)

    try:
        report: TrackReport = track_folder(
            args.flight_dir, args.out_dir,
            config,
            tracker_options=tracker_options, options=options, plots=not args.no_plots,
            overwrite=args.overwrite, progress=progress, config_path=args.config,
            from_images=args.from_images, model=args.model,
            detect_options=detect_options(args))
    finally:
        if bar is not None:
            bar.close()
    if not args.quiet:
        s = report.summary
        lat = s.latency
        if lat is not None:
            print(f"tracked {len(report.estimates)} keyframes: update median "
                  f"{lat.median_ms:.1f} ms, 99th percentile {lat.p99_ms:.1f} ms, max "
                  f"{lat.max_ms:.1f} ms, trend {lat.slope_ms_per_1000_keyframes:+.2f} ms per "
                  "1000 keyframes")
        if s.init is not None:
            print(init_line(s.init))
        print(turbine_line(report.turbine))
        print(verdict_line(s.verdict, None if s.signals is None else s.signals.theta_std))
        if s.defaults is not None:
            print(f"options: the defaults for {s.defaults}")
        print(pair_frame_report(base, options, s.config.fit))
        for name, a in (("initial", s.initial), ("causal", s.causal), ("final", s.final)):
            if a is not None:
                print(f"{name:8s} position error {a.position_error_m:7.3f} m, orientation "
                      f"{a.orientation_error_deg:6.3f} deg, model points "
                      f"{a.model_point_error_m:6.3f} m")
        print(f"wrote {report.out_dir}")
    return verdict_status("track", report.summary.verdict, report.summary.reasons,
                          report.out_dir)
