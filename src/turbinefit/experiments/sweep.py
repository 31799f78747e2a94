"""Monte Carlo sweeps: many simulated flights, each fitted under several configurations.

A sweep is described by a :class:`SweepConfig` (YAML-able, every key checked before any
work). Its flights are drawn from the sweep's seed: flight ``i`` has its own simulation
seed and its own noise scales, uniform in the configured ranges, so the same sweep always
gives the same flights and any subset of them can be run anywhere. Each flight is
simulated once in memory and fitted under every configuration; each (flight,
configuration) gives one row of the tidy table ``rows.csv``:

* the flight: index, seed, keyframes, turbine, the pose / turbine / heat-map fault /
  heat-map blur scales, the blade-rotation offset, whether a second turbine is in view,
  the kind of pose measurements (``odometry``: ``gps``, GPS/IMU keyframes, or ``vio``,
  body-frame odometry, see :class:`~turbinefit.sim.scenario.SimConfig`);
* the outcome: ``status`` (``ok`` or ``error``) and ``reason``;
* initial and final errors: mean position [m], orientation [deg], camera roll [deg],
  model points [m], each turbine parameter (m, deg);
* the solver: initial and final cost, iterations, rounds, termination, wall time [s].

Rows are appended (and flushed) flight by flight, so an interrupted sweep resumes from
the table without redoing finished rows; a partly written last line is ignored. Flights
run in parallel on all local cores by default (processes, one solver thread each), or on
a Ray cluster (``backend="ray"``; ``ray.init()`` reads the cluster address from
``RAY_ADDRESS``). A flight whose fit raises is a row with its reason, not a failure of the
sweep.

Written by hand: the sweep is a plain map over independent tasks, which the standard
library's process pool (and Ray's task API, when asked) run; no experiment framework is
needed for resumable CSV rows.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import math
import os
import shutil
import time
import traceback
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from turbinefit.errors import InputError
from turbinefit.eval.metrics import accuracy, roll_errors_deg
from turbinefit.geometry.se3 import SE3
from turbinefit.io.atomic import (
    is_disk_full,
    read_text,
    remove_stale_temporaries,
    write_error,
    write_text_atomic,
)
from turbinefit.sim.noise import DEFAULT_TURBINE_SIGMA
from turbinefit.sim.scenario import SimConfig, simulate_flight
from turbinefit.solver.config import PRESETS, FitConfig
from turbinefit.solver.fit import fit
from turbinefit.turbine.model import TurbineParams

#: Names of the turbine parameters as table columns, with their units.
PARAM_COLUMNS = tuple(
    f"{n}_{'deg' if a else 'm'}" for n, a in zip(TurbineParams.NAMES, TurbineParams.ANGULAR,
                                                   strict=True))
#: Error columns measured before (``init_``) and after (``final_``) each fit.
ERROR_COLUMNS = ("position_m", "orientation_deg", "roll_deg", "model_points_m", *PARAM_COLUMNS)
#: The table's columns, in order.
COLUMNS: tuple[str, ...] = (
    "flight", "config", "status", "reason", "seed", "keyframes", "turbine", "pose_scale",
    "theta_scale", "heatmap_scale", "blur_scale", "blade_rotation_offset_deg", "second_turbine",
    "odometry", *(f"init_{c}" for c in ERROR_COLUMNS), *(f"final_{c}" for c in ERROR_COLUMNS),
    "initial_cost", "final_cost", "iterations", "rounds", "termination", "time_s",
)
ROWS_FILE = "rows.csv"
#: The columns of tables written before the ``odometry`` column (read as ``gps`` flights).
_COLUMNS_BEFORE_ODOMETRY = tuple(c for c in COLUMNS if c != "odometry")


@dataclass(frozen=True)
class SweepConfig:
    """A Monte Carlo sweep. Ranges are ``(low, high)``, sampled uniformly per flight.

    Attributes:
        name: a label (the study's name).
        flights: number of simulated flights.
        keyframes: keyframes per flight (the lower end, with ``keyframes_max``).
        keyframes_max: if set, each flight's keyframe count is drawn log-uniformly from
            ``[keyframes, keyframes_max]`` (the flight-length study).
        seed: seed of the sweep (flight seeds and noise scales derive from it).
        width, height: heat-map size [px].
        turbine: simulator turbine preset, or ``random``.
        pose_scale: range of the GPS/IMU drift, in units of the default (2 m, 2 deg RMS at
            the end of the flight); 0 = exact poses.
        theta_scale: range of the initial turbine error, in units of the default sigmas
            (1 m, 1 m, 2 m, 5 deg, 0.5 m, 5 deg, 2 m).
        heatmap_scale: range of the heat-map faults, in units of the default (pixel noise,
            missed parts, false responses, peak jitter); 0 = ideal heat-maps.
        blade_rotation_offset_deg: added to the initial blade rotation (the roll study).
        blur_scale: range of the heat-map blob and ridge width, in units of the default
            (2 px at 320 px): a blurrier CNN.
        second_turbine: fraction of flights with a neighbouring turbine in view (false
            responses in the same channels); true / false = all / none.
        odometry: fraction of flights whose pose measurements are body-frame odometry
            (``vio``: odometry.txt, its noise scaled by the flight's pose scale) instead of
            GPS/IMU keyframes (``gps``); drawn per flight after everything else, so that 0
            leaves every flight as it was.
        configs: name -> fit options (a mapping of :class:`FitConfig` fields, optionally
            with ``preset``: a name of :data:`turbinefit.solver.config.PRESETS` to start
            from).
    """

    name: str = "sweep"
    flights: int = 20
    keyframes: int = 100
    keyframes_max: int | None = None
    seed: int = 0
    width: int = 320
    height: int = 240
    turbine: str = "nrel5mw"
    pose_scale: tuple[float, float] = (0.0, 2.0)
    theta_scale: tuple[float, float] = (0.0, 2.0)
    heatmap_scale: tuple[float, float] = (1.0, 1.0)
    blur_scale: tuple[float, float] = (1.0, 1.0)
    blade_rotation_offset_deg: float = 0.0
    second_turbine: float = 0.0
    odometry: float = 0.0
    configs: dict[str, dict[str, Any]] = field(
        default_factory=lambda: {"paper-best": {"preset": "paper-best"}})

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"{name}: {why} (got {getattr(self, name)!r})")

        for name in ("flights", "keyframes", "width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < (2 if name == "keyframes" else 1):
                raise bad(name, "must be a whole number >= " + ("2" if name == "keyframes" else "1"))
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise bad("seed", "must be a whole number >= 0")
        if self.keyframes_max is not None and (
                isinstance(self.keyframes_max, bool) or not isinstance(self.keyframes_max, int)
                or self.keyframes_max < self.keyframes):
            raise bad("keyframes_max", "must be a whole number >= keyframes, or null")
        for name in ("pose_scale", "theta_scale", "heatmap_scale", "blur_scale"):
            v = getattr(self, name)
            if (not isinstance(v, tuple) or len(v) != 2
                    or not all(isinstance(x, int | float) and not isinstance(x, bool)
                               and math.isfinite(x) and x >= 0 for x in v) or v[0] > v[1]):
                raise bad(name, "must be [low, high] with 0 <= low <= high")
        if not (isinstance(self.blade_rotation_offset_deg, int | float)
                and math.isfinite(self.blade_rotation_offset_deg)):
            raise bad("blade_rotation_offset_deg", "must be a finite number")
        if isinstance(self.second_turbine, bool):
            object.__setattr__(self, "second_turbine", 1.0 if self.second_turbine else 0.0)
        if not (isinstance(self.second_turbine, int | float) and 0 <= self.second_turbine <= 1):
            raise bad("second_turbine", "must be a fraction in [0, 1] (or true / false)")
        if not (isinstance(self.odometry, int | float) and not isinstance(self.odometry, bool)
                and 0 <= self.odometry <= 1):
            raise bad("odometry", "must be the fraction of body-frame odometry flights, in [0, 1]")
        if min(self.blur_scale) <= 0:
            raise bad("blur_scale", "must be positive")
        if not isinstance(self.configs, dict) or not self.configs:
            raise bad("configs", "must be a non-empty mapping of name -> fit options")
        for name in self.configs:
            fit_config(self.configs, name)  # raises on unknown options or bad values
        SimConfig(n_keyframes=self.keyframes, width=self.width, height=self.height,
                  turbine=self.turbine)  # raises on an unknown turbine

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        for k in ("pose_scale", "theta_scale", "heatmap_scale", "blur_scale"):
            d[k] = list(d[k])
        d["second_turbine"] = float(d["second_turbine"])
        d["odometry"] = float(d["odometry"])
        return d

    @staticmethod
    def from_dict(d: dict[str, Any]) -> SweepConfig:
        """Build from a (YAML) mapping; unknown keys or bad values raise ValueError."""
        names = {f.name for f in dataclasses.fields(SweepConfig)}
        unknown = sorted(set(map(str, d)) - names)
        if unknown:
            raise ValueError(f"unknown sweep option(s): {', '.join(unknown)}")
        d = dict(d)
        for k in ("pose_scale", "theta_scale", "heatmap_scale", "blur_scale"):
            if isinstance(d.get(k), list):
                d[k] = tuple(d[k])
            elif isinstance(d.get(k), int | float) and not isinstance(d.get(k), bool):
                d[k] = (d[k], d[k])
        return SweepConfig(**d)


def read_sweep_config(path: str | os.PathLike[str]) -> SweepConfig:
    """The sweep of a YAML file (e.g. a run's ``sweep.yaml``); every problem is an
    InputError naming the file (and line, for malformed YAML)."""
    from turbinefit.io.yaml_files import load_yaml_mapping

    data = load_yaml_mapping(path)
    try:
        return SweepConfig.from_dict(data)
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), path) from None


#: How a config of a sweep may start from ``turbinefit init`` instead of the flight's
#: noisy turbine (its ``init`` option): from the images alone, ``near`` a position up to
#: :data:`INIT_NEAR_M` m from the base, or with ``sizes`` (hub height and rotor diameter)
#: wrong by up to :data:`INIT_SIZE_ERROR`.
INIT_MODES = ("nothing", "near", "sizes")
INIT_NEAR_M = 15.0
INIT_SIZE_ERROR = 0.15


def init_start(flight: Any, mode: str, rng: np.random.Generator) -> TurbineParams:
    """The turbine ``turbinefit init`` estimates for a sweep's flight (:data:`INIT_MODES`)."""
    from turbinefit.solver.init import TurbinePrior, initial_turbine

    truth = flight.gt_turbine
    prior = TurbinePrior()
    if mode == "near":
        r, a = INIT_NEAR_M * math.sqrt(rng.uniform()), rng.uniform(0, 2 * math.pi)
        prior = TurbinePrior(near_xy=(truth.base_x + r * math.cos(a),
                                      truth.base_y + r * math.sin(a)))
    elif mode == "sizes":
        e = rng.uniform(-INIT_SIZE_ERROR, INIT_SIZE_ERROR, 2)
        prior = TurbinePrior(hub_height=truth.tower_height * (1 + e[0]),
                             blade_length=truth.blade_length * (1 + e[1]))
    return initial_turbine(flight.heatmaps, flight.camera, flight.world_T_cam, prior).turbine


def fit_config(configs: dict[str, dict[str, Any]], name: str) -> FitConfig:
    """The :class:`FitConfig` of configuration ``name`` (ValueError naming it if bad)."""
    opts = {k: v for k, v in configs[name].items() if k != "init"}
    if configs[name].get("init", "nothing") not in INIT_MODES:
        raise ValueError(f"configs.{name}.init: must be one of {', '.join(INIT_MODES)}")
    if not isinstance(opts, dict):
        raise ValueError(f"configs.{name}: must be a mapping of fit options")
    opts = dict(opts)
    base = FitConfig()
    if "preset" in opts:
        p = opts.pop("preset")
        if p not in PRESETS:
            raise ValueError(f"configs.{name}.preset: unknown preset {p!r} (choose from "
                             f"{', '.join(PRESETS)})")
        base = PRESETS[p]
    try:
        return FitConfig.from_dict({**base.to_dict(), **opts})
    except (TypeError, ValueError) as exc:
        raise ValueError(f"configs.{name}: {exc}") from None


@dataclass(frozen=True)
class FlightSpec:
    """One flight of a sweep (everything needed to simulate it anywhere)."""

    index: int
    seed: int
    pose_scale: float
    theta_scale: float
    heatmap_scale: float
    keyframes: int = 100
    blur_scale: float = 1.0
    second_turbine: bool = False
    odometry: str = "gps"


def flight_specs(cfg: SweepConfig) -> list[FlightSpec]:
    """The sweep's flights, deterministic from its seed (flight i does not depend on how
    many flights there are)."""
    out = []
    for i in range(cfg.flights):
        rng = np.random.default_rng([cfg.seed, i])
        seed = int(rng.integers(0, 2**31 - 1))
        scales = [float(rng.uniform(lo, hi)) for lo, hi in
                  (cfg.pose_scale, cfg.theta_scale, cfg.heatmap_scale)]
        # drawn after the above, so adding them left earlier sweeps' flights unchanged
        n = cfg.keyframes
        if cfg.keyframes_max is not None and cfg.keyframes_max > cfg.keyframes:
            n = round(math.exp(rng.uniform(math.log(cfg.keyframes),
                                           math.log(cfg.keyframes_max))))
        blur = float(rng.uniform(*cfg.blur_scale))
        neighbour = bool(rng.uniform() < cfg.second_turbine)
        vio = bool(rng.uniform() < cfg.odometry)
        out.append(FlightSpec(i, seed, pose_scale=scales[0], theta_scale=scales[1],
                              heatmap_scale=scales[2], keyframes=n, blur_scale=blur,
                              second_turbine=neighbour, odometry="vio" if vio else "gps"))
    return out


def _sim_config(cfg: SweepConfig, spec: FlightSpec) -> SimConfig:
    base = SimConfig()
    s = spec.heatmap_scale
    hn = base.heatmap_noise
    noise = dataclasses.replace(hn, pixel_sigma=hn.pixel_sigma * s,
                                miss_prob=min(hn.miss_prob * s, 0.9),
                                spurious_rate=hn.spurious_rate * s,
                                amplitude_jitter=min(hn.amplitude_jitter * s, 0.9))
    return SimConfig(
        n_keyframes=spec.keyframes, seed=spec.seed, width=cfg.width, height=cfg.height,
        turbine=cfg.turbine, heatmap_noise=noise,
        heatmap_sigma=base.heatmap_sigma * spec.blur_scale,
        drift_pos_m=base.drift_pos_m * spec.pose_scale,
        drift_rot_deg=base.drift_rot_deg * spec.pose_scale,
        turbine_sigma=tuple(x * spec.theta_scale for x in DEFAULT_TURBINE_SIGMA),
        second_turbine=spec.second_turbine, odometry=spec.odometry,
        odometry_noise=spec.pose_scale)


def _errors(prefix: str, poses: SE3, turbine: TurbineParams, gt_poses: SE3,
            gt_turbine: TurbineParams, geometry: Any) -> dict[str, float]:
    a = accuracy(poses, turbine, gt_poses, gt_turbine, geometry)
    out = {f"{prefix}position_m": a.position_error_m,
           f"{prefix}orientation_deg": a.orientation_error_deg,
           f"{prefix}roll_deg": float(np.mean(np.abs(roll_errors_deg(poses, gt_poses)))),
           f"{prefix}model_points_m": a.model_point_error_m}
    for col, name in zip(PARAM_COLUMNS, TurbineParams.NAMES, strict=True):
        out[f"{prefix}{col}"] = a.param_errors[name]
    return out


def run_flight(cfg: SweepConfig, spec: FlightSpec, configs: list[str]) -> list[dict[str, Any]]:
    """Simulate flight ``spec`` and fit it under each of ``configs``: one row each. Never
    raises for a failing fit or simulation: the row says why."""
    base: dict[str, Any] = {
        "flight": spec.index, "seed": spec.seed, "keyframes": spec.keyframes,
        "turbine": cfg.turbine, "pose_scale": spec.pose_scale,
        "theta_scale": spec.theta_scale, "heatmap_scale": spec.heatmap_scale,
        "blur_scale": spec.blur_scale,
        "blade_rotation_offset_deg": cfg.blade_rotation_offset_deg,
        "second_turbine": spec.second_turbine, "odometry": spec.odometry}
    try:
        flight = simulate_flight(_sim_config(cfg, spec))
        if cfg.blade_rotation_offset_deg:
            v = flight.turbine.to_vector()
            v[5] += math.radians(cfg.blade_rotation_offset_deg)
            flight = dataclasses.replace(flight, turbine=TurbineParams.from_vector(v))
    except Exception as exc:  # a row, not a crash of the sweep
        return [{**base, "config": c, "status": "error",
                 "reason": f"simulation failed: {type(exc).__name__}: {exc}"} for c in configs]
    assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
    rows = []
    for name in configs:
        fc = fit_config(cfg.configs, name)
        row = {**base, "config": name}
        start = flight
        mode = cfg.configs[name].get("init")
        t0 = time.perf_counter()
        if mode is not None:
            try:
                start = dataclasses.replace(flight, turbine=init_start(
                    flight, mode, np.random.default_rng([spec.seed, 30])))
            except Exception as exc:  # e.g. a parameter the images do not determine
                rows.append({**row, "status": "error", "reason": f"init: {exc}",
                             "time_s": time.perf_counter() - t0})
                continue
        row.update(_errors("init_", start.world_T_cam, start.turbine, flight.gt_world_T_cam,
                           flight.gt_turbine, fc.geometry))
        try:
            res = fit(start, fc)
            errs = _errors("final_", res.world_T_cam, res.turbine, flight.gt_world_T_cam,
                           flight.gt_turbine, fc.geometry)
            bad = [k for k, v in errs.items() if not math.isfinite(v)]
            if bad or not math.isfinite(res.final_cost):
                raise FloatingPointError(f"non-finite result ({', '.join(bad) or 'cost'})")
            row.update(errs)
            row.update(status="ok", reason="", initial_cost=res.initial_cost,
                       final_cost=res.final_cost, iterations=res.iterations,
                       rounds=res.rounds, termination=res.termination)
        except Exception as exc:
            where = traceback.extract_tb(exc.__traceback__)[-1]
            row.update(status="error", reason=f"{type(exc).__name__}: {exc} "
                       f"({Path(where.filename).name}:{where.lineno})")
        row["time_s"] = time.perf_counter() - t0
        rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------
# the table
# ---------------------------------------------------------------------------------------
def _format(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return str(v)


def format_rows(rows: list[dict[str, Any]]) -> str:
    """CSV lines (no header) of ``rows`` in :data:`COLUMNS` order."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    for r in rows:
        w.writerow([_format(r.get(c)) for c in COLUMNS])
    return buf.getvalue()


_INT = {"flight", "seed", "keyframes", "iterations", "rounds"}
_STR = {"config", "status", "reason", "turbine", "termination", "odometry"}


def read_rows(path: str | os.PathLike[str], missing_ok: bool = False) -> list[dict[str, Any]]:
    """The rows of a sweep table, typed (numbers as float/int, empty as None). A last line
    cut short by an interruption is skipped; any other malformed line is an InputError.
    ``missing_ok``: no rows for a missing table (and for an unreadable one)."""
    p = Path(path)
    if missing_ok:
        try:
            return read_rows(p)
        except InputError:
            return []
    lines = read_text(p).splitlines(keepends=True)
    if not lines:
        raise InputError("empty sweep table (no header)", p)
    header = tuple(next(csv.reader([lines[0]])))
    if header not in (COLUMNS, _COLUMNS_BEFORE_ODOMETRY):
        raise InputError("not a turbinefit sweep table (unexpected columns)", p, 1)
    out = []
    for n, line in enumerate(lines[1:], start=2):
        last = n == len(lines)
        fields = next(csv.reader([line]), [])
        if len(fields) != len(header) or (last and not line.endswith("\n")):
            if last:
                break  # interrupted while writing: the flight is redone
            raise InputError(f"expected {len(header)} fields, found {len(fields)}", p, n)
        row: dict[str, Any] = {"odometry": "gps"}  # tables without the column: GPS/IMU
        for c, v in zip(header, fields, strict=True):
            if c in _STR:
                row[c] = v
            elif v == "":
                row[c] = None
            elif v in ("true", "false"):
                row[c] = v == "true"
            else:
                try:
                    row[c] = int(v) if c in _INT else float(v)
                except ValueError:
                    raise InputError(f"{c}: not a number ({v!r})", p, n) from None
        out.append(row)
    return out


# ---------------------------------------------------------------------------------------
# running
# ---------------------------------------------------------------------------------------
def _run_local(tasks: list[FlightSpec], cfg: SweepConfig, configs: list[str],
               workers: int) -> Generator[list[dict[str, Any]], None, None]:
    if workers <= 1:
        for spec in tasks:
            yield run_flight(cfg, spec, configs)
        return
    import concurrent.futures as cf
    from concurrent.futures.process import BrokenProcessPool

    from turbinefit.errors import TurbinefitError
    from turbinefit.experiments.workers import process_pool

    # workers that end with this process, one solver thread each
    with process_pool(workers) as pool:
        futures = [pool.submit(run_flight, cfg, spec, configs) for spec in tasks]
        for fut in cf.as_completed(futures):
            try:
                rows = fut.result()
            except BrokenProcessPool:
                raise TurbinefitError("a worker process of the sweep was killed (out of memory?); "
                                      "the finished rows are kept: run it again to resume") from None
            yield rows


def _run_ray(tasks: list[FlightSpec], cfg: SweepConfig,
             configs: list[str]) -> Generator[list[dict[str, Any]], None, None]:
    try:
        import ray
    except ImportError:
        raise InputError("the ray backend needs Ray: pip install 'ray[default]'",
                         field="--backend") from None
    if not ray.is_initialized():
        ray.init(runtime_env={"env_vars": {"OMP_NUM_THREADS": "1"}})  # RAY_ADDRESS, if set
    remote = ray.remote(run_flight)
    pending = [remote.remote(cfg, spec, configs) for spec in tasks]
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        yield ray.get(done[0])


def _append(f: io.FileIO, text: str, table: Path, kept: int) -> None:
    """Append ``text`` to the table ``f`` (unbuffered) after its ``kept`` rows, all of it
    or, if the disk is full, none of it."""
    size = f.seek(0, os.SEEK_END)
    data = memoryview(text.encode("utf-8"))
    try:
        while data:
            data = data[f.write(data) or 0:]
    except OSError as exc:
        with contextlib.suppress(OSError):
            f.truncate(size)  # no partial line
        err = write_error(exc, table)
        if kept:
            err = InputError(f"{err}; its {kept} finished row{'s' if kept > 1 else ''} "
                             "kept: run the same command again to resume")
        raise err from exc


@dataclass
class SweepReport:
    """What :func:`run_sweep` did: ``rows`` (all, old and new), how many ``new_rows`` it
    ran, in ``seconds``."""

    rows: list[dict[str, Any]]
    new_rows: int
    seconds: float


def run_sweep(cfg: SweepConfig, out_dir: str | os.PathLike[str], *, backend: str = "local",
              workers: int | None = None,
              progress: Callable[[int, int], None] | None = None) -> SweepReport:
    """Run (or resume) the sweep into ``out_dir/rows.csv``.

    Rows already in the table are kept and not rerun (the table must be from the same
    sweep: ``out_dir/sweep.yaml`` is compared with ``cfg``). A non-empty folder without a
    ``sweep.yaml`` is refused, so that nothing of the user's is overwritten. ``progress(done, total)`` is
    called after each flight (flights, not rows).

    If it stops (an error, an interruption, a full disk: one :class:`InputError` naming the
    table), the rows finished are kept in the table, whole, for the next run to resume
    from; a folder this run created and wrote no row into is removed.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError("not a directory", out)
    if out.is_dir():
        remove_stale_temporaries(out)  # left by a killed run
    if out.is_dir() and any(out.iterdir()) and not (out / "sweep.yaml").exists():
        raise InputError("folder is not empty and holds no sweep (sweep.yaml): choose a new "
                         "or empty folder", out)
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise write_error(exc, out) if is_disk_full(exc) else InputError(
            f"cannot create the output folder: {exc.strerror or exc}", out) from exc
    try:
        return _run_sweep(cfg, out, backend, workers, progress)
    except BaseException:
        if created and not read_rows(out / ROWS_FILE, missing_ok=True):
            shutil.rmtree(out, ignore_errors=True)  # nothing worth keeping: leave no trace
        raise


def _run_sweep(cfg: SweepConfig, out: Path, backend: str, workers: int | None,
               progress: Callable[[int, int], None] | None) -> SweepReport:
    import yaml

    sweep_file = out / "sweep.yaml"
    text = yaml.safe_dump(cfg.to_dict(), sort_keys=False)
    if sweep_file.exists():
        if read_sweep_config(sweep_file) != cfg:
            raise InputError("holds a different sweep; use another output folder",
                             sweep_file)
    else:
        write_text_atomic(sweep_file, text)
    table = out / ROWS_FILE
    rows: list[dict[str, Any]] = read_rows(table) if table.exists() else []
    done = {(r["flight"], r["config"]) for r in rows}
    names = list(cfg.configs)
    specs = flight_specs(cfg)
    todo = [s for s in specs if any((s.index, c) not in done for c in names)]
    # rewrite the table without a cut-off last line, then append flight by flight
    write_text_atomic(table, ",".join(COLUMNS) + "\n" + format_rows(rows))
    t0 = time.perf_counter()
    new = 0
    total = len(specs)
    if progress is not None:
        progress(total - len(todo), total)
    if backend == "local":
        results = _run_local(todo, cfg, names, workers or os.cpu_count() or 1)
    elif backend == "ray":
        results = _run_ray(todo, cfg, names)
    else:
        raise InputError(f"unknown backend {backend!r} (choose local or ray)", field="--backend")
    with open(table, "ab", buffering=0) as f, contextlib.closing(results):
        # closing: an exception here (a full disk, a signal) stops the workers at once
        finished = total - len(todo)
        for flight_rows in results:
            fresh = [r for r in flight_rows if (r["flight"], r["config"]) not in done]
            _append(f, format_rows(fresh), table, len(rows))
            rows.extend(fresh)
            new += len(fresh)
            finished += 1
            if progress is not None:
                progress(finished, total)
    rows.sort(key=lambda r: (r["flight"], names.index(r["config"])
                             if r["config"] in names else len(names)))
    return SweepReport(rows, new, time.perf_counter() - t0)
