"""Where a flight's heat-maps come from: one :class:`HeatmapSource`, two kinds.

* :class:`FileHeatmaps`: the flight folder's ``heatmaps/<t>.npy`` (memory-mapped);
* :class:`PhotoHeatmaps`: detected from the flight folder's ``images/<t>.png|.jpg`` with the
  heat-map CNN (:mod:`turbinefit.detect`), at a working resolution.

A source serves a whole flight (:meth:`HeatmapSource.stack`, for ``fit``) and a stream
alike (:meth:`HeatmapSource.keyframe`, one keyframe at a time, for ``track``); the solver
and the tracker only ever see heat-maps. :func:`open_heatmaps` picks the source of a
flight folder as the commands do.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.edges import PhotoStack
from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera, reduced_size
from turbinefit.heatmaps import HeatmapStack, HeatmapValueError
from turbinefit.io.flight_folder import IMAGE_DIR, FlightFolder, has_heatmaps, keyframe_images
from turbinefit.io.heatmap_files import ValueCheck, value_error
from turbinefit.io.images import image_size, read_image, resize_image, to_grey
from turbinefit.solver.config import FILE_FIT_DEFAULTS, PHOTO_FIT_DEFAULTS

if TYPE_CHECKING:  # detection (onnxruntime, scipy) is imported only when photos are used
    from turbinefit.detect import DetectOptions, HeatmapDetector
    from turbinefit.solver.config import FitConfig

F32Maps = NDArray[np.float32]

#: Heat-maps detected for a fit are at most this wide [px]; a larger camera is resized.
FIT_DETECT_WIDTH = 320


def _describe(options: Mapping[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in options.items())


class HeatmapSource(Protocol):
    """The heat-maps of a flight's keyframes.

    Attributes:
        camera: intrinsics of the maps' pixel grid (the photos' camera, or resized).
        description: what the maps are, for summaries (e.g. ``heatmaps/``).
        fit_defaults: the fit options that measured best on maps of this kind
            (:class:`~turbinefit.solver.config.FitConfig` fields set over its defaults;
            ``benchmarks/bench_defaults.py`` measures them): what ``fit`` and ``track``
            use when no ``--config`` or ``--preset`` is given.
        defaults_name: what those defaults are for, in a few words.
        detects: whether :meth:`keyframe` runs the CNN on a photo (its time is part of
            each keyframe's latency) rather than reading a file.
    """

    camera: PinholeCamera
    detects: bool
    fit_defaults: Mapping[str, Any]
    defaults_name: str

    @property
    def description(self) -> str: ...

    def __len__(self) -> int: ...

    def where(self, k: int) -> Path:
        """The file keyframe ``k``'s maps come from (for error messages)."""
        ...

    def keyframe(self, k: int) -> F32Maps:
        """Keyframe ``k``'s maps, (7, H, W) float32 at :attr:`camera`'s size."""
        ...

    def stack(self, progress: bool = False) -> HeatmapStack:
        """Every keyframe's maps."""
        ...

    def checking(self) -> contextlib.AbstractContextManager[None]:
        """A block in which heat-map values are checked as they are first read (maps read
        with ``check="first read"``), and after which those not read yet are: a value out
        of range is the InputError naming the first such file."""
        ...


class FileHeatmaps:
    """The heat-maps of a flight folder's ``heatmaps/`` (memory-mapped: only the ``.npy``
    headers are read until pixels are touched), at their own size: :attr:`camera` is
    ``camera.yaml``'s scaled to it
    (:meth:`~turbinefit.io.flight_folder.FlightFolder.heatmap_camera`)."""

    description = "heatmaps/"
    detects = False
    fit_defaults = FILE_FIT_DEFAULTS
    defaults_name = f"heat-map files ({_describe(FILE_FIT_DEFAULTS)})"

    def __init__(self, folder: FlightFolder, mmap: bool = True,
                 check: ValueCheck = "now") -> None:
        self.folder = folder
        self._stack = folder.read_heatmaps(mmap, check)
        self.camera = folder.heatmap_camera(self._stack)

    def __len__(self) -> int:
        return len(self._stack)

    def where(self, k: int) -> Path:
        return self.folder.heatmap_path(k)

    def keyframe(self, k: int) -> F32Maps:
        return np.asarray(self._stack[k])

    def stack(self, progress: bool = False) -> HeatmapStack:
        return self._stack

    @contextlib.contextmanager
    def checking(self) -> Iterator[None]:
        try:
            yield
            self._stack.check()
        except HeatmapValueError:
            first = self._stack.files.check() if self._stack.files is not None else 0
            raise value_error(self._stack, first, self.where(first)) from None


def detection_camera(camera: PinholeCamera, width: int = FIT_DETECT_WIDTH) -> PinholeCamera:
    """The camera of heat-maps detected from photos taken with ``camera``: the same, or
    resized to ``width`` px wide if it is wider (detection at a working resolution)."""
    return camera.at_most(width)


class PhotoHeatmaps:
    """Heat-maps detected from a flight folder's ``images/`` with the ONNX ``model``
    (None = the shipped one) and ``options`` (None = as the model's metadata says).

    Photos must be at the size of ``camera.yaml``; their maps are made at that size, or at
    ``width`` px wide (camera resized to match, :func:`detection_camera`) if the camera is
    wider. Every photo's header (format and size) is checked when the source is made,
    before any work. A JPEG wider than the detector uses
    (:attr:`~turbinefit.detect.HeatmapDetector.photo_width`, 640 px for the shipped model)
    is decoded at that width (DCT-scaled, :func:`turbinefit.io.images.read_image`); other
    photos are decoded in full.
    :meth:`stack` detects ``threads`` photos at once, one inference thread each
    (:class:`~turbinefit.detect.DetectorPool`; None = one per core); :meth:`keyframe`
    detects one photo with one detector that does not spin-wait (the tracker's solver
    needs the cores between photos).
    """

    def __init__(self, folder: FlightFolder, model: str | os.PathLike[str] | None = None,
                 options: DetectOptions | None = None, *, width: int = FIT_DETECT_WIDTH,
                 threads: int | None = None) -> None:
        self.paths = keyframe_images(folder.root, folder.timestamps)
        cam = self.photo_camera = folder.camera
        for p in self.paths:  # headers only, before any work
            w, h = image_size(p)
            if (w, h) != (cam.width, cam.height):
                raise InputError(f"photo is {w}x{h} but camera.yaml is {cam.width}x{cam.height}",
                                 path=p)
        self.camera = detection_camera(folder.camera, width)
        from turbinefit.detect import DetectOptions

        self.model = model
        self.options = options or DetectOptions()
        if self.options.refine is None:  # coarse to fine (photos at least twice the input)
            self.options = dataclasses.replace(self.options, refine=True)
        self.threads = threads
        self.detects = True
        self.fit_defaults = PHOTO_FIT_DEFAULTS
        self.defaults_name = f"heat-maps detected from photos ({_describe(PHOTO_FIT_DEFAULTS)})"
        self._detector: HeatmapDetector | None = None
        self._refined: bool | None = None  # whether the photos detected were refined

    @property
    def description(self) -> str:
        """Where the maps come from, and whether coarse to fine reads the photos (as the
        detector found when it detected them; before any, as it would)."""
        refined = self._refined
        if refined is None:
            det = self._keyframe_detector()
            refined = det.refine_zoom(*self._decoded_size(det)) > 1
        return (f"detected from {IMAGE_DIR}/ with {self.model or 'the shipped model'}"
                + (", coarse to fine" if refined else ""))

    def __len__(self) -> int:
        return len(self.paths)

    def where(self, k: int) -> Path:
        return self.paths[k]

    def _decoded_size(self, det: HeatmapDetector) -> tuple[int, int]:
        """(width, height) photos are decoded at for ``det``: at most its photo width."""
        cam = self.photo_camera
        return reduced_size(cam.width, cam.height, det.photo_width)

    def _detect(self, det: HeatmapDetector, path: Path) -> F32Maps:
        img = read_image(path, reduce_to=self._decoded_size(det))
        self._refined = det.refine_zoom(img.shape[1], img.shape[0]) > 1
        return det.detect(img, size=(self.camera.width, self.camera.height))

    def _keyframe_detector(self) -> HeatmapDetector:
        """The one detector of :meth:`keyframe` (made on first use)."""
        if self._detector is None:
            self._detector = self.options.detector(self.model, spinning=False)
        return self._detector

    def keyframe(self, k: int) -> F32Maps:
        return self._detect(self._keyframe_detector(), self.paths[k])

    def checking(self) -> contextlib.AbstractContextManager[None]:
        return contextlib.nullcontext()  # the detector's maps are in [0, 1]

    def stack(self, progress: bool = False) -> HeatmapStack:
        from tqdm import tqdm

        pool = self.options.pool(self.model, self.threads)
        maps = np.empty((len(self.paths), 7, self.camera.height, self.camera.width),
                        dtype=np.float32)
        for k, m in enumerate(tqdm(pool.map(self._detect, self.paths), total=len(self.paths),
                                   desc="detecting", unit="img", leave=False,
                                   disable=None if progress else True)):
            maps[k] = m
        return HeatmapStack(maps)


def open_heatmaps(folder: FlightFolder, from_images: bool | None = None,
                  model: str | os.PathLike[str] | None = None,
                  options: DetectOptions | None = None,
                  threads: int | None = None, check: ValueCheck = "now") -> HeatmapSource:
    """The heat-map source of a flight folder: :class:`PhotoHeatmaps` when ``from_images``
    is True, or when it is None and the folder has ``images/`` but no ``heatmaps/``;
    :class:`FileHeatmaps` otherwise (its values checked as ``check`` says,
    :func:`~turbinefit.io.heatmap_files.read_heatmaps`)."""
    if from_images is None:
        from_images = not has_heatmaps(folder.root) and (folder.root / IMAGE_DIR).is_dir()
    if from_images:
        return PhotoHeatmaps(folder, model, options, threads=threads)
    return FileHeatmaps(folder, check=check)


def fit_config_for(source: HeatmapSource, base: FitConfig | None = None,
                   options: Mapping[str, Any] | None = None) -> FitConfig:
    """The fit options of a job on ``source``: ``base`` (a ``--config`` file or
    ``--preset``), or when it is None the defaults for the source's kind of maps
    (:attr:`HeatmapSource.fit_defaults`); then ``options`` (the command line's) on top.

    Raises:
        InputError: naming the options, if they do not make a valid FitConfig.
    """
    from turbinefit.solver.config import FitConfig

    try:
        cfg = base or dataclasses.replace(FitConfig(), **source.fit_defaults)
        return dataclasses.replace(cfg, **(options or {}))
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), field="fit options") from None


#: Width [px] photos are decoded at for figures (:func:`source_photos`).
PLOT_PHOTO_WIDTH = 640


def source_photos(source: HeatmapSource) -> Callable[[int], NDArray[np.uint8]] | None:
    """For heat-maps detected from photos (:class:`PhotoHeatmaps`): keyframe index -> its
    photo, at most :data:`PLOT_PHOTO_WIDTH` px wide (a JPEG decoded at that size), for
    figures drawn over the photos; None for heat-map files."""
    if not isinstance(source, PhotoHeatmaps):
        return None
    cam = source.photo_camera
    size = reduced_size(cam.width, cam.height, PLOT_PHOTO_WIDTH)
    paths = source.paths

    def photo(k: int) -> NDArray[np.uint8]:
        return resize_image(read_image(paths[k], reduce_to=size), *size)  # PNGs: full decode
    return photo


#: The photo terms read the photos at most this many times the heat-maps' width.
PHOTO_TERM_SCALE = 4


def grey_photos(flight_dir: str | os.PathLike[str], timestamps: NDArray[np.float64],
                map_camera: PinholeCamera
                ) -> tuple[Callable[[int], NDArray[np.uint8]], float] | None:
    """Keyframe index -> its photo (``images/``) in grey levels for the edge and width
    terms (``lambda_edges``, ``lambda_width``), read at the heat-maps' aspect and at most
    :data:`PHOTO_TERM_SCALE` times their width (a 20 MP JPEG decoded at a reduced DCT
    scale: 1.2 MB a photo for 320 px maps), and the photos' scale (photo px per map px);
    None without ``images/``.

    Raises:
        InputError: naming the first keyframe without a photo, or a photo that cannot be
            read (as each is read).
    """
    if not (Path(flight_dir) / IMAGE_DIR).is_dir():
        return None
    paths = keyframe_images(flight_dir, timestamps)
    w0, _ = image_size(paths[0])
    width = min(w0, PHOTO_TERM_SCALE * map_camera.width)
    height = max(1, round(width * map_camera.height / map_camera.width))

    def photo(k: int) -> NDArray[np.uint8]:
        return to_grey(resize_image(read_image(paths[k], reduce_to=(width, height)), width,
                                    height))
    return photo, width / map_camera.width


def photo_stack(flight_dir: str | os.PathLike[str], timestamps: NDArray[np.float64],
                map_camera: PinholeCamera) -> PhotoStack | None:
    """Every keyframe's grey photo (:func:`grey_photos`) as one stack, or None without
    ``images/``."""
    reader = grey_photos(flight_dir, timestamps, map_camera)
    if reader is None:
        return None
    photo, scale = reader
    return PhotoStack(np.stack([photo(k) for k in range(len(timestamps))]), scale)
