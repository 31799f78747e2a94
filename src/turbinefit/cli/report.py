"""``turbinefit report``: rebuild an experiment's figures and report from its stored rows."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    r: argparse.ArgumentParser = sub.add_parser(
        "report", help=help,
        description="Rebuild the figures, summary.json and report.md of an experiment folder "
        "(or of every study folder below it, as `experiment all` writes) from its stored "
        "rows.csv and sweep.yaml, without running anything.")
    r.add_argument("folder", metavar="DIR", type=Path, help="experiment folder")
    return r


def _report(folder: Path) -> None:
    """Write the report of the study in ``folder`` and say how many rows it is drawn from."""
    from turbinefit.experiments import write_report
    from turbinefit.experiments.studies import load_study, planned_rows, rows_text

    cfg, rows = load_study(folder)
    path = write_report(folder)
    note = " (incomplete)" if len(rows) < planned_rows(cfg) else ""
    print(f"wrote {path} from {rows_text(cfg, rows)}{note}")


def run(args: argparse.Namespace) -> int:
    from turbinefit.errors import InputError
    from turbinefit.experiments.studies import write_index

    folder = args.folder
    if (folder / "sweep.yaml").is_file():
        _report(folder)
        return 0
    subs = sorted(p for p in folder.iterdir() if (p / "sweep.yaml").is_file()) \
        if folder.is_dir() else []
    if not subs:
        raise InputError("not an experiment folder (no sweep.yaml in it or its sub-folders)",
                         folder)
    for p in subs:
        _report(p)
    print(f"wrote {write_index(folder)}")
    return 0
