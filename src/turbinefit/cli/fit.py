"""``turbinefit fit``: optimise poses and turbine of a flight folder
(:func:`turbinefit.jobs.fit.fit_folder`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from turbinefit.cli.common import (
    VERDICT_EPILOG,
    add_flight_job_options,
    add_photo_options,
    detect_options,
    fit_base_and_options,
    init_line,
    pair_frame_report,
    turbine_line,
    verdict_line,
    verdict_status,
)

DESCRIPTION = """\
Refine every keyframe pose and the 7 turbine parameters with Levenberg-Marquardt
on the heat-maps and the GPS/IMU relative poses: first two correspondence
stages (align: the trajectory moves nearly rigidly; match: each keyframe), then
the configured cost.

Writes OUT_DIR/keyframes.txt (TUM), turbine.yaml, turbine.glb (the fitted
turbine as a 3-D model for any glTF viewer), summary.json (costs, iterations,
timings, and errors before/after when ground truth exists), config.yaml (the
resolved options) and plots. Every option of
turbinefit.FitConfig can be set in a --config YAML file; command-line options
override it."""


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    f: argparse.ArgumentParser = sub.add_parser(
        "fit", help=help, description=DESCRIPTION,
        usage="%(prog)s FLIGHT_DIR --out OUT_DIR [--config FILE | --preset NAME] [options]",
        epilog=VERDICT_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    f.add_argument("flight_dir", metavar="FLIGHT_DIR", type=Path, help="flight folder to fit")
    add_flight_job_options(f)
    add_photo_options(f, "detect the heat-maps from images/")
    f.add_argument("--overwrite", action="store_true",
                   help="replace OUT_DIR if it exists (only if it holds nothing but fit outputs)")
    f.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    return f


def run(args: argparse.Namespace) -> int:
    from turbinefit.jobs.fit import FitReport, fit_folder

    base, options = fit_base_and_options(args)
    bar = None
    progress = None
    if not args.quiet and sys.stderr.isatty():  # no bar in logs and CI (nor tqdm's import)
        from tqdm import tqdm

        bar = tqdm(desc="fit", unit="it", file=sys.stderr, dynamic_ncols=True, leave=False,
                   disable=None)

        def progress(rec: Any) -> None:
            assert bar is not None
            bar.update(1)
            bar.set_postfix_str(f"{rec.stage} round {rec.round} cost {rec.cost:.6g}")

    try:
        report: FitReport = fit_folder(
            args.flight_dir, args.out_dir, base, options=options, plots=not args.no_plots,
            overwrite=args.overwrite, progress=progress, config_path=args.config,
            from_images=args.from_images, model=args.model, detect_progress=not args.quiet,
            detect_options=detect_options(args))
    finally:
        if bar is not None:
            bar.close()
    if not args.quiet:
        r = report.result
        t = report.timings
        print(f"fitted {len(r.world_T_cam)} keyframes in {t['solve']:.2f} s "
              f"(load {t['load']:.2f} s, total {t['total']:.2f} s): {r.iterations} iterations, "
              f"{r.rounds} round(s), {r.termination}")
        if report.summary.defaults is not None:
            print(f"options: the defaults for {report.summary.defaults}")
        if report.summary.init is not None:
            print(init_line(report.summary.init))
        print(f"cost {r.initial_cost:.6g} -> {r.final_cost:.6g}")
        print(pair_frame_report(base, options, r.config))
        print(turbine_line(r.turbine))
        print(verdict_line(r.verdict, r.theta_std))
        if report.before is not None and report.after is not None:
            b, a = report.before, report.after
            print(f"position error     {b.position_error_m:8.3f} m   -> "
                  f"{a.position_error_m:8.3f} m")
            print(f"orientation error  {b.orientation_error_deg:8.3f} deg -> "
                  f"{a.orientation_error_deg:8.3f} deg")
            print(f"model point error  {b.model_point_error_m:8.3f} m   -> "
                  f"{a.model_point_error_m:8.3f} m")
        print(f"wrote {report.out_dir}")
    return verdict_status("fit", report.result.verdict, report.result.reasons, report.out_dir)
