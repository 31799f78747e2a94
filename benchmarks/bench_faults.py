"""The fault corpus as figures: tracebacks, hangs, silent accepts, files left behind.

Runs every case of the fault corpus (``tests/fault_cases.py``, run by
``tests/faults.py``: malformed files, files that are named pipes or devices, absurd sizes
and magnitudes, bad options, of every command) on a
freshly simulated 6-keyframe flight and counts, over all cases:

* ``tracebacks``: a Python traceback reached stderr (or an exception escaped ``main``);
* ``hangs``: a case run in a subprocess (the named pipes) did not end within 60 s;
* ``silent_accepts``: exit status 0 on bad input;
* ``left_behind``: a file or folder written next to the inputs or at the output path;
* ``inputs_changed``: an input file changed or removed;
* ``other``: any other departure from one error line naming the file or option with exit
  status 2 (wrong message, wrong status).

All must be 0 (``tests/cli/test_fault_corpus.py`` asserts the same, case by case). Also
the time the checks of heat-map values (one minimum and maximum per channel and file)
add to opening a 200-keyframe flight's heat-maps (``--check-flight``; ``fit`` checks them as
its solver first reads them instead).
Results go to ``benchmarks/results/bench_faults.json``.
Run: ``python benchmarks/bench_faults.py`` (about half a minute on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from fault_cases import CASES  # noqa: E402
from faults import make_base, run_case  # noqa: E402

from turbinefit.io.heatmap_files import ValueCheck  # noqa: E402


def run_corpus() -> dict[str, object]:
    counts = dict.fromkeys(("tracebacks", "hangs", "silent_accepts", "left_behind",
                            "inputs_changed", "other"), 0)
    failures: dict[str, list[str]] = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        base = make_base(Path(tmp))
        for i, case in enumerate(CASES):
            work = Path(tmp) / f"case{i}"
            work.mkdir()
            outcome = run_case(case, base, work)
            problems = outcome.problems(case)
            counts["tracebacks"] += outcome.traceback
            counts["hangs"] += outcome.hung
            counts["silent_accepts"] += outcome.accepted
            counts["left_behind"] += bool(outcome.written)
            counts["inputs_changed"] += bool(outcome.changed)
            known = outcome.traceback or outcome.hung or outcome.accepted or bool(
                outcome.written) or bool(outcome.changed)
            counts["other"] += bool(problems) and not known
            if problems:
                failures[case.name] = problems
            shutil.rmtree(work, ignore_errors=True)
    return {"cases": len(CASES), "subprocess_cases": sum(c.subprocess for c in CASES),
            **counts, "seconds": round(time.perf_counter() - t0, 1), "failures": failures}


def heatmap_check_cost(keyframes: int = 200) -> dict[str, float]:
    """Seconds to open a simulated flight's heat-maps with the value checks (``check="now"``,
    as ``track`` and ``init`` open them) and without (``check="first read"``: ``fit`` checks
    them as its solver first reads them), page cache warm (best of 3)."""
    from turbinefit.cli import main
    from turbinefit.io.flight_folder import read_flight_folder

    with tempfile.TemporaryDirectory() as tmp:
        flight = Path(tmp) / "flight"
        assert main(["simulate", str(flight), "--keyframes", str(keyframes), "--quiet"]) == 0
        folder = read_flight_folder(flight)

        def best(check: ValueCheck) -> float:
            times = []
            for _ in range(3):
                t = time.perf_counter()
                folder.read_heatmaps(check=check)
                times.append(time.perf_counter() - t)
            return min(times)

        with_check = best("now")
        without = best("first read")
        stack = folder.read_heatmaps()
    return {"keyframes": keyframes, "map_size": f"{stack.width}x{stack.height}",
            "open_s": round(without, 4), "open_with_checks_s": round(with_check, 4),
            "checks_s": round(with_check - without, 4),
            "checks_ms_per_keyframe": round(1e3 * (with_check - without) / keyframes, 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check-flight", type=int, default=200, metavar="N",
                    help="keyframes of the flight whose heat-map checks are timed (0: skip)")
    args = ap.parse_args()
    result = run_corpus()
    print(f"{result['cases']} cases ({result['subprocess_cases']} in a subprocess) in "
          f"{result['seconds']} s: {result['tracebacks']} tracebacks, {result['hangs']} hangs, "
          f"{result['silent_accepts']} silent accepts, {result['left_behind']} left files "
          f"behind, {result['inputs_changed']} changed an input, {result['other']} other")
    for name, problems in result["failures"].items():  # type: ignore[union-attr]
        print(f"  {name}: {'; '.join(problems)}")
    if args.check_flight:
        cost = heatmap_check_cost(args.check_flight)
        result["heatmap_checks"] = cost
        print(f"heat-map value checks, {cost['keyframes']} keyframes of {cost['map_size']} "
              f"maps: {cost['checks_s']:.3f} s ({cost['checks_ms_per_keyframe']:.2f} ms a "
              f"keyframe; opening without them {cost['open_s']:.3f} s)")
    out = HERE / "results" / "bench_faults.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
