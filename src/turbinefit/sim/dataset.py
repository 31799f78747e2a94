"""Training data for the heat-map CNN: rendered photos with exact heat-map targets.

Each sample is one view of one random scene: a random turbine
(:func:`turbinefit.sim.turbines.sample_turbine`, with random shaft tilt and blade cone),
a random scene look (:func:`turbinefit.sim.images.sample_scene`), a random camera (a share
``closeup_fraction``, 30 % by default, of close-ups of one blade or the tower filling the
frame, :func:`turbinefit.sim.images.sample_closeup_view`, with stronger motion blur and
exposure errors; of the rest 70 % varied training views of
:func:`turbinefit.sim.images.sample_training_view` and 30 % keyframes of planned
inspection flights; horizontal field of view 50-90 deg). A close-up's targets are the
same skeleton projected: the visible part's line, and its tip when in view. Targets are the
skeleton's heat-maps (:func:`turbinefit.sim.render.render_heatmaps`, no imperfections) at
the heat-map size ``width`` x ``height``, with blob / ridge standard deviation
:data:`turbinefit.heatmaps.targets.TARGET_SIGMA_PX`; only the inspected turbine is
labelled (neighbours in view are background, as in a labelled real flight). The photo is
``image_scale`` times the heat-map size (the model's input; 2 for the shipped model, which
sees 320 x 240 photos and gives 160 x 120 heat-maps): it is rendered at
``max(RENDER_SCALE, image_scale)`` times the heat-map size and, where that is larger than
the input, resized exactly as :mod:`turbinefit.detect` resizes a user's photo, so the net
sees the same resampling at training and at inference.

A dataset folder (:func:`build_dataset`) holds ``.npy`` arrays, filled in place so that an
interrupted build resumes where it stopped:

* ``images.npy``   uint8 (N, s H, s W, 3) RGB photos, s = ``image_scale``,
* ``targets.npy``  uint8 (N, 7, H, W), heat-map values x 255,
* ``points.npy``   float32 (N, 6, 2) projected model points [px] (garbage where not visible),
* ``visible.npy``  bool (N, 6): point in front of the camera and inside the image,
* ``in_sight.npy`` bool (N, 6): visible and not hidden behind a turbine surface (a blade
  tip behind the tower or a nearer blade is visible but not in sight; see
  :func:`turbinefit.sim.images.points_in_sight`),
* ``done.npy``     bool (N,): sample written,
* ``spec.json``    the :class:`DatasetSpec` (a folder of another spec is never reused).

Sample ``i`` depends only on ``(seed, i)``, so datasets of different sizes share samples
and any two workers produce the same bytes; datasets that differ only in ``image_scale``
show the same scenes.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass, replace
from multiprocessing import get_context
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import NUM_CHANNELS
from turbinefit.heatmaps.targets import TARGET_SIGMA_PX
from turbinefit.io.atomic import StrPath, write_text_atomic
from turbinefit.io.images import resize_image
from turbinefit.sim.images import (
    points_in_sight,
    render_image_and_depth,
    sample_closeup_view,
    sample_scene,
    sample_training_view,
)
from turbinefit.sim.render import RenderConfig, render_heatmaps
from turbinefit.sim.trajectory import plan_inspection
from turbinefit.sim.turbines import sample_turbine
from turbinefit.turbine.model import TurbineGeometry, TurbineParams, model_points

#: The model's heat-map size [px] (width, height) for 4:3 photos.
MODEL_WIDTH, MODEL_HEIGHT = 160, 120
#: The shipped model's input photos are this many times the heat-map size (320 x 240).
IMAGE_SCALE = 2
#: Photos are rendered at this multiple of the model's input size, then resized.
RENDER_SCALE = 2
#: Bumped whenever the renderer or the sampling changes what sample i looks like, or the
#: arrays a dataset folder holds change (3: in_sight.npy; 4: close-ups, surface wear,
#: ground clutter).
DATA_VERSION = 4
#: Fraction of samples taken from planned inspection flights (the rest: varied views).
FLIGHT_FRACTION = 0.3
#: Default fraction of close-ups (one blade or the tower filling the frame).
CLOSEUP_FRACTION = 0.3
#: Close-ups' camera effects: motion blur up to this [px at the render size] and
#: exposure errors of this standard deviation (log gain) at most.
CLOSEUP_BLUR_PX, CLOSEUP_EXPOSURE_SIGMA = 8.0, 0.45

_ARRAYS = ("images", "targets", "points", "visible", "in_sight", "done")


@dataclass(frozen=True)
class DatasetSpec:
    """What a rendered dataset is: ``n_images`` samples ``seed``-determined, heat-map
    targets of ``width`` x ``height`` [px] with sigma ``sigma_px`` [px], photos
    ``image_scale`` times that size, a share ``closeup_fraction`` of them close-ups."""

    n_images: int
    seed: int = 0
    width: int = MODEL_WIDTH
    height: int = MODEL_HEIGHT
    sigma_px: float = TARGET_SIGMA_PX
    version: int = DATA_VERSION
    image_scale: int = IMAGE_SCALE
    closeup_fraction: float = CLOSEUP_FRACTION

    def __post_init__(self) -> None:
        if self.n_images < 1:
            raise ValueError(f"n_images must be at least 1, got {self.n_images}")
        if self.width < 16 or self.height < 16:
            raise ValueError(f"image size must be at least 16x16, got {self.width}x{self.height}")
        if self.image_scale not in (1, 2):
            raise ValueError(f"image_scale must be 1 or 2, got {self.image_scale}")
        if not 0.0 <= self.closeup_fraction <= 1.0:
            raise ValueError(f"closeup_fraction must be in [0, 1], got {self.closeup_fraction}")


@dataclass(frozen=True)
class Sample:
    """One rendered training sample (see the module docstring for the arrays)."""

    image: NDArray[np.uint8]
    target: NDArray[np.float32]
    points: NDArray[np.float64]
    visible: NDArray[np.bool_]
    in_sight: NDArray[np.bool_]


def _random_geometry(rng: np.random.Generator) -> TurbineGeometry:
    """Shaft tilt 0-6 deg and blade cone 0-4 deg; the hub level with the tower top.

    The hub offset stays 0 (the paper's model): the tower-top point then lies on the
    tower axis at hub height, inside the nacelle, a fixed place relative to what is seen.
    Random offsets (v1 of the data drew 0-3 m) leave the net no way to tell where the
    invisible point is, so it learned their mean: 1.9 m below the paper's tower top on
    simulated flights, enough to spoil the joint fit.
    """
    return TurbineGeometry(shaft_tilt=math.radians(rng.uniform(0.0, 6.0)),
                           blade_cone=math.radians(rng.uniform(0.0, 4.0)),
                           hub_offset=0.0)


def _camera(rng: np.random.Generator, width: int, height: int) -> PinholeCamera:
    hfov = math.radians(rng.uniform(50.0, 90.0))
    f = 0.5 * width / math.tan(0.5 * hfov)
    return PinholeCamera(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0)


def _flight_view(rng: np.random.Generator, turbine: TurbineParams,
                 geometry: TurbineGeometry) -> SE3:
    path = plan_inspection(turbine, 60, rng, geometry)
    return path.world_T_cam[int(rng.integers(60))]


@dataclass(frozen=True)
class View:
    """What one sample shows, before its look is drawn: the inspected ``turbine`` (base at
    the origin) with its ``geometry``, the ``camera`` (at the heat-map size) and the
    camera's pose ``world_T_cam`` (world metres, z up; OpenCV camera frame)."""

    turbine: TurbineParams
    geometry: TurbineGeometry
    camera: PinholeCamera
    world_T_cam: SE3
    closeup: bool = False


def sample_view(rng: np.random.Generator, width: int = MODEL_WIDTH,
                height: int = MODEL_HEIGHT,
                closeup_fraction: float = CLOSEUP_FRACTION) -> View:
    """A random :class:`View` as the training data draws them (turbine, shaft tilt and
    blade cone, horizontal field of view 50-90 deg; a share ``closeup_fraction`` of
    close-ups, of the rest 70 % varied views and 30 % keyframes of planned inspection
    flights), for heat-maps of ``width`` x ``height`` px. Other renderers
    (``benchmarks/bench_blender.py``) use it to show the same kinds of views."""
    closeup = bool(rng.uniform() < closeup_fraction)
    turbine = sample_turbine(rng, base_radius=0.0)
    geometry = _random_geometry(rng)
    small = _camera(rng, width, height)
    big = small.resized(width * RENDER_SCALE, height * RENDER_SCALE)
    if closeup:
        return View(turbine, geometry, small, sample_closeup_view(rng, turbine, big, geometry),
                    closeup=True)
    if rng.uniform() < FLIGHT_FRACTION:
        pose = _flight_view(rng, turbine, geometry)
    else:
        pose = sample_training_view(rng, turbine, big, geometry)
    return View(turbine, geometry, small, pose)


def render_sample(spec: DatasetSpec, index: int) -> Sample:
    """Sample ``index`` of the dataset ``spec`` (deterministic)."""
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, index]))
    view = sample_view(rng, spec.width, spec.height, spec.closeup_fraction)
    turbine, geometry, small, pose = view.turbine, view.geometry, view.camera, view.world_T_cam
    render = max(RENDER_SCALE, spec.image_scale)
    big = small.resized(spec.width * render, spec.height * render)
    scene = sample_scene(rng, turbine)
    if view.closeup:  # a drone close to a blade: shaken, and metered on the wrong thing
        eff = scene.effects
        scene = replace(scene, effects=replace(
            eff, motion_blur_px=float(rng.uniform(0.0, CLOSEUP_BLUR_PX)),
            exposure_sigma=float(rng.uniform(eff.exposure_sigma, CLOSEUP_EXPOSURE_SIGMA))))
    photo, depth = render_image_and_depth(big, pose, turbine.to_vector(), scene, rng, geometry)
    image = resize_image(photo, spec.width * spec.image_scale, spec.height * spec.image_scale)
    target = render_heatmaps(small, pose, turbine.to_vector(), geometry,
                             RenderConfig(sigma_px=spec.sigma_px))
    world_p, _ = model_points(turbine.to_vector(), geometry)
    uv, ok, _ = small.project_unbounded(pose.inverse().apply(world_p))
    visible = ok & small.in_image(uv)
    in_sight = visible & points_in_sight(big, pose, world_p, depth)
    return Sample(image, target, np.where(np.isfinite(uv), uv, 0.0), visible, in_sight)


class Dataset:
    """A built dataset folder, memory-mapped (see the module docstring)."""

    def __init__(self, folder: StrPath) -> None:
        self.folder = Path(folder)
        self.spec = read_spec(self.folder)
        arrays = {name: np.load(self.folder / f"{name}.npy", mmap_mode="r") for name in _ARRAYS}
        self.images: NDArray[np.uint8] = arrays["images"]
        self.targets: NDArray[np.uint8] = arrays["targets"]
        self.points: NDArray[np.float32] = arrays["points"]
        self.visible: NDArray[np.bool_] = arrays["visible"]
        self.in_sight: NDArray[np.bool_] = arrays["in_sight"]
        self.done: NDArray[np.bool_] = arrays["done"]

    def __len__(self) -> int:
        return self.spec.n_images

    @property
    def complete(self) -> bool:
        return bool(self.done.all())


def read_spec(folder: Path) -> DatasetSpec:
    path = folder / "spec.json"
    try:
        fields = json.loads(path.read_text())
        fields.setdefault("image_scale", 1)  # folders written before the field existed
        return DatasetSpec(**fields)
    except FileNotFoundError as e:
        raise InputError("not a dataset folder (no spec.json)", path=folder) from e
    except (ValueError, TypeError) as e:
        raise InputError(f"malformed dataset spec: {e}", path=path) from e


def _create(folder: Path, spec: DatasetSpec) -> None:
    n, h, w, s = spec.n_images, spec.height, spec.width, spec.image_scale
    shapes: dict[str, tuple[tuple[int, ...], type]] = {
        "images": ((n, s * h, s * w, 3), np.uint8), "targets": ((n, NUM_CHANNELS, h, w), np.uint8),
        "points": ((n, 6, 2), np.float32), "visible": ((n, 6), np.bool_),
        "in_sight": ((n, 6), np.bool_),
        "done": ((n,), np.bool_),
    }
    folder.mkdir(parents=True, exist_ok=True)
    for name, (shape, dtype) in shapes.items():
        arr = np.lib.format.open_memmap(folder / f"{name}.npy", mode="w+", dtype=dtype,
                                        shape=shape)
        arr[...] = 0
        arr.flush()
        del arr
    # spec.json last: a folder without it is an unfinished creation and is redone
    write_text_atomic(folder / "spec.json", json.dumps(asdict(spec), indent=2) + "\n")


def _fill(args: tuple[str, list[int]]) -> list[int]:
    """Worker: render samples ``indices`` into the folder's arrays."""
    folder, indices = Path(args[0]), args[1]
    spec = read_spec(folder)
    arrays = {name: np.load(folder / f"{name}.npy", mmap_mode="r+") for name in _ARRAYS[:-1]}
    for i in indices:
        s = render_sample(spec, i)
        arrays["images"][i] = s.image
        arrays["targets"][i] = np.rint(np.clip(s.target, 0.0, 1.0) * 255.0).astype(np.uint8)
        arrays["points"][i] = s.points
        arrays["visible"][i] = s.visible
        arrays["in_sight"][i] = s.in_sight
    for a in arrays.values():
        a.flush()
    return indices


def _chunks(indices: list[int], size: int) -> Iterator[list[int]]:
    for k in range(0, len(indices), size):
        yield indices[k:k + size]


def check_dataset_folder(folder: StrPath, spec: DatasetSpec) -> None:
    """Raise :class:`InputError` if ``folder`` holds a dataset of another spec (one
    rendered by an older data version says so); an absent folder is fine."""
    root = Path(folder)
    if not (root / "spec.json").exists():
        return
    have = read_spec(root)
    if have == spec:
        return
    if replace(have, version=spec.version) == spec:
        why = (f"was rendered by data version {have.version}; this turbinefit renders "
               f"version {spec.version}")
    else:
        why = f"holds a dataset of another spec ({have})"
    raise InputError(f"{why}; use another folder or delete it", path=root)


def build_dataset(folder: StrPath, spec: DatasetSpec, workers: int | None = None,
                  progress: bool = True) -> Dataset:
    """Render ``spec`` into ``folder`` (created), or finish / reuse what is there.

    A folder holding a complete dataset of the same spec is reused as is; an unfinished
    one is resumed. ``workers`` processes render in parallel (default: all cores).

    Raises:
        InputError: if ``folder`` holds a dataset of another spec.
    """
    root = Path(folder)
    check_dataset_folder(root, spec)
    if not (root / "spec.json").exists():
        _create(root, spec)
    done = np.load(root / "done.npy", mmap_mode="r+")
    todo = [int(i) for i in np.flatnonzero(~done)]
    workers = max(1, workers or os.cpu_count() or 1)
    if todo:
        bar = tqdm(total=spec.n_images, initial=spec.n_images - len(todo), unit="img",
                   desc="rendering training images", disable=not progress)
        jobs = [(str(root), c) for c in _chunks(todo, 32)]
        try:
            if workers == 1:
                results: Iterator[list[int]] = map(_fill, jobs)
                for idx in results:
                    done[idx] = True
                    bar.update(len(idx))
            else:
                with get_context("spawn").Pool(workers) as pool:
                    for idx in pool.imap_unordered(_fill, jobs):
                        done[idx] = True
                        bar.update(len(idx))
        finally:
            done.flush()
            bar.close()
    del done
    return Dataset(root)
