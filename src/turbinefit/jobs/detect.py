"""The ``detect`` job: heat-maps of photos with the CNN, written beside an overlay of each."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from turbinefit.detect import DetectOptions, HeatmapDetector, overlay, unique_stems
from turbinefit.errors import InputError
from turbinefit.io.images import check_image, encode_png, list_images, read_image
from turbinefit.jobs.outputs import DETECT_OUTPUTS


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

    out = Path(out_dir)
    paths = list_images([Path(p) for p in inputs])
    unique_stems(paths)
    for p in paths:  # headers only: a non-image file fails here, before any work
        check_image(p)
    DETECT_OUTPUTS.check(out, [p for p in inputs if Path(p).is_dir()] + paths, overwrite)
    pool = (detect_options or DetectOptions()).pool(model, threads)
    t0 = time.perf_counter()
    with DETECT_OUTPUTS.writing(out, overwrite) as tmp:

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
