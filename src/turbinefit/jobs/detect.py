"""The ``detect`` job: heat-maps of photos with the CNN, written beside an overlay of each.

The maps are written at the net's own resolution (:meth:`HeatmapDetector.map_size`: 160 x
120 for a 4:3 photo and the shipped model, whatever the photo's size), or at most
``max_size`` px wide; map pixel ``(j, i)`` is photo pixel ``u = (j + 0.5) W / w - 0.5``,
``v = (i + 0.5) H / h - 0.5`` (the photo's camera resized to the maps, as a flight folder
reads them). The overlay is at most :data:`OVERLAY_WIDTH` px wide. A JPEG is decoded at
the size it is used at (the larger of the overlay's and :attr:`HeatmapDetector.photo_width`,
DCT-scaled: :func:`turbinefit.io.images.read_image`), so a 20 MP photo costs a few tens
of megabytes and milliseconds, not a full decode; other formats are decoded in full.
"""

from __future__ import annotations

import os
import time
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from turbinefit.detect import DetectOptions, HeatmapDetector, overlay, unique_stems
from turbinefit.errors import InputError
from turbinefit.geometry.camera import reduced_size
from turbinefit.io.atomic import write_error
from turbinefit.io.heatmap_files import WRITTEN_HEATMAP_DTYPE
from turbinefit.io.images import (
    encode_png,
    image_size,
    list_images,
    read_image,
    resize_image,
)
from turbinefit.io.limits import MIN_IMAGE_SIDE
from turbinefit.jobs.outputs import DETECT_OUTPUTS

#: The overlay PNG is at most this wide [px] (the photo's width if it is narrower): four
#: times the shipped net's maps, and as wide as the photo the detector uses (a JPEG is
#: decoded once, at 1/8 of 20 MP).
OVERLAY_WIDTH = 640


@dataclass
class DetectReport:
    """What :func:`detect_images` did: ``count`` photos detected, their outputs written to
    ``out_dir``, in ``seconds`` (wall clock: checks, decoding, detection and writing) by
    ``workers`` photos at once."""

    out_dir: Path
    count: int
    seconds: float
    workers: int = 1

    @property
    def photos_per_second(self) -> float:
        return self.count / max(self.seconds, 1e-9)


def output_size(det: HeatmapDetector, width: int, height: int,
                max_size: int | None = None) -> tuple[int, int]:
    """(width, height) of the maps ``detect`` writes for a ``width`` x ``height`` photo:
    the net's own (:meth:`HeatmapDetector.map_size`), or the photo scaled to at most
    ``max_size`` px wide; never larger than the photo."""
    if max_size is not None:
        return reduced_size(width, height, max_size)
    w, h = det.map_size(width, height)
    return (w, h) if w <= width and h <= height else (width, height)


def detect_images(inputs: list[Path], out_dir: str | os.PathLike[str],
                  model: str | os.PathLike[str] | None = None, *, overwrite: bool = False,
                  progress: bool = False, threads: int | None = None,
                  detect_options: DetectOptions | None = None,
                  max_size: int | None = None) -> DetectReport:
    """Detect heat-maps in photos (files, or folders of ``.png`` / ``.jpg``) and write, per
    photo, ``<stem>.npy`` (float16 (7, h, w), :func:`output_size`, channels of
    :data:`turbinefit.heatmaps.CHANNEL_NAMES`) and ``<stem>.png`` (the photo with the
    heat-maps overlaid, at most :data:`OVERLAY_WIDTH` px wide) into ``out_dir``,
    atomically.

    Everything is checked before any photo is processed: the inputs exist (an empty folder
    is an error), no two photos share a stem, the output is not an input folder, the model
    loads; a photo that cannot be decoded stops the job with nothing written.
    ``detect_options``: as :class:`~turbinefit.detect.DetectOptions` (default: as the
    model's metadata says). ``threads``: photos detected (and written) at once, one
    inference thread each (:class:`~turbinefit.detect.DetectorPool`; None = one per core).
    ``max_size``: maps at most this wide [px] instead of the net's own size.
    """
    from tqdm import tqdm

    if max_size is not None and max_size < 1:
        raise ValueError(f"max_size must be at least 1, got {max_size}")
    out = Path(out_dir)
    paths = list_images([Path(p) for p in inputs])
    unique_stems(paths)
    sizes = [image_size(p) for p in paths]  # headers only: a non-image fails here
    DETECT_OUTPUTS.check(out, [p for p in inputs if Path(p).is_dir()] + paths, overwrite)
    pool = (detect_options or DetectOptions()).pool(model, threads)
    for p, (w, h) in zip(paths, sizes, strict=True):  # maps a flight folder would refuse
        mw, mh = output_size(pool.detector, w, h, max_size)
        if min(mw, mh) < MIN_IMAGE_SIDE:
            raise InputError(f"a {w}x{h} photo gives heat-maps of {mw}x{mh} px; each side must "
                             f"be at least {MIN_IMAGE_SIDE} px (a larger --max-size, or a less "
                             "elongated photo)", path=p)
    t0 = time.perf_counter()
    with DETECT_OUTPUTS.writing(out, overwrite) as tmp:

        def detect(det: HeatmapDetector, item: tuple[Path, tuple[int, int]]) -> None:
            p, (w, h) = item
            ov = reduced_size(w, h, OVERLAY_WIDTH)
            img = read_image(p, reduce_to=reduced_size(w, h, max(ov[0], det.photo_width)))
            maps = det.detect(img, size=output_size(det, w, h, max_size))
            picture = encode_png(overlay(resize_image(img, *ov), maps), compress_level=1)
            try:
                with open(tmp / f"{p.stem}.npy", "wb") as f:
                    np.save(f, maps.astype(WRITTEN_HEATMAP_DTYPE), allow_pickle=False)
                (tmp / f"{p.stem}.png").write_bytes(picture)
            except OSError as e:
                raise write_error(e, out / p.stem) from e

        # closing: on an exception (a signal) here, the running detections end before the
        # temporary folder they write into is removed. disable=None: no bar when stderr is
        # not a terminal
        with closing(pool.map(detect, zip(paths, sizes, strict=True))) as done:
            for _ in tqdm(done, total=len(paths), desc="detecting", unit="img",
                          disable=None if progress else True):
                pass
    return DetectReport(out, len(paths), time.perf_counter() - t0, pool.workers)
