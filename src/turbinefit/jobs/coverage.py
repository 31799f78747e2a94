"""The ``coverage`` job: what each keyframe of a fitted flight shows of each blade and the
tower (:mod:`turbinefit.inspection.coverage`).

:func:`read_fit_output` reads what a ``fit`` or ``track`` output folder holds (fitted
poses, turbine and shape geometry) and the camera of the flight it came from
(``summary.json`` names it, or ``flight_dir``); :func:`coverage_folder` writes
``coverage.csv`` (one row per keyframe and part in view), ``sides.csv`` (the best
resolution reached on each side, span by span), ``summary.json`` and ``coverage.png``,
with a damage CSV ``damage.csv`` (where each box drawn on a photo lies on the turbine),
atomically (:mod:`turbinefit.jobs.outputs`).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

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
from turbinefit.inspection.surface import (
    PARTS,
    BoxLocation,
    SurfaceShape,
    TurbineSurface,
    locate_box,
    name_margin_deg,
)
from turbinefit.io.atomic import read_text, write_text_atomic
from turbinefit.io.camera_yaml import read_camera_yaml
from turbinefit.io.defects import LocatedDamage
from turbinefit.io.flight_folder import CAMERA_FILE, IMAGE_DIR, KEYFRAMES_FILE, TURBINE_FILE
from turbinefit.io.geojson import write_geojson_twin
from turbinefit.io.georef import Georef, read_flight_georef
from turbinefit.io.quantities import Quantity
from turbinefit.io.tum import read_tum_lines
from turbinefit.io.turbine_yaml import read_turbine_yaml
from turbinefit.io.yaml_files import load_yaml_mapping
from turbinefit.jobs.outputs import (
    OutputKind,
    check_not_input,
    plot_error,
    recorded_input,
    recorded_path,
    summary_json,
)
from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineGeometry, TurbineParams

if TYPE_CHECKING:
    from turbinefit.eval.damage import DamageScore

COVERAGE_OUTPUTS = OutputKind("coverage", frozenset({
    "coverage.csv", "sides.csv", "summary.json", "coverage.png", "damage.csv",
    "coverage.geojson", "damage.geojson"}))

#: ``--step``, between samples along a part [m]: from 1 cm (a 60 m blade is 6,000 samples
#: a side; memory grows as keyframes x samples) to 5 m (still several samples on the
#: shortest blade of the catalogue).
STEP = Quantity("step", "m", 0.01, 5.0)
#: ``--gsd``, the resolution a side must be seen at [mm/px].
GSD_MM = Quantity("ground sampling distance", "mm/px", 0.0, 1000.0, lo_open=True)
#: ``--blade-pitch`` and ``--blade-twist`` [deg].
BLADE_ANGLE_DEG = Quantity("blade angle", "deg", -90.0, 90.0)

#: Columns a georeferenced flight's ``coverage.csv`` and ``damage.csv`` end with: WGS84
#: [deg] and altitude [m, the flight's datum] of the photo's camera (coverage) or of the
#: box's point on the turbine (damage).
GEO_COLUMNS = ("latitude", "longitude", "altitude")
#: Columns of ``damage.csv`` (:func:`format_damage_csv`).
DAMAGE_COLUMNS = ("photo", "timestamp", "keyframe", "class", "xmin", "ymin", "xmax", "ymax",
                  "part", "side", "span_m", "span_from_m", "span_to_m", "distance_m",
                  "on_part", "chord", "defect")


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
    """The flight folder ``summary.json`` of a fit names (relative to the fit folder, or
    absolute; :func:`~turbinefit.jobs.outputs.recorded_input`)."""
    path = fit_dir / "summary.json"
    if not path.is_file():
        raise InputError("missing: cannot tell which flight it came from; give --flight", path)
    try:
        name = json.loads(read_text(path)).get("flight")
    except (json.JSONDecodeError, AttributeError):
        name = None
    if not isinstance(name, str):
        raise InputError("names no flight folder; give --flight", path, field="flight")
    for cand in recorded_input(name, fit_dir):
        if (cand / CAMERA_FILE).is_file():
            return cand
    raise InputError(f"its flight folder {name} has no {CAMERA_FILE} here; give --flight",
                     path, field="flight")


def read_fit_output(fit_dir: str | os.PathLike[str],
                    flight_dir: str | os.PathLike[str] | None = None, *,
                    need_camera: bool = True) -> FitOutput:
    """Read a ``fit``/``track`` output folder and its flight's camera (see :class:`FitOutput`;
    ``need_camera=False``: the flight is optional). A flight folder (with ``camera.yaml``)
    is read as its own flight: its measured poses and ``turbine.yaml``.

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
    if flight is None and (fit_dir / CAMERA_FILE).is_file():
        flight = fit_dir  # a flight folder itself: its own poses and turbine.yaml
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
    the summary written, timings [s] and, with a damage CSV, where each box lies."""

    coverage: Coverage
    surface: TurbineSurface
    out_dir: Path
    summary: dict[str, Any]
    timings: dict[str, float] = field(default_factory=dict)
    damage: list[DamageBox] | None = None
    damage_score: DamageScore | None = None


def _geo(georef: Georef | None, world_p: Any) -> list[str]:
    """The :data:`GEO_COLUMNS` cells of points ``world_p`` (N, 3; NaN rows: empty cells),
    one list per point; nothing without a georef."""
    p = np.asarray(world_p, dtype=np.float64).reshape(-1, 3)
    if georef is None:
        return [""] * len(p)
    ok = np.all(np.isfinite(p), axis=1)
    lat, lon, alt = georef.geodetic(np.where(ok[:, None], p, 0.0))
    return [f",{lat[i]:.10f},{lon[i]:.10f},{alt[i]:.3f}" if ok[i] else ",,,"
            for i in range(len(p))]


def format_coverage_csv(coverage: Coverage, timestamps: Any, georef: Georef | None = None,
                        world_T_cam: SE3 | None = None) -> str:
    """The text of ``coverage.csv``; with ``georef`` (and the keyframes' ``world_T_cam``)
    each row ends with the keyframe's camera position in WGS84 (:data:`GEO_COLUMNS`)."""
    lines = [",".join(COVERAGE_COLUMNS + (GEO_COLUMNS if georef is not None else ()))]
    geo = _geo(georef if world_T_cam is not None else None,
               world_T_cam.translation[[r.keyframe for r in coverage.rows]]
               if world_T_cam is not None else np.zeros((len(coverage.rows), 3)))
    for r, g in zip(coverage.rows, geo, strict=True):
        lines.append(f"{float(timestamps[r.keyframe]):.6f},{r.keyframe},{PARTS[r.part]},"
                     f"{r.span_from:.2f},{r.span_to:.2f},{r.visible_m:.2f},{'+'.join(r.sides)},"
                     f"{r.distance_m:.2f},{r.gsd_mm_px:.3f}{g}")
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


Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class DamageBox:
    """One box of a damage CSV on a keyframe's photo, and where it lies on the turbine.

    Attributes:
        photo: the photo's file name as the CSV gives it; keyframe: its keyframe index.
        label: the box's class; box: (left, top, right, bottom) in the CSV's pixels.
        location: :func:`~turbinefit.inspection.surface.locate_box` of the box scaled to
            the camera's pixels.
        defect: the known defect the box shows (the CSV's ``defect`` column; ``""``: none
            or no such column).
    """

    photo: str
    keyframe: int
    label: str
    box: Box
    location: BoxLocation
    defect: str = ""


def _same_photo(a: Path, b: Path) -> bool:
    """Whether two photo files are one (a hard link, as ``import dji`` makes) or hold the
    same bytes (a copy)."""
    try:
        if os.path.samefile(a, b):
            return True
        if a.stat().st_size != b.stat().st_size:
            return False
        return a.read_bytes() == b.read_bytes()
    except OSError:
        return False


def read_damage_boxes(path: Path, photos_dir: Path, fit: FitOutput, camera: PinholeCamera
                      ) -> list[tuple[str, int, str, Box, Box, str]]:
    """The boxes of a damage CSV (:func:`turbinefit.io.regions.read_box_csv`; photos in
    ``photos_dir``) as (photo, keyframe, class, box, the box in the camera's pixels, the
    known defect it shows or ``""``). A photo is a
    keyframe's if its name is the keyframe's timestamp (``images/<t>.jpg`` of a flight
    folder) or if it is the same file as that keyframe's photo (the originals ``import dji``
    linked); boxes drawn on the photo at another size of the same aspect are scaled.

    Raises:
        InputError: naming the CSV row of a photo that is no keyframe of the fit, or whose
            size is not the camera's aspect (and the errors of ``read_box_csv``).
    """
    from turbinefit.io.heatmap_files import keyframe_stem
    from turbinefit.io.images import IMAGE_SUFFIXES
    from turbinefit.io.regions import read_box_csv

    labels = read_box_csv(path, photos_dir)
    stems = {keyframe_stem(float(t)): k for k, t in enumerate(fit.timestamps)}
    keyframe_photos: list[tuple[int, Path]] | None = None
    out = []
    for lab in labels:
        k = stems.get(lab.path.stem)
        if k is None:
            if keyframe_photos is None:  # those of the flight folder's images/ that exist
                img = None if fit.flight_dir is None else fit.flight_dir / IMAGE_DIR
                keyframe_photos = [] if img is None else [
                    (i, img / (stem + suffix)) for stem, i in stems.items()
                    for suffix in IMAGE_SUFFIXES if (img / (stem + suffix)).is_file()]
            k = next((i for i, q in keyframe_photos if _same_photo(lab.path, q)), None)
        if k is None:
            raise InputError(f"photo {lab.path.name} is not the photo of any keyframe of the fit",
                             path=lab.where)
        assert lab.size is not None
        w, h = lab.size
        sx, sy = camera.width / w, camera.height / h
        if abs(sx / sy - 1.0) > 0.01:
            raise InputError(f"photo {lab.path.name} is {w}x{h}, not the shape of the camera's "
                             f"{camera.width}x{camera.height}", path=lab.where)
        names = lab.defects or ("",) * len(lab.boxes)
        for (cls, (x0, y0, x1, y1)), defect in zip(lab.boxes, names, strict=True):
            out.append((lab.path.name, k, cls, (x0, y0, x1, y1),
                        (x0 * sx, y0 * sy, x1 * sx, y1 * sy), defect))
    return out


def format_damage_csv(boxes: list[DamageBox], timestamps: Any,
                      georef: Georef | None = None) -> str:
    """The text of ``damage.csv``: one row per box (:data:`DAMAGE_COLUMNS`; the box in the
    CSV's pixels; empty cells where the box shows no part, side or span); with ``georef``
    each row ends with the box's point on the turbine in WGS84 (:data:`GEO_COLUMNS`, empty
    where the box shows no turbine)."""
    def num(v: float | None, fmt: str) -> str:
        return "" if v is None else format(v, fmt)

    lines = [",".join(DAMAGE_COLUMNS + (GEO_COLUMNS if georef is not None else ()))]
    nan3 = (math.nan, math.nan, math.nan)
    geo = _geo(georef, [d.location.world_p or nan3 for d in boxes])
    for d, g in zip(boxes, geo, strict=True):
        loc = d.location
        lines.append(",".join([
            d.photo, f"{float(timestamps[d.keyframe]):.6f}", str(d.keyframe), d.label,
            *(f"{v:g}" for v in d.box), loc.part or "", loc.side or "",
            num(loc.span_m, ".2f"), num(loc.span_from_m, ".2f"), num(loc.span_to_m, ".2f"),
            num(loc.distance_m, ".2f"), f"{loc.on_part:.2f}", num(loc.chord, ".3f"),
            d.defect]) + g)
    return "\n".join(lines) + "\n"


def coverage_folder(fit_dir: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                    flight_dir: str | os.PathLike[str] | None = None,
                    camera: PinholeCamera | None = None, step: float = 0.5,
                    max_gsd_mm: float = 2.0, blade_pitch: float = 0.0,
                    blade_twist: float = 0.0, damage: str | os.PathLike[str] | None = None,
                    damage_photos: str | os.PathLike[str] | None = None,
                    truth: str | os.PathLike[str] | None = None, plots: bool = True,
                    overwrite: bool = False) -> CoverageReport:
    """What each keyframe of the fit in ``fit_dir`` shows (its fitted poses and turbine, the
    photos' ``camera``, by default that of ``flight_dir`` or of the flight its
    ``summary.json`` names), written to
    ``out_dir``: ``coverage.csv``, ``sides.csv``, ``summary.json`` (per part and side the
    fraction of the span seen, and seen at ``max_gsd_mm`` mm/px or finer) and, unless
    ``plots=False``, ``coverage.png``. Parts are sampled every ``step`` m; blades have pitch
    ``blade_pitch`` and root twist ``blade_twist`` [rad] (0: flat in the rotor plane).
    With ``damage`` (a box CSV, :mod:`turbinefit.io.regions`, of photos in
    ``damage_photos``, default the flight's ``images/``), ``damage.csv`` says where each
    box lies: part, side, span, distance and chord (:func:`read_damage_boxes`,
    :func:`~turbinefit.inspection.surface.locate_box`), and the known defect the box shows
    if the CSV names it. With ``truth`` too (the known defects, ``defects_groundtruth.csv``
    of ``simulate``), the boxes are scored against them
    (:func:`turbinefit.eval.damage.score_damage`): ``summary.json``'s ``damage_score``.

    Raises:
        InputError: bad input or a bad ``out_dir`` (checked first); nothing is written.
    """
    t0 = time.perf_counter()
    fit_dir, out_dir = Path(fit_dir), Path(out_dir)
    step = STEP.check(step, field="--step")
    max_gsd_mm = GSD_MM.check(max_gsd_mm, field="--gsd")
    BLADE_ANGLE_DEG.check(math.degrees(blade_pitch), field="--blade-pitch")
    BLADE_ANGLE_DEG.check(math.degrees(blade_twist), field="--blade-twist")
    if truth is not None and damage is None:
        raise InputError("needs --damage (the boxes to score)", field="--truth")
    inputs = [fit_dir] + [Path(p) for p in (flight_dir, damage, damage_photos, truth)
                          if p is not None]
    COVERAGE_OUTPUTS.check(out_dir, inputs, overwrite)
    fit = read_fit_output(fit_dir, flight_dir, need_camera=camera is None)
    if fit.flight_dir is not None:
        check_not_input(out_dir, [fit.flight_dir])
    cam = camera or fit.camera
    assert cam is not None
    surface = TurbineSurface(fit.turbine, fit.geometry,
                             SurfaceShape(blade_pitch=blade_pitch, blade_twist=blade_twist))
    damage_boxes: list[DamageBox] | None = None
    if damage is not None:
        if damage_photos is None and fit.flight_dir is None:
            raise InputError("needs the flight folder (its images/) or the photos' folder",
                             field="--damage")
        photos = Path(damage_photos) if damage_photos is not None else \
            fit.flight_dir / IMAGE_DIR  # type: ignore[operator]
        damage_boxes = [DamageBox(name, k, cls, box, locate_box(surface, cam,
                                                                fit.world_T_cam[k], cam_box),
                                  defect)
                        for name, k, cls, box, cam_box, defect in read_damage_boxes(
                            Path(damage), photos, fit, cam)]
    score = None
    if truth is not None:
        from turbinefit.eval.damage import score_damage
        from turbinefit.io.defects import read_defects_csv

        assert damage_boxes is not None
        score = score_damage(located_damage(damage_boxes), read_defects_csv(truth).defects)
    t1 = time.perf_counter()
    cov = flight_coverage(surface, cam, fit.world_T_cam, step)
    timings = {"load": t1 - t0, "coverage": time.perf_counter() - t1}
    summary = {
        "turbinefit_version": __version__, "fit": recorded_path(fit_dir, out_dir),
        "flight": None if fit.flight_dir is None else recorded_path(fit.flight_dir, out_dir),
        "keyframes": len(fit.timestamps), "step_m": step, "max_gsd_mm_px": max_gsd_mm,
        "blade_pitch_deg": math.degrees(blade_pitch), "blade_twist_deg": math.degrees(blade_twist),
        "blades": {bl.name: {"model_blade": bl.model_index + 1,
                             "clock_deg": round(bl.clock_deg, 3)} for bl in surface.blades},
        "name_margin_deg": round(name_margin_deg(surface.turbine), 3),
        "coverage": cov.summary(max_gsd_mm), "timing_s": timings,
        "damage_boxes": None if damage_boxes is None else len(damage_boxes),
    }
    if score is not None:
        summary["damage_score"] = {**score.summary(), "truth": str(truth),
                                   "per_defect": score.rows()}
    with COVERAGE_OUTPUTS.writing(out_dir, overwrite) as tmp:
        text = format_coverage_csv(cov, fit.timestamps, fit.georef, fit.world_T_cam)
        write_text_atomic(tmp / "coverage.csv", text, fsync=False)
        if fit.georef is not None:
            write_geojson_twin(tmp / "coverage.csv", text)
        write_text_atomic(tmp / "sides.csv", format_sides_csv(cov, fit.timestamps),
                          fsync=False)
        if damage_boxes is not None:
            text = format_damage_csv(damage_boxes, fit.timestamps, fit.georef)
            write_text_atomic(tmp / "damage.csv", text, fsync=False)
            if fit.georef is not None:
                write_geojson_twin(tmp / "damage.csv", text)
        if plots:
            from turbinefit.plots.inspection import plot_coverage

            try:
                plot_coverage(tmp / "coverage.png", cov, max_gsd_mm,
                              math.sqrt(cam.fx * cam.fy))
            except OSError as exc:
                raise plot_error(exc, out_dir) from exc
        timings["total"] = time.perf_counter() - t0
        write_text_atomic(tmp / "summary.json", summary_json(summary), fsync=False)
    return CoverageReport(cov, surface, out_dir, summary, timings, damage_boxes, score)


def located_damage(boxes: list[DamageBox]) -> list[LocatedDamage]:
    """The boxes as ``damage.csv`` rows (:func:`turbinefit.eval.damage.score_damage`'s)."""
    return [LocatedDamage(d.photo, d.keyframe, d.label, d.location.part, d.location.side,
                          d.location.span_m, d.location.chord, d.location.distance_m, d.defect,
                          (d.box[2] - d.box[0]) * (d.box[3] - d.box[1]))
            for d in boxes]
