"""What the benchmark scripts share: where data and results live, cached simulated flight
folders, page-cache warming and atomic JSON results (run the scripts from anywhere: their
own folder is on ``sys.path``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from turbinefit.jobs.outputs import finite_json

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
RESULTS = HERE / "results"
BIN = Path(sys.executable).parent / "turbinefit"


def simulate(n: int, seed: int, odometry: str = "gps") -> Path:
    """The default-preset flight folder of ``n`` keyframes and ``seed`` (simulated once,
    then reused from ``benchmarks/data/``); ``odometry="vio"``: with body-frame odometry
    (``simulate --odometry vio``)."""
    out = DATA / (f"flight_n{n}_s{seed}" if odometry == "gps" else f"flight_{odometry}_n{n}_s{seed}")
    if not (out / "keyframes.txt").exists():
        DATA.mkdir(exist_ok=True)
        subprocess.run([str(BIN), "simulate", str(out), "--keyframes", str(n), "--seed",
                        str(seed), "--odometry", odometry, "--overwrite", "--quiet"], check=True)
    return out


#: Exit statuses of a command that ran and wrote its outputs: 0, and 3 for a `fit` or
#: `track` whose verdict is `failed` (a result to record, not a crash of the benchmark).
RAN = (0, 3)


def run_command(argv: list[str], **kwargs: object) -> subprocess.CompletedProcess:
    """``turbinefit ARGV...`` in a child process (``subprocess.run`` keywords); raises
    ``RuntimeError`` with its stderr unless it exits with a status of :data:`RAN`."""
    kwargs.setdefault("stderr", subprocess.PIPE)
    proc = subprocess.run([str(BIN), *argv], text=True, **kwargs)  # type: ignore[call-overload]
    if proc.returncode not in RAN:
        raise RuntimeError(f"turbinefit {' '.join(argv)} failed (exit status "
                           f"{proc.returncode}): {(proc.stderr or '').strip()}")
    return proc


def warm(flight: Path) -> None:
    """Read every file once so that all runs see the page cache (as right after `simulate`)."""
    for p in flight.rglob("*"):
        if p.is_file():
            with open(p, "rb") as f:
                while f.read(1 << 24):
                    pass


def write_json(path: Path, result: dict) -> None:
    """Write ``result`` to ``path`` atomically, as strict JSON (undefined numbers: null)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(finite_json(result), indent=2, allow_nan=False) + "\n")
    os.replace(tmp, path)
