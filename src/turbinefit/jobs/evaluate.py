"""The ``evaluate`` job: detection metrics of the CNN on photos labelled with COCO
keypoints (e.g. a user's own photos, to see how the shipped model does on them)."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from turbinefit import __version__
from turbinefit.detect import DetectOptions, HeatmapDetector
from turbinefit.errors import InputError
from turbinefit.io.atomic import write_text_atomic
from turbinefit.jobs.outputs import finite_json

if TYPE_CHECKING:
    from turbinefit.io.coco import LabelledImage


def _report_json(report: dict) -> str:
    """The text of a JSON report: strict JSON, undefined (NaN) figures written as null."""
    return json.dumps(finite_json(report), indent=2, allow_nan=False) + "\n"


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
                  "refine": det.refine,
                  "match_px": match_px, "metrics": summary}
        write_text_atomic(out_path, _report_json(report))
    return EvaluateReport(summary, len(items), Path(det.path), info.input_width,
                          info.threshold, info.tip_threshold, out_path, det.tip_shift,
                          det.flip, det.zoom)


@dataclass
class RegionReport:
    """What :func:`evaluate_regions` measured: :meth:`RegionStats.summary
    <turbinefit.eval.regions.RegionStats.summary>` (``{"overall": figures, class:
    figures}``) over ``photos`` photos labelled with boxes or masks, with the ONNX
    ``model``; ``out`` and ``sheet``: the files written, if any."""

    summary: dict[str, dict[str, float]]
    photos: int
    model: Path
    threshold: float
    grow: float
    out: Path | None
    sheet: Path | None


def _check_output(path: Path | None, inputs: set[Path], overwrite: bool, what: str) -> None:
    if path is None:
        return
    if path.resolve() in inputs:
        raise InputError(f"is an input; the {what} needs another file", path=path)
    if path.is_dir():
        raise InputError(f"is a folder; the {what} is a file", path=path)
    if path.exists() and not overwrite:
        raise InputError("exists (use --overwrite to replace it)", path=path)


def evaluate_regions(images_dir: str | os.PathLike[str], *,
                     boxes: str | os.PathLike[str] | None = None,
                     masks: str | os.PathLike[str] | None = None,
                     model: str | os.PathLike[str] | None = None,
                     out: str | os.PathLike[str] | None = None,
                     sheet: str | os.PathLike[str] | None = None, worst: int = 12,
                     grow: float = 0.05, overwrite: bool = False, progress: bool = False,
                     threads: int | None = None,
                     detect_options: DetectOptions | None = None) -> RegionReport:
    """Figures of the ONNX ``model`` (default: shipped) on photos labelled with boxes (a
    CSV, or a COCO file whose ``bbox`` or ``segmentation`` (polygons or RLE) are read,
    ``boxes``) or masks (a folder of label PNGs, ``masks``; :mod:`turbinefit.io.regions`),
    per class and overall (:mod:`turbinefit.eval.regions`: line mass inside the box grown by
    ``grow`` of its size on each side, or the outline or mask; the skeleton of outlines
    and masks covered; photos where anything is found; point peaks outside),
    and, with ``out``, a JSON report (also each photo's figures) and, with ``sheet``, a
    PNG contact sheet of the ``worst`` photos (least line mass inside) with their
    heat-maps and regions (white) overlaid.

    Everything is checked before any photo is run: the labels (every box inside its
    image, every photo present), every photo's and mask's header (sizes agree), the model
    and the outputs; a bad input raises :class:`InputError` naming the file and row.
    """
    from tqdm import tqdm

    from turbinefit.detect import overlay
    from turbinefit.eval.regions import (
        RegionStats,
        box_region,
        grow_box,
        mask_region,
        polygon_region,
    )
    from turbinefit.geometry.camera import reduced_size
    from turbinefit.io.atomic import write_bytes_atomic
    from turbinefit.io.images import check_image, encode_png, read_image
    from turbinefit.io.regions import RegionLabel, decode_rle, read_region_labels
    from turbinefit.plots.sheet import contact_sheet, draw_outline

    if not (math.isfinite(grow) and 0 <= grow <= 1):
        raise InputError(f"must be between 0 and 1, got {grow}", field="grow")
    labels = read_region_labels(boxes, masks, images_dir)
    sizes = []
    for lab in labels:  # headers only: a wrong file fails here, before any work
        w, h = check_image(lab.path)
        lab.check_size(w, h, None if lab.mask is None else check_image(lab.mask))
        sizes.append((w, h))
    out_path = None if out is None else Path(out)
    sheet_path = None if sheet is None else Path(sheet)
    inputs = {p.resolve() for lab in labels for p in (lab.path, lab.mask) if p is not None}
    inputs |= {Path(x).resolve() for x in (boxes, masks) if x is not None}
    _check_output(out_path, inputs, overwrite, "report")
    _check_output(sheet_path, inputs, overwrite, "contact sheet")
    if out_path is not None and sheet_path is not None and out_path.resolve() == sheet_path.resolve():
        raise InputError("the report and the contact sheet need two files", path=out_path)
    pool = (detect_options or DetectOptions()).pool(model, threads)
    det = pool.detector
    stats = RegionStats(det.info.threshold, det.info.tip_threshold)

    def region(lab: RegionLabel, size: tuple[int, int], map_wh: tuple[int, int]) -> np.ndarray:
        if lab.mask is not None:
            return mask_region(read_image(lab.mask).max(axis=2) > 0, map_wh)
        reg = box_region([grow_box(b, grow, *size) for _, b in lab.boxes], size, map_wh)
        if lab.polygons:
            reg |= polygon_region([xy for _, xy in lab.polygons], size, map_wh)
        for _, rle in lab.rles:
            reg |= mask_region(decode_rle(rle), map_wh)
        return reg

    def run(d: HeatmapDetector, job: tuple[RegionLabel, tuple[int, int]]
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lab, size = job
        img = read_image(lab.path, reduce_to=reduced_size(*size, max(d.photo_width, 320)))
        maps = d.detect_small(img)
        return img, maps, region(lab, size, (maps.shape[2], maps.shape[1]))

    jobs = list(zip(labels, sizes, strict=True))
    for (lab, _), (_, maps, reg) in zip(jobs, tqdm(pool.map(run, jobs), total=len(jobs),
                                                   desc="evaluating", unit="img",
                                                   disable=None if progress else True),
                                        strict=True):
        stats.add(str(lab.path), lab.classes, maps, reg, mask=lab.outlined)
    summary = stats.summary()
    if sheet_path is not None:
        tiles, captions = [], []
        for k in stats.worst(worst):
            img, maps, reg = run(det, jobs[k])
            tiles.append(draw_outline(overlay(img, maps), reg))
            p = stats.photos[k]
            captions.append(f"{jobs[k][0].path.name} {'/'.join(p.classes) or 'negative'} "
                            f"inside {p.line_mass_inside:.2f}")
        write_bytes_atomic(sheet_path, encode_png(contact_sheet(tiles, captions)))

    if out_path is not None:
        report = {"turbinefit_version": __version__, "model": str(det.path),
                  "boxes": None if boxes is None else str(boxes),
                  "masks": None if masks is None else str(masks), "grow": grow,
                  "threshold": det.info.threshold, "tip_threshold": det.info.tip_threshold,
                  "tip_shift_px": det.tip_shift, "flip": det.flip, "zoom": det.zoom,
                  "refine": det.refine,
                  "metrics": summary,
                  "photos": [{"photo": p.name, "classes": list(p.classes),
                              "line_mass_inside": p.line_mass_inside,
                              "skeleton_covered": p.skeleton_covered, "found": p.found,
                              "peaks": p.peaks, "peaks_outside": p.peaks_outside}
                             for p in stats.photos]}
        write_text_atomic(out_path, _report_json(report))
    return RegionReport(summary, len(labels), Path(det.path), det.info.threshold, grow,
                        out_path, sheet_path)
