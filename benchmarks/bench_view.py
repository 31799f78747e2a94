"""``turbinefit view`` of a 1000-keyframe fit with 200 embedded photos: how long the page
takes to write, how large it is, and how long headless Chromium takes to make it
interactive.

The flight is ``turbinefit simulate F --keyframes 1000 --images`` at a small camera
(``--width`` x 3/4, default 640 x 480: the default 400 px thumbnails are then real
reductions), fitted with ``turbinefit fit`` from its heat-maps (both cached in
``benchmarks/data/``). Then, each run a fresh process with a warm page cache:

* ``turbinefit view FIT --out view.html`` (defaults: 200 photos, 400 px thumbnails,
  coverage computed): wall time from process start to exit (targets: < 10 s, page
  <= 25 MB), and the job's stages;
* the page opened in headless Chromium (Debian's, driven by playwright:
  ``tests/support_browser.py``): wall time from the request to the page's ready flag
  (the scene drawn once, the legend built, clicks answered; target < 5 s), the page's own
  time to ready since navigation began, console errors (target: none), and a click on a
  camera until its photo panel shows.

Usage::

    python benchmarks/bench_view.py [--keyframes 1000] [--photos 200] [--width 640] [--runs 3]

Prints a table and writes ``benchmarks/results/bench_view.json``.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from common import BIN, DATA, HERE, RESULTS, run_command, warm, write_json

sys.path.insert(0, str(HERE.parent / "tests"))

from support_browser import opened, why_no_browser


def photo_fit(keyframes: int, width: int) -> tuple[Path, Path]:
    """The simulated photo flight and its fit (made once, then reused)."""
    flight = DATA / f"view_flight_n{keyframes}_w{width}"
    fit = DATA / f"view_fit_n{keyframes}_w{width}"
    if not (flight / "keyframes.txt").exists():
        DATA.mkdir(exist_ok=True)
        subprocess.run([str(BIN), "simulate", str(flight), "--keyframes", str(keyframes),
                        "--seed", "0", "--images", "--width", str(width), "--height",
                        str(width * 3 // 4), "--overwrite", "--quiet"], check=True)
    if not (fit / "keyframes.txt").exists():
        run_command(["fit", str(flight), "--out", str(fit), "--no-plots", "--quiet",
                     "--overwrite"])
    return flight, fit


def write_page(fit: Path, out: Path, photos: int) -> float:
    """Wall time [s] of ``turbinefit view`` from process start to exit."""
    t0 = time.perf_counter()
    run_command(["view", str(fit), "--out", str(out), "--photos", str(photos), "--overwrite",
                 "--quiet"])
    return time.perf_counter() - t0


def open_page(out: Path) -> dict[str, Any]:
    """One visit: time to ready, the page's own time, errors, a click's answer [s]."""
    with opened(out) as view:
        page = view.page
        state = page.evaluate("() => document.documentElement.dataset.ready")
        xy = next((xy for k in range(0, 1000, 7)
                   if (xy := page.evaluate(f"() => window.turbinefitView.screenOf('optimised', {k})"))),
                  None)
        click_s = None
        if xy is not None:
            t0 = time.perf_counter()
            page.mouse.click(*xy)
            page.locator("#photo").wait_for(state="visible", timeout=10000)
            click_s = time.perf_counter() - t0
        return {"ready_s": view.seconds, "page_ready_ms": view.ready_ms, "state": state,
                "errors": view.errors, "requests": len(view.requests), "click_s": click_s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--keyframes", type=int, default=1000)
    ap.add_argument("--photos", type=int, default=200)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    flight, fit = photo_fit(args.keyframes, args.width)
    warm(flight)
    warm(fit)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "view.html"
        walls = [write_page(fit, out, args.photos) for _ in range(args.runs)]
        size = out.stat().st_size
        from turbinefit.jobs.view import view_page

        stages = view_page(fit, Path(tmp) / "stages.html", photos=args.photos).timings
        reason = why_no_browser()
        visits = [] if reason else [open_page(out) for _ in range(args.runs)]
    result: dict[str, Any] = {
        "machine": platform.platform(), "keyframes": args.keyframes, "photos": args.photos,
        "camera": f"{args.width}x{args.width * 3 // 4}", "write_wall_s": walls,
        "write_median_s": statistics.median(walls), "stages_s": stages, "size_bytes": size,
        "browser": reason or "headless Chromium", "visits": visits}
    print(f"turbinefit view of a {args.keyframes}-keyframe fit, {args.photos} photos of "
          f"{result['camera']} px (400 px thumbnails)")
    print(f"  write: median {result['write_median_s']:.2f} s of {args.runs} "
          f"({min(walls):.2f}-{max(walls):.2f} s); stages "
          + ", ".join(f"{k} {v:.2f}" for k, v in stages.items()))
    print(f"  page: {size / 1e6:.2f} MB")
    if visits:
        ready = [v["ready_s"] for v in visits]
        print(f"  Chromium: ready in median {statistics.median(ready):.2f} s "
              f"({min(ready):.2f}-{max(ready):.2f} s; the page's own "
              f"{statistics.median(v['page_ready_ms'] for v in visits):.0f} ms), "
              f"click to photo {statistics.median(v['click_s'] or 0 for v in visits):.3f} s, "
              f"console errors {sum(len(v['errors']) for v in visits)}")
        result["ready_median_s"] = statistics.median(ready)
    else:
        print(f"  Chromium: skipped ({reason})")
    write_json(RESULTS / "bench_view.json", result)


if __name__ == "__main__":
    main()
