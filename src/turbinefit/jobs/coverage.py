"""The ``coverage`` job: what each keyframe of a fitted flight shows of each blade and the
tower (:mod:`turbinefit.inspection.coverage`).

:func:`read_fit_output` reads what a ``fit`` or ``track`` output folder holds (fitted
poses, turbine and shape geometry) and the camera of the flight it came from
(``summary.json`` names it, or ``flight_dir``); :func:`coverage_folder` writes
``coverage.csv`` (one row per keyframe and part in view), ``sides.csv`` (the best
resolution reached on each side, span by span), ``summary.json`` and ``coverage.png``,
atomically (:mod:`turbinefit.jobs.outputs`).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.inspection.coverage import (
    COVERAGE_COLUMNS,
    Coverage,
    flight_coverage,
    side_names,
)
from turbinefit.inspection.surface import PARTS, SurfaceShape, TurbineSurface, name_margin_deg
from turbinefit.io.atomic import read_text, write_text_atomic
from turbinefit.io.camera_yaml import read_camera_yaml
from turbinefit.io.flight_folder import CAMERA_FILE, KEYFRAMES_FILE, TURBINE_FILE
from turbinefit.io.georef import Georef, read_flight_georef
from turbinefit.io.tum import read_tum_lines
from turbinefit.io.turbine_yaml import read_turbine_yaml
from turbinefit.io.yaml_files import load_yaml_mapping
from turbinefit.jobs.outputs import OutputKind, check_not_input, plot_error, summary_json
from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineGeometry, TurbineParams

COVERAGE_OUTPUTS = OutputKind("coverage", frozenset({
    "coverage.csv", "sides.csv", "summary.json", "coverage.png"}))


@dataclass
class FitOutput:
    """What a ``fit`` or ``track`` output folder says, with its flight's camera.

    Attributes:
        fit_dir, flight_dir: the folders (no flight if its camera was not needed and
            ``summary.json`` names none that is there).
        timestamps, world_T_cam: the fitted keyframe poses.
        turbine: the fitted turbine; geometry: its fixed shape details (``config.yaml``).
        camera: the photos' camera (the flight's ``camera.yaml``; None without a flight).
        georef: the flight's ``georef.yaml`` (None: not georeferenced or no flight).
    """

    fit_dir: Path
    flight_dir: Path | None
    timestamps: Any
    world_T_cam: SE3
    turbine: TurbineParams
    geometry: TurbineGeometry
    camera: PinholeCamera | None
    georef: Georef | None


def _geometry(path: Path) -> TurbineGeometry:
    """The shape geometry of a fit's or track's ``config.yaml`` (defaults without one)."""
    if not path.exists():
        return PAPER_GEOMETRY
    data = load_yaml_mapping(path)
    fit = data.get("fit", data)
    geo = fit.get("geometry", {}) if isinstance(fit, dict) else None
    if not isinstance(geo, dict):
        raise InputError("geometry must be a mapping", path, field="geometry")
    try:
        return TurbineGeometry(**geo)
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), path, field="geometry") from None


def _flight_of(fit_dir: Path) -> Path:
    """The flight folder ``summary.json`` of a fit names (as given to ``fit``: relative to
    the working directory then, or to the fit folder's parent)."""
    path = fit_dir / "summary.json"
    if not path.is_file():
        raise InputError("missing: cannot tell which flight it came from; give --flight", path)
    try:
        name = json.loads(read_text(path)).get("flight")
    except (json.JSONDecodeError, AttributeError):
        name = None
    if not isinstance(name, str):
        raise InputError("names no flight folder; give --flight", path, field="flight")
    for cand in (Path(name), fit_dir.parent / name):
        if (cand / CAMERA_FILE).is_file():
            return cand
    raise InputError(f"its flight folder {name} has no {CAMERA_FILE} here; give --flight",
                     path, field="flight")


def read_fit_output(fit_dir: str | os.PathLike[str],
                    flight_dir: str | os.PathLike[str] | None = None, *,
                    need_camera: bool = True) -> FitOutput:
    """Read a ``fit``/``track`` output folder and its flight's camera (see :class:`FitOutput`;
    ``need_camera=False``: the flight is optional).

    Raises:
        InputError: a missing folder, ``keyframes.txt`` or ``turbine.yaml`` (the fitted
            poses and turbine), a flight that cannot be found (when needed), or any bad file.
    """
    fit_dir = Path(fit_dir)
    if not fit_dir.is_dir():
        raise InputError("is not a fit output folder", fit_dir)
    for name, what in ((KEYFRAMES_FILE, "poses"), (TURBINE_FILE, "turbine")):
        if not (fit_dir / name).exists():
            raise InputError(f"missing: a fit folder without fitted {what}", fit_dir / name)
    traj = read_tum_lines(fit_dir / KEYFRAMES_FILE)
    turbine = read_turbine_yaml(fit_dir / TURBINE_FILE)
    geometry = _geometry(fit_dir / "config.yaml")
    flight: Path | None = Path(flight_dir) if flight_dir is not None else None
    if flight is None:
        try:
            flight = _flight_of(fit_dir)
        except InputError:
            if need_camera:
                raise
    if flight is None:
        return FitOutput(fit_dir, None, traj.timestamps, traj.poses, turbine, geometry, None,
                         None)
    camera = read_camera_yaml(flight / CAMERA_FILE) if need_camera else None
    return FitOutput(fit_dir, flight, traj.timestamps, traj.poses, turbine, geometry, camera,
                     read_flight_georef(flight))


@dataclass
class CoverageReport:
    """What :func:`coverage_folder` did: the coverage, the surface it was computed on,
    the summary written and timings [s]."""

    coverage: Coverage
    surface: TurbineSurface
    out_dir: Path
    summary: dict[str, Any]
    timings: dict[str, float] = field(default_factory=dict)


def format_coverage_csv(coverage: Coverage, timestamps: Any) -> str:
    """The text of ``coverage.csv``."""
    lines = [",".join(COVERAGE_COLUMNS)]
    for r in coverage.rows:
        lines.append(f"{float(timestamps[r.keyframe]):.6f},{r.keyframe},{PARTS[r.part]},"
                     f"{r.span_from:.2f},{r.span_to:.2f},{r.visible_m:.2f},{'+'.join(r.sides)},"
                     f"{r.distance_m:.2f},{r.gsd_mm_px:.3f}")
    return "\n".join(lines) + "\n"


def format_sides_csv(coverage: Coverage, timestamps: Any) -> str:
    """The text of ``sides.csv``: per part, side and span bin, the best GSD and the
    keyframe that reached it (empty: never seen)."""
    lines = ["part,side,span_from_m,span_to_m,best_gsd_mm_px,timestamp"]
    for g in coverage.grids:
        for k, side in enumerate(side_names(g.part)):
            for j, s in enumerate(g.spans):
                gsd, kf = g.best_gsd[k, j], int(g.best_keyframe[k, j])
                lines.append(f"{PARTS[g.part]},{side},{s - 0.5 * g.step:.2f},"
                             f"{s + 0.5 * g.step:.2f},"
                             + (f"{gsd:.3f},{float(timestamps[kf]):.6f}" if kf >= 0 else ","))
    return "\n".join(lines) + "\n"


@dataclass
class MappingSummary:
    """A summary that is already the mapping ``summary.json`` holds."""

    data: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return self.data


def coverage_folder(fit_dir: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                    flight_dir: str | os.PathLike[str] | None = None,
                    camera: PinholeCamera | None = None, step: float = 0.5,
                    max_gsd_mm: float = 2.0, blade_pitch: float = 0.0,
                    blade_twist: float = 0.0, plots: bool = True,
                    overwrite: bool = False) -> CoverageReport:
    """What each keyframe of the fit in ``fit_dir`` shows (its fitted poses and turbine, the
    photos' ``camera``, by default that of ``flight_dir`` or of the flight its
    ``summary.json`` names), written to
    ``out_dir``: ``coverage.csv``, ``sides.csv``, ``summary.json`` (per part and side the
    fraction of the span seen, and seen at ``max_gsd_mm`` mm/px or finer) and, unless
    ``plots=False``, ``coverage.png``. Parts are sampled every ``step`` m; blades have pitch
    ``blade_pitch`` and root twist ``blade_twist`` [rad] (0: flat in the rotor plane).

    Raises:
        InputError: bad input or a bad ``out_dir`` (checked first); nothing is written.
    """
    t0 = time.perf_counter()
    fit_dir, out_dir = Path(fit_dir), Path(out_dir)
    if not (step > 0 and math.isfinite(step)):
        raise InputError(f"must be a positive number of metres, got {step}", field="--step")
    if not (max_gsd_mm > 0 and math.isfinite(max_gsd_mm)):
        raise InputError(f"must be a positive number, got {max_gsd_mm}", field="--gsd")
    inputs = [fit_dir] + ([] if flight_dir is None else [Path(flight_dir)])
    COVERAGE_OUTPUTS.check(out_dir, inputs, overwrite)
    fit = read_fit_output(fit_dir, flight_dir, need_camera=camera is None)
    if fit.flight_dir is not None:
        check_not_input(out_dir, [fit.flight_dir])
    cam = camera or fit.camera
    assert cam is not None
    surface = TurbineSurface(fit.turbine, fit.geometry,
                             SurfaceShape(blade_pitch=blade_pitch, blade_twist=blade_twist))
    t1 = time.perf_counter()
    cov = flight_coverage(surface, cam, fit.world_T_cam, step)
    timings = {"load": t1 - t0, "coverage": time.perf_counter() - t1}
    summary = {
        "turbinefit_version": __version__, "fit": str(fit_dir),
        "flight": None if fit.flight_dir is None else str(fit.flight_dir),
        "keyframes": len(fit.timestamps), "step_m": step, "max_gsd_mm_px": max_gsd_mm,
        "blade_pitch_deg": math.degrees(blade_pitch), "blade_twist_deg": math.degrees(blade_twist),
        "blades": {bl.name: {"model_blade": bl.model_index + 1,
                             "clock_deg": round(bl.clock_deg, 3)} for bl in surface.blades},
        "name_margin_deg": round(name_margin_deg(surface.turbine), 3),
        "coverage": cov.summary(max_gsd_mm), "timing_s": timings,
    }
    with COVERAGE_OUTPUTS.writing(out_dir, overwrite) as tmp:
        write_text_atomic(tmp / "coverage.csv", format_coverage_csv(cov, fit.timestamps),
                          fsync=False)
        write_text_atomic(tmp / "sides.csv", format_sides_csv(cov, fit.timestamps),
                          fsync=False)
        if plots:
            from turbinefit.plots.inspection import plot_coverage

            try:
                plot_coverage(tmp / "coverage.png", cov, max_gsd_mm)
            except OSError as exc:
                raise plot_error(exc, out_dir) from exc
        timings["total"] = time.perf_counter() - t0
        write_text_atomic(tmp / "summary.json", summary_json(MappingSummary(summary)), fsync=False)
    return CoverageReport(cov, surface, out_dir, summary, timings)
