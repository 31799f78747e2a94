"""The ``view`` job: one self-contained HTML page of a fit (:mod:`turbinefit.view`), with
its flight's initial and ground-truth estimates and photos, a plan and coverage.

**What it reads.** ``source`` is a fit (or track) output folder, or a *mission folder*
holding one in ``fit/`` (else ``track/``), with optional ``plan/`` (a ``plan`` output)
and ``coverage/`` (a ``coverage`` output) beside it: :func:`find_inputs`. ``--plan`` and
``--coverage`` name those folders explicitly (and win over a mission's). The fit's flight
(``--flight``, or the one its ``summary.json`` names) gives the camera, the initial poses
and turbine, the ground truth and the photos; without it the page shows the fit alone and
says so. Without a coverage folder, coverage is computed from the fit's poses and the
flight's camera (as ``turbinefit coverage`` does) unless ``coverage=False``.

**What it writes.** One HTML file, atomically (:func:`~turbinefit.io.atomic.write_bytes_atomic`),
refused before any work if it is an input, inside one, a folder, or an existing file
without ``overwrite`` (and then only a page this job wrote is replaced):
:func:`~turbinefit.jobs.outputs.check_output_file`. The inputs are the fit, plan, coverage
and flight folders: a page may be written into a mission folder, beside them.

The readers of the ``plan`` and ``coverage`` outputs (``waypoints.csv``, ``sides.csv``)
are here, the one job that reads them back; every number in them passes a
:class:`~turbinefit.io.quantities.Quantity`.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera, reduced_size
from turbinefit.geometry.se3 import SE3
from turbinefit.inspection.coverage import COVERED_PARTS, SideGrid, flight_coverage, side_names
from turbinefit.inspection.surface import PARTS, SurfaceShape, TurbineSurface
from turbinefit.io.atomic import read_text, write_bytes_atomic
from turbinefit.io.flight_folder import (
    CAMERA_FILE,
    IMAGE_DIR,
    KEYFRAMES_FILE,
    TIMESTAMP_TOLERANCE,
    TURBINE_FILE,
    FlightFolder,
    read_flight_folder,
)
from turbinefit.io.heatmap_files import keyframe_stem
from turbinefit.io.quantities import COORDINATE, Quantity
from turbinefit.io.tum import read_tum_lines
from turbinefit.io.turbine_yaml import read_turbine_yaml
from turbinefit.jobs.coverage import BLADE_ANGLE_DEG, GSD_MM, STEP, FitOutput, read_fit_output
from turbinefit.jobs.outputs import check_output_file
from turbinefit.turbine.model import TurbineGeometry, TurbineParams, model_points

#: ``--thumbnail``, the width of the embedded photos [px]: from a glance (64) to the
#: width of a screen (4096; the page grows by about 1 MB per 100 photos at 400 px).
THUMBNAIL = Quantity("thumbnail width", "px", 64, 4096, integer=True)
#: ``--photos``: how many keyframes are drawn as frusta with their photo embedded.
PHOTOS = Quantity("number of photos", "", 0, 100_000, integer=True)
#: A best ground sampling distance in ``sides.csv`` [mm/px] (a camera far away resolves
#: metres a pixel: no upper bound but a sane one).
BEST_GSD = Quantity("best ground sampling distance", "mm/px", 0.0, 1e9, lo_open=True)
#: JPEG quality of the thumbnails (Pillow's scale).
JPEG_QUALITY = 82
#: Frusta drawn when no photo is embedded (``photos=0``).
FRUSTA_WITHOUT_PHOTOS = 200
#: The fit's folder in a mission folder, in order of preference, and the others.
MISSION_FITS = ("fit", "track")
MISSION_PLAN, MISSION_COVERAGE = "plan", "coverage"
#: The verdicts a fit's ``summary.json`` may give.
VERDICTS = ("ok", "doubtful", "failed")
#: Model points of a plan's turbine further than this [m] from the fit's: a note says the
#: plan was made round another turbine.
PLAN_TURBINE_TOLERANCE_M = 0.5


@dataclass(frozen=True)
class ViewInputs:
    """The folders a page is made of (:func:`find_inputs`): the fit, and optionally a plan,
    a coverage and the mission folder holding them."""

    fit_dir: Path
    plan_dir: Path | None = None
    coverage_dir: Path | None = None
    mission_dir: Path | None = None


def _is_fit(folder: Path) -> bool:
    """Whether ``folder`` is a fit's or track's output (poses and turbine, not a plan or a
    flight, which hold them too)."""
    return ((folder / KEYFRAMES_FILE).is_file() and (folder / TURBINE_FILE).is_file()
            and not (folder / "waypoints.csv").exists() and not (folder / CAMERA_FILE).exists())


def find_inputs(source: str | os.PathLike[str], plan_dir: str | os.PathLike[str] | None = None,
                coverage_dir: str | os.PathLike[str] | None = None) -> ViewInputs:
    """The folders of a page: ``source`` is a fit (or track) output, or a mission folder
    (``fit/`` or ``track/``, with ``plan/`` and ``coverage/`` taken when present); an
    explicit ``plan_dir`` or ``coverage_dir`` wins.

    Raises:
        InputError: ``source`` is neither (one line saying what it looks like instead), or a
            mission's ``fit/`` is not a fit.
    """
    src = Path(source)
    if not src.is_dir():
        raise InputError("not found" if not src.exists() else
                         "is not a folder (give a fit output or a mission folder)", src)
    plan = None if plan_dir is None else Path(plan_dir)
    cov = None if coverage_dir is None else Path(coverage_dir)
    if _is_fit(src):
        return ViewInputs(src, plan, cov)
    fits = [src / name for name in MISSION_FITS if (src / name).is_dir()]
    if fits:
        fit = next((f for f in fits if _is_fit(f)), None)
        if fit is None:
            raise InputError(f"mission folder whose {fits[0].name}/ is not a fit output "
                             f"(no {KEYFRAMES_FILE} and {TURBINE_FILE})", src)
        if plan is None and (src / MISSION_PLAN).is_dir():
            plan = src / MISSION_PLAN
        if cov is None and (src / MISSION_COVERAGE).is_dir():
            cov = src / MISSION_COVERAGE
        return ViewInputs(fit, plan, cov, src)
    if (src / "waypoints.csv").exists():
        hint = "; it is a plan output: view its fit with --plan"
    elif (src / "sides.csv").exists():
        hint = "; it is a coverage output: view its fit with --coverage"
    elif (src / CAMERA_FILE).exists():
        hint = "; it is a flight folder: view the output of turbinefit fit"
    else:
        hint = ""
    raise InputError("is neither a fit output (keyframes.txt, turbine.yaml) nor a mission "
                     f"folder (fit/, plan/, coverage/){hint}", src)


# ---------------------------------------------------------------- plan and coverage outputs


def _csv_rows(path: Path, columns: str) -> list[tuple[int, dict[str, str]]]:
    """The rows of a CSV file whose header is ``columns``, with their line numbers."""
    text = read_text(path)
    lines = text.splitlines()
    if not lines or lines[0].strip() != columns:
        raise InputError(f"expected the header {columns!r}", path, line=1)
    reader = csv.DictReader(io.StringIO(text))
    out = []
    for row in reader:
        if None in row or any(v is None for v in row.values()):
            raise InputError(f"expected {len(columns.split(','))} columns", path,
                             line=reader.line_num)
        out.append((reader.line_num, row))
    return out


def read_plan_output(plan_dir: Path) -> tuple[np.ndarray, SE3, list[str], TurbineParams]:
    """A ``plan`` output: its waypoints (M, 3) in flying order, its photos' ``world_T_cam``
    (``keyframes.txt``), one caption per photo and the turbine it was planned round.

    Raises:
        InputError: a missing or bad file, or as many photos in ``waypoints.csv`` as poses
            in ``keyframes.txt`` not being so.
    """
    from turbinefit.jobs.plan import WAYPOINT_COLUMNS

    if not plan_dir.is_dir():
        raise InputError("plan output folder not found", plan_dir)
    path = plan_dir / "waypoints.csv"
    points, labels = [], []
    for line, row in _csv_rows(path, WAYPOINT_COLUMNS):
        points.append([COORDINATE.parse(row[c], path, line, c) for c in ("x", "y", "z")])
        if row["photo"] not in ("0", "1"):
            raise InputError(f"must be 0 or 1, got {row['photo']!r}", path, line, "photo")
        if row["photo"] == "1":
            part, side = row["part"].replace("_", " "), row["side"].replace("_", " ")
            span = COORDINATE.parse(row["span_m"], path, line, "span_m")
            labels.append(f"{part}, {side}, {'height' if part == 'tower' else 'span'} "
                          f"{span:.1f} m")
    if len(points) < 2:
        raise InputError("a path needs at least 2 waypoints", path)
    traj = read_tum_lines(plan_dir / KEYFRAMES_FILE)
    if len(traj.timestamps) != len(labels):
        raise InputError(f"{len(traj.timestamps)} photo poses, but {path.name} has "
                         f"{len(labels)} photos", plan_dir / KEYFRAMES_FILE)
    return np.array(points), traj.poses, labels, read_turbine_yaml(plan_dir / TURBINE_FILE)


def read_coverage_output(cov_dir: Path, turbine: TurbineParams, geometry: TurbineGeometry
                         ) -> tuple[list[SideGrid], float, TurbineSurface]:
    """A ``coverage`` output: the best GSD per side and span bin of each blade and the tower
    (``sides.csv``), the resolution it counted as covered and the surface (blade pitch and
    twist of ``summary.json``) it named the sides on, for ``turbine``.

    Raises:
        InputError: a missing or bad file, naming the row and column of a bad value.
    """
    if not cov_dir.is_dir():
        raise InputError("coverage output folder not found", cov_dir)
    spath = cov_dir / "summary.json"
    try:
        summary = json.loads(read_text(spath))
    except json.JSONDecodeError as exc:
        raise InputError(f"not JSON: {exc.msg}", spath, line=exc.lineno) from None
    if not isinstance(summary, dict):
        raise InputError("expected a JSON object", spath)
    max_gsd = GSD_MM.check(summary.get("max_gsd_mm_px"), spath, field="max_gsd_mm_px")
    pitch, twist = (math.radians(BLADE_ANGLE_DEG.check(summary.get(k, 0.0), spath, field=k))
                    for k in ("blade_pitch_deg", "blade_twist_deg"))
    path = cov_dir / "sides.csv"
    bins: dict[int, dict[tuple[float, float], dict[int, float]]] = {
        p: {} for p in range(len(COVERED_PARTS))}
    for line, row in _csv_rows(path, "part,side,span_from_m,span_to_m,best_gsd_mm_px,timestamp"):
        if row["part"] not in COVERED_PARTS:
            raise InputError(f"unknown part {row['part']!r} (one of {', '.join(COVERED_PARTS)})",
                             path, line, "part")
        part = COVERED_PARTS.index(row["part"])
        sides = side_names(part)
        if row["side"] not in sides:
            raise InputError(f"unknown side {row['side']!r} of {row['part']} (one of "
                             f"{', '.join(sides)})", path, line, "side")
        lo, hi = (COORDINATE.parse(row[c], path, line, c) for c in ("span_from_m", "span_to_m"))
        if not hi > lo:
            raise InputError(f"span_to_m {hi:g} is not above span_from_m {lo:g}", path, line,
                             "span_to_m")
        gsd = (math.inf if row["best_gsd_mm_px"] == "" else
               BEST_GSD.parse(row["best_gsd_mm_px"], path, line, "best_gsd_mm_px"))
        bins[part].setdefault((lo, hi), {})[sides.index(row["side"])] = gsd
    grids = []
    for part, spans in bins.items():
        keys = sorted(spans)
        centres = np.array([0.5 * (a + b) for a, b in keys])
        step = float(np.median([b - a for a, b in keys])) if keys else STEP.hi
        best = np.full((4, len(keys)), np.inf)
        for j, key in enumerate(keys):
            for k, g in spans[key].items():
                best[k, j] = g
        grids.append(SideGrid(part, centres, step, best, np.full(best.shape, -1, dtype=np.int64)))
    surface = TurbineSurface(turbine, geometry, SurfaceShape(blade_pitch=pitch, blade_twist=twist))
    return grids, max_gsd, surface


# ---------------------------------------------------------------- photos


def read_thumbnails(flight_dir: Path, timestamps: np.ndarray, keyframes: list[int],
                    camera: PinholeCamera, width: int) -> tuple[list[Any], int]:
    """JPEG thumbnails at most ``width`` px wide of the photos of ``keyframes`` in the flight's
    ``images/`` (:class:`~turbinefit.view.scene.Photo`), and how many of them had no
    photo.

    Raises:
        InputError: naming a photo that cannot be read or is not the camera's shape.
    """
    from turbinefit.io.images import (
        IMAGE_SUFFIXES,
        check_image,
        encode_jpeg,
        read_image,
        resize_image,
    )
    from turbinefit.view.scene import Photo

    img_dir = flight_dir / IMAGE_DIR
    present = {p.name for p in img_dir.iterdir()} if img_dir.is_dir() else set()
    tw, th = reduced_size(camera.width, camera.height, width)  # never enlarged
    jobs = []
    for k in keyframes:
        stem = keyframe_stem(float(timestamps[k]))
        name = next((stem + s for s in IMAGE_SUFFIXES if stem + s in present), None)
        if name is not None:
            jobs.append((k, img_dir / name))

    def thumbnail(job: tuple[int, Path]) -> Photo:
        k, path = job
        w, h = check_image(path)  # the header as stored (an EXIF turn may swap the sides)
        aspect = camera.width / camera.height
        if min(abs(a / b / aspect - 1.0) for a, b in ((w, h), (h, w))) > 0.01:
            raise InputError(f"photo is {w}x{h}, not the shape of the camera's "
                             f"{camera.width}x{camera.height}", path)
        img = read_image(path, reduce_to=(tw, th))
        if img.shape[:2] != (th, tw):
            img = resize_image(img, tw, th)
        return Photo(k, encode_jpeg(img, JPEG_QUALITY), tw, th)

    with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1)) as pool:
        photos = list(pool.map(thumbnail, jobs))
    return photos, len(keyframes) - len(jobs)


# ---------------------------------------------------------------- the job


@dataclass
class ViewReport:
    """What :func:`view_page` did.

    Attributes:
        out: the page written; size_bytes: its size.
        inputs: the folders it was made of; flight_dir: the flight (None: not found).
        keyframes, shown, photos: keyframes of the fit, drawn as frusta, with a photo.
        coverage: where the coverage colours came from (a folder, ``computed`` or None).
        verdict: the fit's verdict (None: its summary gives none).
        notes: what the page says is missing, and why.
        timings: seconds per stage.
    """

    out: Path
    size_bytes: int
    inputs: ViewInputs
    flight_dir: Path | None
    keyframes: int
    shown: int
    photos: int
    coverage: str | None
    verdict: str | None
    notes: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)


def _verdict(fit_dir: Path) -> str | None:
    """The verdict of a fit's ``summary.json`` (None: no summary, or no verdict in it)."""
    path = fit_dir / "summary.json"
    if not path.exists():
        return None
    try:
        summary = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"not JSON: {exc.msg}", path, line=exc.lineno) from None
    verdict = summary.get("verdict") if isinstance(summary, dict) else None
    if verdict is not None and verdict not in VERDICTS:
        raise InputError(f"unknown verdict {verdict!r} (one of {', '.join(VERDICTS)})", path,
                         field="verdict")
    return verdict


def _flight_matching(fit: FitOutput) -> FlightFolder | None:
    """The fit's flight folder, read, if it has one; refused if its keyframes are not the
    fit's."""
    if fit.flight_dir is None:
        return None
    flight = read_flight_folder(fit.flight_dir)
    t_fit, t_flight = np.asarray(fit.timestamps), flight.timestamps
    if t_fit.shape != t_flight.shape or not np.allclose(t_fit, t_flight, rtol=0.0,
                                                         atol=TIMESTAMP_TOLERANCE):
        raise InputError(f"{len(t_flight)} keyframes that are not the fit's {len(t_fit)} "
                         f"(in {fit.fit_dir / KEYFRAMES_FILE}); give the fit's --flight",
                         flight.root / KEYFRAMES_FILE)
    return flight


def _turbine_text(t: TurbineParams) -> str:
    return (f"tower {t.tower_height:.2f} m, blades {abs(t.blade_length):.2f} m, heading "
            f"{math.degrees(t.heading) % 360:.1f}\u00b0, blade rotation "
            f"{math.degrees(t.blade_rotation) % 120:.1f}\u00b0")


def view_page(source: str | os.PathLike[str], out: str | os.PathLike[str], *,
              flight_dir: str | os.PathLike[str] | None = None,
              plan_dir: str | os.PathLike[str] | None = None,
              coverage_dir: str | os.PathLike[str] | None = None, coverage: bool = True,
              max_gsd_mm: float | None = None, thumbnail: int = 400, photos: int = 200,
              title: str | None = None, overwrite: bool = False) -> ViewReport:
    """Write the interactive page of the fit (or mission) ``source`` to ``out`` (see the
    module docstring): ``photos`` keyframes spread evenly over the flight drawn as frusta,
    with their photos embedded ``thumbnail`` px wide; coverage coloured at ``max_gsd_mm``
    (default: the coverage folder's, else 2 mm/px).

    Raises:
        InputError: bad input or a bad ``out`` (checked before any work); nothing is written.
    """
    from turbinefit.eval.metrics import accuracy
    from turbinefit.plots.common import choose_keyframes
    from turbinefit.view.page import is_view_page, page_html
    from turbinefit.view.scene import (
        ESTIMATE_COLOURS,
        CameraSet,
        CoverageView,
        PlanView,
        ViewScene,
        scene_data,
    )

    t0 = time.perf_counter()
    thumbnail = int(THUMBNAIL.check(thumbnail, field="--thumbnail"))
    photos = int(PHOTOS.check(photos, field="--photos"))
    if max_gsd_mm is not None:
        max_gsd_mm = GSD_MM.check(max_gsd_mm, field="--gsd")
    out = Path(out)
    inputs = find_inputs(source, plan_dir, coverage_dir)
    # a mission folder itself is no input: the page may sit beside its sub-folders
    given = [inputs.fit_dir] + [Path(p) for p in (
        flight_dir, inputs.plan_dir, inputs.coverage_dir) if p is not None]

    def ours(path: Path) -> bool:
        with path.open("rb") as f:
            return is_view_page(f.read(4096))

    check_output_file(out, given, overwrite, "page", ours)
    fit = read_fit_output(inputs.fit_dir, flight_dir, need_camera=False)
    if fit.flight_dir is not None:
        check_output_file(out, [fit.flight_dir], overwrite, "page", ours)
    flight = _flight_matching(fit)
    camera = flight.camera if flight is not None else None
    notes: list[str] = []
    if flight is None:
        notes.append("The fit's flight folder was not found (give --flight): no initial or "
                     "ground-truth estimates, no photos, no computed coverage; frusta drawn "
                     "4:3, 60\u00b0 wide.")
    n = len(fit.timestamps)
    sets = [CameraSet("optimised", "optimised cameras", ESTIMATE_COLOURS["optimised"],
                      fit.world_T_cam)]
    skeletons = []
    if flight is not None:
        sets.append(CameraSet("initial", "initial cameras (GPS/IMU)", ESTIMATE_COLOURS["initial"],
                              flight.keyframes.poses))
        if flight.turbine is not None:
            skeletons.append(("initial", "initial turbine", ESTIMATE_COLOURS["initial"],
                              flight.turbine))
        if flight.gt_world_T_cam is not None:
            sets.append(CameraSet("ground_truth", "ground-truth cameras",
                                  ESTIMATE_COLOURS["ground_truth"], flight.gt_world_T_cam))
        if flight.gt_turbine is not None:
            skeletons.append(("ground_truth", "ground-truth turbine",
                              ESTIMATE_COLOURS["ground_truth"], flight.gt_turbine))
    verdict = _verdict(fit.fit_dir)
    facts = [("fit", f"{n} keyframes \u00b7 {fit.fit_dir}"), ("turbine", _turbine_text(fit.turbine))]
    if flight is not None and flight.gt_world_T_cam is not None and flight.gt_turbine is not None:
        errs = [accuracy(p, t, flight.gt_world_T_cam, flight.gt_turbine, fit.geometry)
                for p, t in ((flight.keyframes.poses, flight.turbine or fit.turbine),
                             (fit.world_T_cam, fit.turbine))]
        facts.append(("error vs ground truth",
                      f"position {errs[0].position_error_m:.3f} \u2192 {errs[1].position_error_m:.3f} m, "
                      f"orientation {errs[0].orientation_error_deg:.2f} \u2192 "
                      f"{errs[1].orientation_error_deg:.2f}\u00b0"))
    t1 = time.perf_counter()

    cov_view = None
    if inputs.coverage_dir is not None:
        grids, cov_gsd, surface = read_coverage_output(inputs.coverage_dir, fit.turbine,
                                                       fit.geometry)
        cov_view = CoverageView(grids, max_gsd_mm or cov_gsd, surface, str(inputs.coverage_dir))
    elif coverage and camera is not None:
        surface = TurbineSurface(fit.turbine, fit.geometry)
        cov = flight_coverage(surface, camera, fit.world_T_cam)
        cov_view = CoverageView(cov.grids, max_gsd_mm or 2.0, surface,
                                "computed from the fit and its camera")
    if cov_view is not None:
        fine = {PARTS[g.part]: float(np.mean(g.covered(cov_view.max_gsd_mm))) for g in cov_view.grids}
        facts.append((f"covered at \u2264 {cov_view.max_gsd_mm:g} mm/px",
                      ", ".join(f"{p.replace('_', ' ')} {100 * v:.0f} %" for p, v in fine.items())))
    plan_view = None
    if inputs.plan_dir is not None:
        path, poses, labels, plan_turbine = read_plan_output(inputs.plan_dir)
        plan_view = PlanView(path, poses, labels, str(inputs.plan_dir))
        moved = np.max(np.linalg.norm(model_points(plan_turbine.to_vector(), fit.geometry)[0]
                                      - model_points(fit.turbine.to_vector(), fit.geometry)[0],
                                      axis=1))
        if moved > PLAN_TURBINE_TOLERANCE_M:
            notes.append(f"The plan was made round another turbine: its model points lie up to "
                         f"{moved:.1f} m from this fit's.")
        facts.append(("plan", f"{len(labels)} photos, path "
                      f"{np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)):.0f} m"))
    t2 = time.perf_counter()

    shown = choose_keyframes(n, photos if photos else FRUSTA_WITHOUT_PHOTOS)
    embedded: list[Any] = []
    if photos and flight is not None and camera is not None:
        embedded, missing = read_thumbnails(flight.root, fit.timestamps, shown, camera, thumbnail)
        if not embedded:
            notes.append(f"The flight has no photos in {IMAGE_DIR}/.")
        elif missing:
            notes.append(f"{missing} of the {len(shown)} keyframes chosen have no photo.")
    if verdict in ("doubtful", "failed"):
        notes.insert(0, f"The fit's verdict is {verdict}: see its summary.json for why.")
    t3 = time.perf_counter()
    scene = ViewScene(
        title=title or f"turbinefit: {(inputs.mission_dir or inputs.fit_dir).resolve().name}",
        facts=facts, turbine=fit.turbine, geometry=fit.geometry,
        timestamps=np.asarray(fit.timestamps, dtype=np.float64), camera=camera, sets=sets,
        shown=shown, skeletons=skeletons, photos=embedded, coverage=cov_view, plan=plan_view,
        verdict=verdict, notes=notes)
    page = page_html(scene_data(scene)).encode("utf-8")
    write_bytes_atomic(out, page)
    t4 = time.perf_counter()
    timings = {"read": t1 - t0, "coverage_plan": t2 - t1, "photos": t3 - t2, "page": t4 - t3,
               "total": t4 - t0}
    return ViewReport(out, len(page), inputs, fit.flight_dir, n, len(shown), len(embedded),
                      None if cov_view is None else cov_view.source, verdict, notes, timings)
