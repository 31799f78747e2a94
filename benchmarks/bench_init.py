"""``turbinefit init`` and fits started from it, against fits started from the
simulator's near-true turbine.yaml (``turbinefit simulate``'s initial turbine).

Per default 200-keyframe flight (``--flights`` seeds, GPS/IMU and VIO odometry):

* ``init`` from nothing and from ``--near`` a position up to 10 m from the base: its
  parameter errors (targets: heading and blade rotation within 5 deg, base within 2 m,
  lengths within 5 %, on >= 95 % of flights) and its time (target < 3 s);
* ``fit`` from each estimate and from the flight's turbine.yaml: success = final position
  and model-point errors under 0.5 m (target >= 95 %, same accuracy as from turbine.yaml);
* ``track`` from nothing against ``track`` from turbine.yaml on the first ``--track``
  GPS flights (target: final position error within 10 %);
* ``--photos N``: the photo flights of bench_defaults.py (seeds 0 to N-1, 200 keyframes,
  320 x 240 photos, rendered once into ``benchmarks/data/``), init + fit from the heat-maps
  the CNN detects (target >= 90 %), the fit from their turbine.yaml, and the fit of the
  simulator's ideal heat-maps from it (what the flight allows without the CNN's errors);
  ``--photo-size 1280``: bench_resolution.py's flights with 1280 x 960 photos instead
  (seeds 20 to 19+N), detected coarse to fine as ``fit`` does.

Usage::

    python benchmarks/bench_init.py [--flights 10] [--track 3] [--photos 0]
        [--photo-size 320|1280] [--out FILE]

Prints a table and writes ``benchmarks/results/bench_init.json`` (or ``--out``).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import RESULTS, write_json

from turbinefit.eval.metrics import accuracy
from turbinefit.jobs.sources import FILE_FIT_DEFAULTS
from turbinefit.sim.scenario import SimConfig, simulate_flight
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import fit
from turbinefit.solver.init import TurbinePrior, initial_turbine
from turbinefit.turbine.model import param_errors

CLI_DEFAULTS = dataclasses.replace(FitConfig(), **FILE_FIT_DEFAULTS)
GOOD_M = 0.5


def init_ok(e: np.ndarray, truth: Any) -> bool:
    """The issue's init targets: angles within 5 deg, base 2 m, lengths 5 %."""
    return bool(abs(math.degrees(e[3])) < 5 and abs(math.degrees(e[5])) < 5
                and math.hypot(e[0], e[1]) < 2
                and abs(e[2]) < 0.05 * truth.tower_height
                and abs(e[6]) < 0.05 * truth.blade_length
                and abs(e[4]) < max(0.05 * truth.nacelle_length, 1.0))


def one_flight(seed: int, odometry: str) -> dict[str, Any]:
    flight = simulate_flight(SimConfig(seed=seed, odometry=odometry))
    truth = flight.gt_turbine
    assert truth is not None and flight.gt_world_T_cam is not None
    row: dict[str, Any] = {"seed": seed, "odometry": odometry}
    rng = np.random.default_rng(1000 + seed)
    ang = rng.uniform(0, 2 * math.pi)
    near = (truth.base_x + 10 * math.cos(ang), truth.base_y + 10 * math.sin(ang))
    starts = {"yaml": flight.turbine}
    for name, prior in (("nothing", TurbinePrior()), ("near", TurbinePrior(near_xy=near))):
        t0 = time.perf_counter()
        res = initial_turbine(flight.heatmaps, flight.camera, flight.world_T_cam, prior)
        row[f"init_{name}_s"] = time.perf_counter() - t0
        e = param_errors(res.turbine, truth)
        row[f"init_{name}_errors"] = e.tolist()
        row[f"init_{name}_ok"] = init_ok(e, truth)
        starts[name] = res.turbine
    for name, start in starts.items():
        fl = dataclasses.replace(flight, turbine=start)
        r = fit(fl, CLI_DEFAULTS)
        a = accuracy(r.world_T_cam, r.turbine, flight.gt_world_T_cam, truth)
        row[f"fit_{name}_position_m"] = a.position_error_m
        row[f"fit_{name}_model_m"] = a.model_point_error_m
        row[f"fit_{name}_ok"] = a.position_error_m < GOOD_M and a.model_point_error_m < GOOD_M
    return row


def track_pair(seed: int, root: Path) -> dict[str, Any]:
    from turbinefit.jobs.simulate import simulate_folder
    from turbinefit.jobs.track import track_folder

    folder = simulate_folder(root / f"t{seed}", SimConfig(seed=seed))
    a = track_folder(folder, root / f"t{seed}_yaml", plots=False).summary.final
    (folder / "turbine.yaml").unlink()
    b = track_folder(folder, root / f"t{seed}_none", plots=False).summary.final
    assert a is not None and b is not None
    return {"seed": seed, "yaml_position_m": a.position_error_m,
            "nothing_position_m": b.position_error_m,
            "ratio": b.position_error_m / a.position_error_m}


def _link_or_copy(src: str, dst: str) -> None:
    try:
        os.link(src, dst)
    except OSError:  # another file system
        shutil.copy2(src, dst)


def photo_flight(seed: int, root: Path, size: int = 320) -> dict[str, Any]:
    """init + fit of the photo flight of ``seed``, copied without its heat-maps (photos
    hard-linked): bench_defaults.py's with 320 x 240 photos, or bench_resolution.py's with
    1280 x 960 photos (each simulated once into ``benchmarks/data/``). Also the fit of its
    ideal heat-maps from its turbine.yaml."""
    from turbinefit.jobs.fit import fit_folder

    if size == 1280:
        from bench_resolution import photo_flight as simulate_1280
        source = simulate_1280(seed, 200)
    else:
        from bench_defaults import simulate
        source = simulate(seed, 200)
    ideal = fit_folder(source, root / f"p{seed}_ideal", plots=False).summary.after
    folder = root / f"p{seed}"
    shutil.copytree(source, folder, copy_function=_link_or_copy,
                    ignore=shutil.ignore_patterns("heatmaps"))
    y = fit_folder(folder, root / f"p{seed}_yaml", plots=False).summary.after
    assert y is not None and ideal is not None
    (folder / "turbine.yaml").unlink()
    rep = fit_folder(folder, root / f"p{seed}_fit", plots=False)
    a = rep.summary.after
    init = rep.summary.init
    assert a is not None and init is not None and init.errors is not None
    e = init.errors
    return {"seed": seed, "photo_width": size, "init_errors": e,
            "ideal_position_m": ideal.position_error_m,
            "ideal_model_m": ideal.model_point_error_m,
            "ideal_ok": (ideal.position_error_m < GOOD_M
                         and ideal.model_point_error_m < GOOD_M),
            "yaml_position_m": y.position_error_m,
            "yaml_model_m": y.model_point_error_m,
            "yaml_ok": y.position_error_m < GOOD_M and y.model_point_error_m < GOOD_M,
            "position_m": a.position_error_m,
            "model_m": a.model_point_error_m,
            "ok": a.position_error_m < GOOD_M and a.model_point_error_m < GOOD_M}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flights", type=int, default=10)
    ap.add_argument("--track", type=int, default=3)
    ap.add_argument("--photos", type=int, default=0)
    ap.add_argument("--photo-size", type=int, choices=(320, 1280), default=320,
                    help="photo width of the --photos flights: 320 (seeds 0, 1, ...) or "
                         "1280 (seeds 20, 21, ...)")
    ap.add_argument("--out", type=Path, default=RESULTS / "bench_init.json")
    args = ap.parse_args()
    rows = [one_flight(s, odo) for odo in ("gps", "vio") for s in range(args.flights)]
    out: dict[str, Any] = {"machine": platform.platform(), "flights": rows}
    n = max(len(rows), 1)

    def share(key: str) -> float:
        return 100.0 * sum(bool(r[key]) for r in rows) / n

    if rows:
        print(f"{len(rows)} default 200-keyframe flights (seeds 0-{args.flights - 1}, gps and "
              f"vio)")
    for name in ("nothing", "near") if rows else ():
        times = [r[f"init_{name}_s"] for r in rows]
        err = np.array([r[f"init_{name}_errors"] for r in rows])
        print(f"init from {name:<8}: targets met on {share(f'init_{name}_ok'):5.1f} %; worst "
              f"heading {np.degrees(np.abs(err[:, 3])).max():.2f} deg, blade rotation "
              f"{np.degrees(np.abs(err[:, 5])).max():.2f} deg, base "
              f"{np.hypot(err[:, 0], err[:, 1]).max():.2f} m, tower "
              f"{np.abs(err[:, 2]).max():.2f} m, blades {np.abs(err[:, 6]).max():.2f} m; "
              f"time median {np.median(times):.2f} s, max {max(times):.2f} s")
    for name in ("yaml", "nothing", "near") if rows else ():
        pos = [r[f"fit_{name}_position_m"] for r in rows]
        mod = [r[f"fit_{name}_model_m"] for r in rows]
        print(f"fit from {name:<8}: success {share(f'fit_{name}_ok'):5.1f} %, position mean "
              f"{np.mean(pos):.3f} m, model points mean {np.mean(mod):.3f} m")
    with tempfile.TemporaryDirectory() as tmp:
        tracks = [track_pair(s, Path(tmp)) for s in range(args.track)]
        if args.photo_size == 1280:
            from bench_resolution import PHOTO_SEED as first
        else:
            first = 0
        photos = [photo_flight(first + i, Path(tmp), args.photo_size)
                  for i in range(args.photos)]
    out["track"] = tracks
    out["photos"] = photos
    if tracks:
        print("track from nothing / from turbine.yaml, final position error: "
              + ", ".join(f"{t['ratio']:.3f}" for t in tracks)
              + f" (mean {np.mean([t['ratio'] for t in tracks]):.3f})")
    if photos:
        print(f"photos: init + fit success {100 * np.mean([p['ok'] for p in photos]):.1f} % of "
              f"{len(photos)}, from turbine.yaml {100 * np.mean([p['yaml_ok'] for p in photos]):.1f}"
              f" %, ideal heat-maps {100 * np.mean([p['ideal_ok'] for p in photos]):.1f}"
              " %; position init + fit / from turbine.yaml: " + ", ".join(
                  f"{p['position_m']:.3f} / {p['yaml_position_m']:.3f}" for p in photos))
    write_json(args.out, out)


if __name__ == "__main__":
    main()
