"""End-to-end jobs over flight folders: what the CLI commands run.

Each job is one typed function returning a result dataclass; the CLI only parses
arguments, calls it and prints. Outputs are written atomically: everything goes into a
temporary folder next to ``out_dir`` that is renamed into place at the end, so a failure
(bad input, an interrupted run) leaves nothing half-written, and inputs are never
overwritten.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from turbinefit import __version__
from turbinefit.detect import DetectOptions, HeatmapDetector
from turbinefit.errors import InputError
from turbinefit.eval.metrics import Accuracy, accuracy
from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import NonFiniteHeatmapError
from turbinefit.io.atomic import atomic_output_dir, check_output_dir, read_text, write_text_atomic
from turbinefit.io.flight_folder import (
    HEATMAP_DIR,
    IMAGE_DIR,
    HeatmapSource,
    has_heatmaps,
    heatmap_filename,
    keyframe_images,
    read_flight,
)
from turbinefit.io.tum import write_tum
from turbinefit.io.turbine_yaml import write_turbine_yaml
from turbinefit.io.yaml_files import FLOAT_TEXT, safe_load_strict
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import FitResult, fit
from turbinefit.solver.lm import IterationRecord
from turbinefit.solver.tracker import KeyframeError, TrackerConfig, TrackEstimate
from turbinefit.turbine.model import TurbineGeometry, TurbineParams

if TYPE_CHECKING:
    from turbinefit.io.coco import LabelledImage

#: Everything ``fit`` writes into its output folder: all that ``fit --overwrite`` replaces.
FIT_ENTRIES = frozenset({"keyframes.txt", "turbine.yaml", "config.yaml", "summary.json",
                         "scene.png", "reprojections.png", "errors.png", "cost.png"})
#: How the command line asks for an existing non-empty output folder to be replaced.
_OVERWRITE_HINT = "use --overwrite"


@dataclass
class FitReport:
    """What :func:`fit_folder` did.

    Attributes:
        result: the solver's result.
        out_dir: where the outputs were written.
        before, after: accuracy of the initial and optimised estimates (None without
            ground truth).
        timings: seconds spent loading, solving, writing and plotting.
        summary: the dictionary written to ``summary.json``.
    """

    result: FitResult
    out_dir: Path
    before: Accuracy | None
    after: Accuracy | None
    timings: dict[str, float]
    summary: dict[str, Any] = field(default_factory=dict)


def load_fit_config(path: str | os.PathLike[str]) -> FitConfig:
    """Read fit options from a YAML mapping (the ``config.yaml`` that ``fit`` writes).

    Every problem is an :class:`InputError` naming the file (and line or option): a file that
    is missing, a directory, unreadable or not UTF-8; malformed YAML or a duplicate key; an
    unknown option; a value of the wrong type (numbers written like ``1e-5``, which YAML 1.1
    reads as strings, are accepted) or out of range.
    """
    p = Path(path)
    text = read_text(p)
    try:
        data = safe_load_strict(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise InputError(f"malformed YAML: {getattr(exc, 'problem', None) or exc}", p,
                         None if mark is None else mark.line + 1) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError("expected a mapping of fit options", p)
    data.pop("turbinefit_version", None)
    try:
        return FitConfig.from_dict(_typed_options(data, p))
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), p) from None


def _typed_options(data: dict[Any, Any], path: Path) -> dict[str, Any]:
    """``data`` with the types of the numeric options checked (YAML gives any type; the
    dataclass checks ranges and choices): whole numbers for ``int`` options, numbers (or
    numeric text) for ``float`` options, a mapping for ``geometry`` (whose values
    :class:`TurbineGeometry` checks), a list of finite numbers for ``pair_information``.
    Raises InputError naming the option."""
    for key in data:
        if not isinstance(key, str):
            raise InputError(f"option name {key!r} is not a string", path)
    out = dict(data)
    # annotations are strings (postponed evaluation) or, without that, the types themselves
    kinds = {f.name: f.type if isinstance(f.type, str) else getattr(f.type, "__name__", "")
             for f in dataclasses.fields(FitConfig)}

    def number(name: str, v: Any) -> float:
        if isinstance(v, str) and FLOAT_TEXT.fullmatch(v.strip()):
            return float(v)
        if isinstance(v, bool) or not isinstance(v, numbers.Real):
            raise InputError(f"{name}: must be a number (got {v!r})", path)
        return float(v)

    for name, v in data.items():
        kind = kinds.get(name)
        if kind == "int" and (isinstance(v, bool) or not isinstance(v, int)):
            raise InputError(f"{name}: must be a whole number (got {v!r})", path)
        if kind == "float":
            out[name] = number(name, v)
    if "geometry" in data:
        geo = data["geometry"]
        if not isinstance(geo, dict):
            names = ", ".join(f.name for f in dataclasses.fields(TurbineGeometry))
            raise InputError(f"geometry: must be a mapping with keys {names} (got {geo!r})",
                             path)
        for key in geo:
            if not isinstance(key, str):
                raise InputError(f"geometry: option name {key!r} is not a string", path)
    if "pair_information" in data:
        info = data["pair_information"]
        if info is not None:
            if not isinstance(info, list):
                raise InputError("pair_information: must be a list of 36 numbers (a 6x6 "
                                 f"matrix, row-major) or null (got {info!r})", path)
            out["pair_information"] = [number(f"pair_information[{i}]", x)
                                       for i, x in enumerate(info)]
            if not all(math.isfinite(x) for x in out["pair_information"]):
                raise InputError("pair_information: must be finite", path)
    return out


def _check_out_dir(out_dir: Path, inputs: list[Path]) -> None:
    try:
        out = out_dir.resolve()
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symbolic-link loop
        raise InputError(f"cannot resolve the output path: {exc}", out_dir) from None
    for src in inputs:
        try:
            s = src.resolve()
        except (OSError, RuntimeError) as exc:
            raise InputError(f"cannot resolve the input path: {exc}", src) from None
        if out == s or s.is_relative_to(out) or out.is_relative_to(s):
            raise InputError(f"output folder would overwrite or nest inside the input {src}",
                             out_dir)


def _only_fit_outputs(folder: Path) -> str | None:
    """None if ``folder`` holds nothing but files ``fit`` writes (safe to replace)."""
    for entry in folder.iterdir():
        if entry.name not in FIT_ENTRIES or entry.is_dir():
            return f"{entry.name!r} is not an output of turbinefit fit"
    return None


def fit_folder(
    flight_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: FitConfig | None = None,
    *,
    plots: bool = True,
    overwrite: bool = False,
    progress: Callable[[IterationRecord], None] | None = None,
    config_path: str | os.PathLike[str] | None = None,
    from_images: bool | None = None,
    model: str | os.PathLike[str] | None = None,
    detect_progress: bool = False,
    detect_options: DetectOptions | None = None,
) -> FitReport:
    """Fit the flight in ``flight_dir`` and write the results to ``out_dir``.

    Writes ``keyframes.txt`` (optimised ``world_T_cam``, TUM), ``turbine.yaml`` (fitted
    theta), ``summary.json``, ``config.yaml`` (the resolved options) and, unless
    ``plots=False``, ``scene.png``, ``reprojections.png``, ``errors.png`` (with ground
    truth) and ``cost.png``.

    ``out_dir`` is checked before anything is read: it must not be, contain or lie inside
    ``flight_dir`` (or ``config_path``, the file ``config`` was read from, if given); a file
    or symbolic link there is refused; an existing non-empty folder is refused unless
    ``overwrite``, and even then unless it holds nothing but the files above (a guard
    against ``--overwrite`` on a wrong path).

    Heat-maps come from ``flight_dir/heatmaps/``, or are detected from the photos in
    ``flight_dir/images/`` (:func:`image_heatmap_source`, ONNX ``model`` or the shipped
    one, with ``detect_options``) when ``from_images`` is True, or when it is None and
    the flight has photos but no ``heatmaps/``. Nothing is written into ``flight_dir``.
    """
    cfg = config or FitConfig()
    flight_dir = Path(flight_dir)
    out_dir = Path(out_dir)
    _check_out_dir(out_dir, [flight_dir] + ([] if config_path is None else [Path(config_path)]))
    check_output_dir(out_dir, overwrite, _only_fit_outputs, _OVERWRITE_HINT)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    if from_images is None:
        from_images = not has_heatmaps(flight_dir) and (flight_dir / IMAGE_DIR).is_dir()
    source = (image_heatmap_source(flight_dir, model, progress=detect_progress,
                                   detect_options=detect_options)
              if from_images else None)
    flight = read_flight(flight_dir, heatmaps=source)
    timings["load"] = time.perf_counter() - t0

    t1 = time.perf_counter()
    try:
        result = fit(flight, cfg, callback=progress)
    except NonFiniteHeatmapError as exc:
        stamp = flight.timestamps[exc.keyframe]
        raise InputError("heat-map contains NaN or inf",
                         flight_dir / HEATMAP_DIR / heatmap_filename(stamp)) from None
    timings["solve"] = time.perf_counter() - t1

    before = after = None
    if flight.gt_world_T_cam is not None and flight.gt_turbine is not None:
        before = accuracy(flight.world_T_cam, flight.turbine, flight.gt_world_T_cam,
                          flight.gt_turbine, cfg.geometry)
        after = accuracy(result.world_T_cam, result.turbine, flight.gt_world_T_cam,
                         flight.gt_turbine, cfg.geometry)

    summary = make_summary(flight_dir, flight, result, before, after, timings)
    summary["heatmaps"] = (f"detected from {IMAGE_DIR}/ with {model or 'the shipped model'}"
                           if from_images else "heatmaps/")
    t2 = time.perf_counter()
    with atomic_output_dir(out_dir, overwrite=overwrite, may_replace=_only_fit_outputs) as tmp:
        write_tum(tmp / "keyframes.txt", flight.timestamps, result.world_T_cam)
        write_turbine_yaml(tmp / "turbine.yaml", result.turbine,
                           comment="turbinefit: fitted turbine parameters (metres, radians)")
        cfg_dict = {"turbinefit_version": __version__, **result.config.to_dict()}
        write_text_atomic(tmp / "config.yaml", yaml.safe_dump(cfg_dict, sort_keys=False),
                          fsync=False)
        if plots:
            t3 = time.perf_counter()
            try:
                write_plots(tmp, flight, result)
            except OSError as exc:  # e.g. no space left on the device
                raise InputError(f"cannot write the plots: {exc.strerror or exc}",
                                 out_dir) from exc
            timings["plots"] = time.perf_counter() - t3
        timings["write"] = time.perf_counter() - t2 - timings.get("plots", 0.0)
        timings["total"] = time.perf_counter() - t0
        summary["timing_s"] = {k: round(v, 4) for k, v in timings.items()}
        write_text_atomic(tmp / "summary.json", json.dumps(summary, indent=2) + "\n",
                          fsync=False)
    return FitReport(result, out_dir, before, after, timings, summary)


def make_summary(flight_dir: Path, flight: Flight, result: FitResult, before: Accuracy | None,
                 after: Accuracy | None, timings: dict[str, float]) -> dict[str, Any]:
    """The content of ``summary.json``."""
    summary: dict[str, Any] = {
        "turbinefit_version": __version__,
        "flight": str(flight_dir),
        "num_keyframes": flight.num_keyframes,
        "heatmap_size": [flight.camera.width, flight.camera.height],
        "config": result.config.to_dict(),
        "solver": {
            "initial_cost": result.initial_cost,
            "final_cost": result.final_cost,
            "initial_terms": result.initial_terms,
            "final_terms": result.final_terms,
            "iterations": result.iterations,
            "rounds": result.rounds,
            "termination": result.termination,
            "num_residuals": result.num_residuals,
            "history": [
                {"stage": h.stage, "round": h.round, "iteration": h.iteration, "cost": h.cost,
                 "step_norm": h.step_norm, "mu": h.mu, "accepted": h.accepted,
                 "time_s": round(h.time_s, 5)}
                for h in result.history
            ],
        },
        "turbine": {"initial": flight.turbine.to_dict(), "optimised": result.turbine.to_dict()},
        "timing_s": {k: round(v, 4) for k, v in timings.items()},
    }
    if before is not None and after is not None:
        summary["accuracy"] = {"before": before.to_dict(), "after": after.to_dict()}
    return summary


def write_plots(out: Path, flight: Flight, result: FitResult) -> None:
    """The figures of a fit (imports matplotlib only when called)."""
    from turbinefit import plots
    from turbinefit.geometry.se3 import pose_errors

    geometry = result.config.geometry
    plots.plot_scene(
        out / "scene.png", initial_poses=flight.world_T_cam, optimised_poses=result.world_T_cam,
        initial_turbine=flight.turbine, optimised_turbine=result.turbine,
        gt_poses=flight.gt_world_T_cam, gt_turbine=flight.gt_turbine, geometry=geometry)
    plots.plot_reprojections(
        out / "reprojections.png", camera=flight.camera, heatmaps=flight.heatmaps,
        keyframes=plots.choose_keyframes(flight.num_keyframes, 6),
        initial_poses=flight.world_T_cam, initial_turbine=flight.turbine,
        optimised_poses=result.world_T_cam, optimised_turbine=result.turbine,
        geometry=geometry, timestamps=flight.timestamps)
    if flight.gt_world_T_cam is not None:
        p0, r0 = pose_errors(flight.world_T_cam, flight.gt_world_T_cam)
        p1, r1 = pose_errors(result.world_T_cam, flight.gt_world_T_cam)
        plots.plot_errors(out / "errors.png", timestamps=flight.timestamps,
                          initial_pos_err=p0, optimised_pos_err=p1,
                          initial_rot_err_deg=np.degrees(r0), optimised_rot_err_deg=np.degrees(r1))
    if result.history:
        plots.plot_cost_history(out / "cost.png", [h.cost for h in result.history],
                                [h.stage for h in result.history])


def simulate_folder(
    out_dir: str | os.PathLike[str],
    config: Any = None,
    *,
    overwrite: bool = False,
    progress: bool = False,
    images: bool = False,
) -> Path:
    """Simulate a flight (:func:`turbinefit.sim.simulate_flight`) and write it as a flight
    folder with ground truth; the resolved simulation settings go to ``simulation.yaml``.
    With ``images``, photos of every keyframe rendered from the ground truth
    (:func:`turbinefit.sim.images.render_flight_images`, scene from the seed) go to
    ``images/<t>.png``.

    The whole folder, ``simulation.yaml`` included, is written atomically. ``out_dir`` is
    checked before simulating: a file or symbolic link is refused, and an existing
    non-empty folder unless ``overwrite`` and it is a flight folder (e.g. one this wrote).
    """
    from turbinefit.io.flight_folder import SIMULATION_FILE, check_flight_destination, write_flight
    from turbinefit.sim.scenario import SimConfig, simulate_flight

    cfg = config or SimConfig()
    out = Path(out_dir)
    check_flight_destination(out, overwrite, _OVERWRITE_HINT)
    flight = simulate_flight(cfg, progress=progress)
    settings = {"turbinefit_version": __version__, **_plain(dataclasses.asdict(cfg))}
    photos = None
    if images:
        from turbinefit.sim.images import render_flight_images

        assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
        photos = render_flight_images(flight.camera, flight.gt_world_T_cam,
                                      flight.gt_turbine.to_vector(), cfg.seed, cfg.geometry,
                                      progress=progress)
    write_flight(flight, out, overwrite=overwrite,
                 extra_texts={SIMULATION_FILE: yaml.safe_dump(settings, sort_keys=False)},
                 images=photos)
    return out


# ---- detection ---------------------------------------------------------------------------

#: Heat-maps detected for a fit are at most this wide [px]; a larger camera is resized.
FIT_DETECT_WIDTH = 320


def detection_camera(camera: PinholeCamera, width: int = FIT_DETECT_WIDTH) -> PinholeCamera:
    """The camera of heat-maps detected from photos taken with ``camera``: the same, or
    resized to ``width`` px wide if it is wider (detection at a working resolution)."""
    if camera.width <= width:
        return camera
    return camera.resized(width, max(1, round(camera.height * width / camera.width)))


def _photo_size_error(img: np.ndarray, camera: PinholeCamera) -> str | None:
    """Why a photo does not fit ``camera.yaml``, or None."""
    if img.shape[:2] == (camera.height, camera.width):
        return None
    return (f"photo is {img.shape[1]}x{img.shape[0]} but camera.yaml is "
            f"{camera.width}x{camera.height}")


def image_heatmap_source(flight_dir: str | os.PathLike[str],
                         model: str | os.PathLike[str] | None = None,
                         width: int = FIT_DETECT_WIDTH, progress: bool = False,
                         threads: int | None = None,
                         detect_options: DetectOptions | None = None) -> HeatmapSource:
    """A :data:`~turbinefit.io.flight_folder.HeatmapSource` detecting the heat-maps of
    every keyframe from ``flight_dir/images/`` with the ONNX ``model`` (default: shipped)
    and ``detect_options`` (default: as the model's metadata says).

    Photos must be at the size of ``camera.yaml``; heat-maps are made at that size, or at
    ``width`` px wide (camera resized to match) if the camera is wider. ``threads``:
    photos detected at once, one inference thread each (:class:`~turbinefit.detect.
    DetectorPool`; None = one per core).
    """
    from tqdm import tqdm

    from turbinefit.heatmaps import HeatmapStack
    from turbinefit.io.images import read_image

    root = Path(flight_dir)

    def source(camera: PinholeCamera, timestamps: np.ndarray) -> tuple[PinholeCamera, HeatmapStack]:
        paths = keyframe_images(root, timestamps)
        pool = (detect_options or DetectOptions()).pool(model, threads)
        cam = detection_camera(camera, width)

        def detect(det: HeatmapDetector, p: Path) -> np.ndarray:
            img = read_image(p)
            why = _photo_size_error(img, camera)
            if why is not None:
                raise InputError(why, path=p)
            return det.detect(img, size=(cam.width, cam.height))

        maps = np.empty((len(paths), 7, cam.height, cam.width), dtype=np.float32)
        for k, m in enumerate(tqdm(pool.map(detect, paths), total=len(paths), desc="detecting",
                                   unit="img", leave=False, disable=None if progress else True)):
            maps[k] = m
        return cam, HeatmapStack(maps)

    return source


#: What ``detect`` writes for each photo: ``<stem>.npy`` heat-maps and ``<stem>.png`` overlay.
_DETECT_SUFFIXES = (".npy", ".png")


def _only_detect_outputs(folder: Path) -> str | None:
    for entry in folder.iterdir():
        if entry.suffix not in _DETECT_SUFFIXES or not entry.is_file():
            return f"{entry.name!r} is not an output of turbinefit detect"
    return None


@dataclass
class DetectReport:
    """What :func:`detect_images` did: ``count`` photos detected, their outputs written to
    ``out_dir``, in ``seconds`` (wall clock: checks, decoding, detection and writing) by
    ``workers`` photos at once."""

    out_dir: Path
    count: int
    seconds: float
    workers: int = 1


def detect_images(inputs: list[Path], out_dir: str | os.PathLike[str],
                  model: str | os.PathLike[str] | None = None, *, overwrite: bool = False,
                  progress: bool = False, threads: int | None = None,
                  detect_options: DetectOptions | None = None) -> DetectReport:
    """Detect heat-maps in photos (files, or folders of ``.png`` / ``.jpg``) and write, per
    photo, ``<stem>.npy`` (float32 (7, H, W) at the photo's size, channels of
    :data:`turbinefit.heatmaps.CHANNEL_NAMES`) and ``<stem>.png`` (the photo with the
    heat-maps overlaid) into ``out_dir``, atomically.

    Everything is checked before any photo is processed: the inputs exist (an empty folder
    is an error), no two photos share a stem, the output is not an input folder, the model
    loads; a photo that cannot be decoded stops the job with nothing written.
    ``detect_options``: as :class:`~turbinefit.detect.DetectOptions` (default: as the
    model's metadata says). ``threads``: photos detected (and written) at once, one
    inference thread each (:class:`~turbinefit.detect.DetectorPool`; None = one per core).
    """
    from tqdm import tqdm

    from turbinefit.detect import overlay, unique_stems
    from turbinefit.io.images import check_image, encode_png, list_images, read_image

    out = Path(out_dir)
    paths = list_images([Path(p) for p in inputs])
    unique_stems(paths)
    for p in paths:  # headers only: a non-image file fails here, before any work
        check_image(p)
    _check_out_dir(out, [p for p in inputs if Path(p).is_dir()] + paths)
    check_output_dir(out, overwrite, _only_detect_outputs, _OVERWRITE_HINT)
    pool = (detect_options or DetectOptions()).pool(model, threads)
    t0 = time.perf_counter()
    with atomic_output_dir(out, overwrite=overwrite, may_replace=_only_detect_outputs) as tmp:

        def detect(det: HeatmapDetector, p: Path) -> None:
            img = read_image(p)
            maps = det.detect(img)
            try:
                with open(tmp / f"{p.stem}.npy", "wb") as f:
                    np.save(f, maps, allow_pickle=False)
                (tmp / f"{p.stem}.png").write_bytes(encode_png(overlay(img, maps)))
            except OSError as e:
                raise InputError(f"cannot write: {e.strerror or e}", path=out / p.stem) from e

        # disable=None: no bar when stderr is not a terminal
        for _ in tqdm(pool.map(detect, paths), total=len(paths), desc="detecting", unit="img",
                      disable=None if progress else True):
            pass
    return DetectReport(out, len(paths), time.perf_counter() - t0, pool.workers)


@dataclass
class EvaluateReport:
    """What :func:`evaluate_labels` measured: :meth:`InstanceStats.summary
    <turbinefit.eval.detection.InstanceStats.summary>` over ``photos`` labelled photos
    with the ONNX ``model``; distances in pixels of the photos resized to ``input_width``
    (the model's input width, as the held-out benchmark measures them)."""

    summary: dict[str, float]
    photos: int
    model: Path
    input_width: int
    threshold: float
    tip_threshold: float
    out: Path | None
    tip_shift: float = 0.0
    flip: bool = False
    zoom: bool = False


def evaluate_labels(labels: str | os.PathLike[str], images_dir: str | os.PathLike[str],
                    model: str | os.PathLike[str] | None = None, *,
                    out: str | os.PathLike[str] | None = None, overwrite: bool = False,
                    match_px: float = 5.0, progress: bool = False,
                    threads: int | None = None,
                    detect_options: DetectOptions | None = None) -> EvaluateReport:
    """Detection metrics of the ONNX ``model`` (default: shipped) on photos labelled with
    COCO keypoints (:func:`turbinefit.io.coco.read_coco_keypoints`; any number of
    turbines per photo, photos without any are negatives), and, with ``out``, a JSON
    report written atomically.

    Everything is checked before any photo is run: the labels, every photo's header and
    size against its label entry, the model, and ``out`` (not an input; an existing file
    only with ``overwrite``). ``detect_options``: as
    :class:`~turbinefit.detect.DetectOptions` (default: as the model's metadata says).
    """
    from tqdm import tqdm

    from turbinefit.eval.detection import InstanceStats
    from turbinefit.heatmaps.targets import TARGET_SIGMA_PX, render_keypoint_heatmaps
    from turbinefit.io.coco import read_coco_keypoints
    from turbinefit.io.images import check_image, read_image

    if not (math.isfinite(match_px) and match_px > 0):
        raise InputError(f"must be a positive number, got {match_px}", field="match_px")
    items = read_coco_keypoints(labels, images_dir)
    if not items:
        raise InputError("no images in the label file", path=Path(labels))
    for item in items:  # headers only: a wrong file fails here, before any work
        item.check_size(*check_image(item.path))
    out_path = None if out is None else Path(out)
    if out_path is not None:
        inputs = {Path(labels).resolve(), *(i.path.resolve() for i in items)}
        if out_path.resolve() in inputs:
            raise InputError("is an input; the report needs another file", path=out_path)
        if out_path.is_dir():
            raise InputError("is a folder; the report is a JSON file", path=out_path)
        if out_path.exists() and not overwrite:
            raise InputError("exists (use --overwrite to replace it)", path=out_path)
    pool = (detect_options or DetectOptions()).pool(model, threads)
    det = pool.detector
    info = det.info
    stats = InstanceStats(threshold=info.threshold, tip_threshold=info.tip_threshold,
                          match_px=match_px, px_scale=info.output_scale)

    def detect(d: HeatmapDetector, item: LabelledImage) -> tuple[tuple[int, ...], np.ndarray]:
        img = read_image(item.path)
        return img.shape, d.detect_small(img)

    for item, (shape, pred) in zip(items, tqdm(pool.map(detect, items), total=len(items),
                                               desc="evaluating", unit="img",
                                               disable=None if progress else True),
                                   strict=True):
        gh, gw = pred.shape[1:]
        h0, w0 = shape[:2]
        # pixel centres: u in the photo is (u + 0.5) * gw / w0 - 0.5 on the heat-map grid
        uv = [(t.uv + 0.5) * np.array([gw / w0, gh / h0]) - 0.5 for t in item.turbines]
        vis = [t.visibility for t in item.turbines]
        target = render_keypoint_heatmaps(gh, gw, uv, [v > 0 for v in vis], TARGET_SIGMA_PX)
        stats.add(pred, target, np.array(uv).reshape(-1, 6, 2), np.array(vis).reshape(-1, 6))
    summary = stats.summary()
    if out_path is not None:
        report = {"turbinefit_version": __version__, "model": str(det.path),
                  "labels": str(labels), "input_width": info.input_width,
                  "threshold": info.threshold, "tip_threshold": info.tip_threshold,
                  "tip_shift_px": det.tip_shift, "flip": det.flip, "zoom": det.zoom,
                  "match_px": match_px,  # NaN (undefined) is written as null
                  "metrics": {k: v if math.isfinite(v) else None for k, v in summary.items()}}
        write_text_atomic(out_path, json.dumps(report, indent=2) + "\n")
    return EvaluateReport(summary, len(items), Path(det.path), info.input_width,
                          info.threshold, info.tip_threshold, out_path, det.tip_shift,
                          det.flip, det.zoom)


#: Everything ``track`` writes into its output folder: all that ``track --overwrite`` replaces.
TRACK_ENTRIES = frozenset({"causal.txt", "keyframes.txt", "turbine.yaml", "latency.csv",
                           "latency.png", "config.yaml", "summary.json", "scene.png",
                           "errors.png"})


def _only_track_outputs(folder: Path) -> str | None:
    for entry in folder.iterdir():
        if entry.name not in TRACK_ENTRIES or entry.is_dir():
            return f"{entry.name!r} is not an output of turbinefit track"
    return None


@dataclass
class TrackReport:
    """What :func:`track_folder` did.

    Attributes:
        out_dir: where the outputs were written.
        estimates: the tracker's answer to each keyframe, in time order.
        world_T_cam: (N,) final estimates (window at its last, earlier keyframes moved
            with it by back-substitution).
        turbine: the final turbine.
        latency_ms: (N,) wall time of each keyframe's update [ms].
        causal, final: accuracy of the causal and final estimates (None without ground
            truth); ``batch`` is not run here (see ``benchmarks/bench_track.py``).
        summary: the dictionary written to ``summary.json``.
    """

    out_dir: Path
    estimates: list[TrackEstimate]
    world_T_cam: SE3
    turbine: TurbineParams
    latency_ms: np.ndarray
    causal: Accuracy | None
    final: Accuracy | None
    summary: dict[str, Any] = field(default_factory=dict)


def latency_stats(latency_ms: np.ndarray, window: int | None = None) -> dict[str, float]:
    """Median, 90th / 99th percentile, max [ms] and the slope of a least-squares line
    through latency against keyframe index [ms per 1000 keyframes]; also that slope after
    the first ``window`` keyframes (``steady_*``: the window is full, so any growth left
    would come from the flight's length)."""
    lat = np.asarray(latency_ms, dtype=np.float64)
    if lat.size == 0:
        return {}

    def slope(v: np.ndarray) -> float:
        if v.size < 2:
            return 0.0
        return float(np.polyfit(np.arange(v.size, dtype=np.float64), v, 1)[0]) * 1000.0

    out = {"median_ms": float(np.median(lat)), "p90_ms": float(np.percentile(lat, 90)),
           "p99_ms": float(np.percentile(lat, 99)), "max_ms": float(lat.max()),
           "mean_ms": float(lat.mean()), "slope_ms_per_1000_keyframes": slope(lat)}
    if window is not None and lat.size > window + 1:
        out["steady_slope_ms_per_1000_keyframes"] = slope(lat[window:])
    return out


def track_folder(
    flight_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: TrackerConfig | None = None,
    *,
    plots: bool = True,
    overwrite: bool = False,
    progress: Callable[[TrackEstimate, int], None] | None = None,
    config_path: str | os.PathLike[str] | None = None,
    from_images: bool | None = None,
    model: str | os.PathLike[str] | None = None,
    detect_options: DetectOptions | None = None,
) -> TrackReport:
    """Replay the flight in ``flight_dir`` keyframe by keyframe through a :class:`Tracker`.

    Writes into ``out_dir`` (atomically, checked as :func:`fit_folder` checks it):
    ``causal.txt`` (TUM: each keyframe's estimate when it arrived), ``keyframes.txt`` and
    ``turbine.yaml`` (the final estimates, as ``fit`` writes them), ``latency.csv``
    (``timestamp,latency_ms``: wall time of each update), ``config.yaml``,
    ``summary.json`` (latency figures, accuracy of the causal and final estimates with
    ground truth) and, unless ``plots=False``, ``latency.png``, ``errors.png`` (with
    ground truth) and ``scene.png``.

    With photos (``images/`` and no ``heatmaps/``, or ``from_images``) each keyframe's photo
    is read and run through the CNN (ONNX ``model`` or the shipped one, with
    ``detect_options``) as it arrives, inside the update (its latency includes
    detection). ``progress(estimate, total)`` is called after every keyframe.
    """
    from turbinefit.solver.tracker import Tracker

    cfg = config or TrackerConfig()
    flight_dir = Path(flight_dir)
    out = Path(out_dir)
    _check_out_dir(out, [flight_dir] + ([] if config_path is None else [Path(config_path)]))
    check_output_dir(out, overwrite, _only_track_outputs, _OVERWRITE_HINT)
    if from_images is None:
        from_images = not has_heatmaps(flight_dir) and (flight_dir / IMAGE_DIR).is_dir()
    photos: list[Path] = []
    detector: Callable[[np.ndarray], np.ndarray] | None = None
    if from_images:
        flight, photos, detector = _photo_flight(flight_dir, model, detect_options)
    else:
        flight = read_flight(flight_dir)
    tracker = Tracker(flight.camera, flight.turbine, cfg, detector=detector)
    n = flight.num_keyframes
    for k in range(n):
        try:
            if photos:
                from turbinefit.io.images import read_image

                img = read_image(photos[k])
                est = tracker.update(flight.timestamps[k], flight.world_T_cam[k], image=img)
            else:
                est = tracker.update(flight.timestamps[k], flight.world_T_cam[k],
                                     flight.heatmaps[k])
        except KeyframeError as exc:
            where = (photos[k] if photos else
                     flight_dir / HEATMAP_DIR / heatmap_filename(flight.timestamps[k]))
            raise InputError(exc.reason, where) from None
        if progress is not None:
            progress(est, n)
    final_poses = tracker.world_T_cam()
    causal_poses = tracker.causal_world_T_cam()
    turbine = tracker.turbine
    latency = np.array([e.update_s * 1e3 for e in tracker.estimates])
    causal = final = before = frozen = None
    geometry = cfg.fit.geometry
    if flight.gt_world_T_cam is not None and flight.gt_turbine is not None:
        before = accuracy(flight.world_T_cam, flight.turbine, flight.gt_world_T_cam,
                          flight.gt_turbine, geometry)
        causal = accuracy(causal_poses, turbine, flight.gt_world_T_cam, flight.gt_turbine,
                          geometry)
        final = accuracy(final_poses, turbine, flight.gt_world_T_cam, flight.gt_turbine,
                         geometry)
        frozen = accuracy(tracker.world_T_cam(back_substitution=False), turbine,
                          flight.gt_world_T_cam, flight.gt_turbine, geometry)
    cfg_dict = {"turbinefit_version": __version__, **tracker_config_dict(cfg)}
    summary: dict[str, Any] = {
        "turbinefit_version": __version__,
        "flight": str(flight_dir),
        "num_keyframes": n,
        "heatmap_size": [flight.camera.width, flight.camera.height],
        "heatmaps": (f"detected from {IMAGE_DIR}/ with {model or 'the shipped model'} "
                     "(inside each update)" if from_images else "heatmaps/"),
        "config": _plain(tracker_config_dict(cfg)),
        "latency": latency_stats(latency, cfg.window),
        "iterations_mean": float(np.mean([e.iterations for e in tracker.estimates])),
        "theta_prior_active_at_end": tracker.theta_prior_active,
        "turbine": {"initial": flight.turbine.to_dict(), "final": turbine.to_dict()},
    }
    last = tracker.estimates[-1]
    if last.theta_covariance is not None:
        summary["turbine"]["final_sigma"] = dict(zip(
            TurbineParams.NAMES, np.sqrt(np.diag(last.theta_covariance)).tolist(), strict=True))
    if before is not None and causal is not None and final is not None and frozen is not None:
        summary["accuracy"] = {"initial": before.to_dict(), "causal": causal.to_dict(),
                               "final": final.to_dict(),
                               "final_without_back_substitution": frozen.to_dict()}
    with atomic_output_dir(out, overwrite=overwrite, may_replace=_only_track_outputs) as tmp:
        write_tum(tmp / "causal.txt", flight.timestamps, causal_poses,
                  comment="turbinefit track: each keyframe's estimate when it arrived")
        write_tum(tmp / "keyframes.txt", flight.timestamps, final_poses)
        write_turbine_yaml(tmp / "turbine.yaml", turbine,
                           comment="turbinefit: fitted turbine parameters (metres, radians)")
        rows = "".join(f"{t:.6f},{ms:.3f}\n" for t, ms in zip(flight.timestamps, latency,
                                                               strict=True))
        write_text_atomic(tmp / "latency.csv", "timestamp,latency_ms\n" + rows, fsync=False)
        write_text_atomic(tmp / "config.yaml", yaml.safe_dump(_plain(cfg_dict), sort_keys=False),
                          fsync=False)
        write_text_atomic(tmp / "summary.json", json.dumps(summary, indent=2) + "\n",
                          fsync=False)
        if plots:
            try:
                _track_plots(tmp, flight, final_poses, causal_poses, turbine, latency, geometry)
            except OSError as exc:
                raise InputError(f"cannot write the plots: {exc.strerror or exc}", out) from exc
    return TrackReport(out, list(tracker.estimates), final_poses, turbine, latency, causal,
                       final, summary)


def tracker_config_dict(cfg: TrackerConfig) -> dict[str, Any]:
    """The tracker options as a plain mapping (``fit`` nested as :meth:`FitConfig.to_dict`)."""
    d = {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg) if f.name != "fit"}
    return {"tracker": _plain(d), "fit": cfg.fit.to_dict()}


def _photo_flight(flight_dir: Path, model: str | os.PathLike[str] | None,
                  detect_options: DetectOptions | None = None
                  ) -> tuple[Flight, list[Path], Callable[[np.ndarray], np.ndarray]]:
    """The flight with its photos in place of heat-maps: the photos' paths, checked, and a
    detector making heat-maps at the fit's working size (see :func:`image_heatmap_source`).
    The flight's own heat-map stack is an empty placeholder."""
    from turbinefit.heatmaps import HeatmapStack
    from turbinefit.io.images import check_image

    found: dict[str, Any] = {}

    def source(camera: PinholeCamera, timestamps: np.ndarray) -> tuple[PinholeCamera, HeatmapStack]:
        paths = keyframe_images(flight_dir, timestamps)
        for p in paths:  # headers only, before any work
            check_image(p)
        cam = detection_camera(camera)
        found.update(paths=paths, camera=camera, cam=cam)
        blank = np.zeros((7, cam.height, cam.width), dtype=np.float32)
        return cam, HeatmapStack([blank] * len(paths))

    flight = read_flight(flight_dir, heatmaps=source)
    # spinning off: the solver needs the cores between photos
    detector = (detect_options or DetectOptions()).detector(model, spinning=False)
    camera, cam, paths = found["camera"], found["cam"], found["paths"]

    def detect(img: np.ndarray) -> np.ndarray:
        why = _photo_size_error(img, camera)
        if why is not None:
            raise KeyframeError(-1, why)
        return detector.detect(img, size=(cam.width, cam.height))

    return flight, paths, detect


def _track_plots(out: Path, flight: Flight, final_poses: SE3, causal_poses: SE3,
                 turbine: TurbineParams, latency: np.ndarray, geometry: TurbineGeometry) -> None:
    from turbinefit import plots
    from turbinefit.geometry.se3 import pose_errors

    plots.plot_latency(out / "latency.png", latency)
    plots.plot_scene(
        out / "scene.png", initial_poses=flight.world_T_cam, optimised_poses=final_poses,
        initial_turbine=flight.turbine, optimised_turbine=turbine,
        gt_poses=flight.gt_world_T_cam, gt_turbine=flight.gt_turbine, geometry=geometry)
    if flight.gt_world_T_cam is not None:
        p0, r0 = pose_errors(flight.world_T_cam, flight.gt_world_T_cam)
        p1, r1 = pose_errors(final_poses, flight.gt_world_T_cam)
        pc, rc = pose_errors(causal_poses, flight.gt_world_T_cam)
        plots.plot_errors(out / "errors.png", timestamps=flight.timestamps,
                          initial_pos_err=p0, optimised_pos_err=p1,
                          initial_rot_err_deg=np.degrees(r0),
                          optimised_rot_err_deg=np.degrees(r1),
                          causal_pos_err=pc, causal_rot_err_deg=np.degrees(rc))


def _plain(obj: Any) -> Any:
    """Tuples to lists, recursively (for YAML)."""
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    return obj
