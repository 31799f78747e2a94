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

if TYPE_CHECKING:
    from turbinefit.io.coco import LabelledImage


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
