"""``turbinefit experiment``: run (or resume) the paper's Monte Carlo studies
(:mod:`turbinefit.experiments`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from turbinefit.cli.common import positive_int, seed

STUDY_NAMES = ("unary", "joint", "turbine", "roll", "basin", "quality", "length", "odometry",
               "init")

DESCRIPTION = """\
Run (or resume) a Monte Carlo study: many simulated flights, each fitted under
the study's configurations, one row per (flight, configuration) in
OUT_DIR/rows.csv, with sweep.yaml (the resolved sweep), PNG figures, summary.json
and report.md (medians and 90th percentiles, figures embedded).

  unary    the four unary configurations (paper Fig. 4)
  joint    joint vs pose-only (Fig. 5)
  turbine  recovery of the turbine parameters (Fig. 6)
  roll     a wrong blade rotation: false roll of pose-only (Fig. 7)
  basin    success rate against the size of the initial errors
  quality  heat-map faults, blur and a second turbine in view
  length   flight length (25-400 keyframes)
  odometry pairwise frame measured / estimated / auto on GPS/IMU and odometry flights
  init     turbinefit init then fit: from nothing, --near (<= 15 m), sizes (+-15 %)
  all      all of them, into OUT_DIR/<study>/

Re-running the same command resumes without redoing finished rows. Flights run
on all local cores, or on a Ray cluster with --backend ray (address from
RAY_ADDRESS; needs `pip install ray`)."""


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    e: argparse.ArgumentParser = sub.add_parser(
        "experiment", help=help, description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    e.add_argument("study", metavar="STUDY", choices=[*STUDY_NAMES, "all"],
                   help=", ".join(STUDY_NAMES) + " or all")
    e.add_argument("--flights", type=positive_int, default=None,
                   help="simulated flights (default: the study's: 200 for unary, joint and "
                   "turbine, 20 for roll, 120 for basin and quality, 60 for length and odometry)")
    e.add_argument("--keyframes", type=positive_int, default=100, help="keyframes per flight "
                   "(default: 100; the length study draws 25-400)")
    e.add_argument("--seed", type=seed, default=0, help="sweep seed (default: 0)")
    e.add_argument("--config", type=Path, default=None,
                   help="a sweep YAML (the sweep.yaml of a run) instead of the study's; "
                   "--flights, --keyframes and --seed then do not apply")
    e.add_argument("--out", dest="out_dir", metavar="OUT_DIR", type=Path, default=None,
                   help="output folder (default: experiments/STUDY)")
    e.add_argument("--backend", choices=["local", "ray"], default="local",
                   help="where flights run (default: local processes)")
    e.add_argument("--workers", type=positive_int, default=None,
                   help="local processes (default: all cores)")
    e.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    return e


def run(args: argparse.Namespace) -> int:
    from turbinefit.errors import InputError
    from turbinefit.experiments import STUDIES, study_config
    from turbinefit.experiments.studies import rows_text, run_study, write_index
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
            print(f"{st}: {rows_text(cfg, rep.rows)} ({rep.new_rows} new in {rep.seconds:.0f} s, "
                  f"{rate:.2f} rows/s), {failed} failed; report {out / 'report.md'}")
    if args.study == "all":
        index = write_index(root)
        if not args.quiet:
            print(f"index {index}")
    return 0
