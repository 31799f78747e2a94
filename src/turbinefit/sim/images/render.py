"""Rendering entry points: one photo (and its turbine depth) from a pose, the photos of a
flight, and which world points a photo shows.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from tqdm import tqdm

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.sim.images.effects import apply_effects
from turbinefit.sim.images.frame import Frame
from turbinefit.sim.images.landscape import Landscape
from turbinefit.sim.images.painter import Painter
from turbinefit.sim.images.scene import Scene, flight_scene
from turbinefit.sim.images.turbine import TurbineSolid
from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineGeometry


def render_image(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine: ArrayLike,
    scene: Scene,
    rng: np.random.Generator,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> NDArray[np.uint8]:
    """An RGB image (H, W, 3) uint8 of ``turbine`` and its scene seen from one pose.

    Args:
        camera: intrinsics (H, W = its image size; plumb_bob distortion is applied).
        world_T_cam: camera-to-world pose (a single pose, world metres, OpenCV camera).
        turbine: theta (7,) of the primary turbine [m, rad]; its solid geometry is built
            round :func:`~turbinefit.turbine.model.model_points` ``(theta, geometry)``.
        scene: appearance (sky, terrain, paint, neighbours, effect strengths).
        rng: drives the per-frame camera effects only (exposure, white balance, blur,
            noise, JPEG quality).
        geometry: shaft tilt, blade cone and hub offset of every turbine of the scene.
    """
    return render_image_and_depth(camera, world_T_cam, turbine, scene, rng, geometry)[0]


def render_image_and_depth(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine: ArrayLike,
    scene: Scene,
    rng: np.random.Generator,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
    """:func:`render_image` (same arguments, same image) and its depth: (H, W) float32,
    the distance [m] along each pixel's ray to the nearest turbine surface (of any turbine
    of the scene) covering most of the pixel, inf where none does (sky, terrain)."""
    image, depth, _ = _render(camera, world_T_cam, turbine, scene, rng, geometry, False)
    return image, depth


def render_photo(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine: ArrayLike,
    scene: Scene,
    rng: np.random.Generator,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> tuple[NDArray[np.uint8], TurbineLabels]:
    """:func:`render_image` (same arguments, same image) and, from the same pass, what
    each pixel shows (:func:`render_labels`' labels, with the landscape and clutter in
    front hiding what they cover, and :attr:`TurbineLabels.defect`)."""
    image, _, labels = _render(camera, world_T_cam, turbine, scene, rng, geometry, True)
    assert labels is not None
    return image, labels


def _render(camera: PinholeCamera, world_T_cam: SE3, turbine: ArrayLike, scene: Scene,
            rng: np.random.Generator, geometry: TurbineGeometry, labels: bool
            ) -> tuple[NDArray[np.uint8], NDArray[np.float32], TurbineLabels | None]:
    if world_T_cam.batch_shape != ():
        raise ValueError(f"expected one pose, got batch {world_T_cam.batch_shape}")
    fr = Frame(camera, world_T_cam, scene)
    if labels:
        fr.enable_labels()
    land = Landscape(fr)
    thetas = [np.asarray(turbine, dtype=np.float64).ravel(), *map(np.asarray, scene.neighbours)]
    doors = np.random.default_rng(scene.seed).uniform(-math.pi, math.pi, len(thetas))
    turbines = [TurbineSolid(th, geometry, scene, float(dz)) for th, dz in zip(thetas, doors, strict=True)]
    land.prepare_shadows(turbines)
    land.paint()
    painter = Painter(fr, scene)
    painter.clutter(scene.clutter)
    for k in sorted(range(len(turbines)),
                    key=lambda q: -float(np.linalg.norm(turbines[q].centre - fr.o))):
        painter.turbine(turbines[k], primary=k == 0)
    img = fr.C.reshape(3, camera.height, camera.width)
    np.nan_to_num(img, copy=False, nan=0.5, posinf=1.0, neginf=0.0)
    depth = fr.Z.reshape(camera.height, camera.width).copy()
    return apply_effects(img, fr.rn, scene.effects, rng), depth, _labels(fr, depth)


def _labels(fr: Frame, depth: NDArray[np.float32]) -> TurbineLabels | None:
    """The labels a frame recorded (None: it recorded none)."""
    if fr.labels is None:
        return None
    shape = (fr.H, fr.W)
    part, span, angle = fr.labels
    defect = None if fr.defect_labels is None else fr.defect_labels.reshape(shape)
    return TurbineLabels(part.reshape(shape), span.reshape(shape), angle.reshape(shape),
                         depth, defect)


@dataclass
class TurbineLabels:
    """Per-pixel ground truth of a render (:func:`render_labels`), arrays (H, W).

    Attributes:
        part: code of :data:`~turbinefit.sim.images.painter.LABEL_CODES` of the part
            covering most of the pixel (0: none).
        span: [m] along the part's axis at the surface point: from the hub on a blade,
            from the base on the tower (NaN elsewhere).
        side_angle: on a blade, the direction to the camera round the blade axis [rad],
            from the leading edge towards the upwind (pressure) side of the blade's section
            as drawn (pitch and twist included), for a rotor turning clockwise seen from
            upwind (the convention of :mod:`turbinefit.inspection.surface`); NaN elsewhere.
            The renderer's blades are symmetric about their chord and its pitch turns the
            chord the other way round: a scene pitch ``p`` is a pitch ``-p`` there.
        depth: ray distance [m] of the labelled surface (inf: none).
        defect: index into ``scene.defects`` of the defect covering most of the pixel
            (-1: none).
    """

    part: NDArray[np.int8]
    span: NDArray[np.float32]
    side_angle: NDArray[np.float32]
    depth: NDArray[np.float32]
    defect: NDArray[np.int16] | None = None


def render_labels(camera: PinholeCamera, world_T_cam: SE3, turbine: ArrayLike, scene: Scene,
                  geometry: TurbineGeometry = PAPER_GEOMETRY) -> TurbineLabels:
    """Which part of ``turbine`` (or another turbine of ``scene``) each pixel of
    :func:`render_image` (same arguments) shows, with span and side: the turbines drawn as
    there, without landscape or camera effects."""
    if world_T_cam.batch_shape != ():
        raise ValueError(f"expected one pose, got batch {world_T_cam.batch_shape}")
    fr = Frame(camera, world_T_cam, scene)
    fr.C[:] = 0.5
    fr.enable_labels()
    thetas = [np.asarray(turbine, dtype=np.float64).ravel(), *map(np.asarray, scene.neighbours)]
    doors = np.random.default_rng(scene.seed).uniform(-math.pi, math.pi, len(thetas))
    turbines = [TurbineSolid(th, geometry, scene, float(dz))
                for th, dz in zip(thetas, doors, strict=True)]
    painter = Painter(fr, scene)
    for k in sorted(range(len(turbines)),
                    key=lambda q: -float(np.linalg.norm(turbines[q].centre - fr.o))):
        painter.turbine(turbines[k], primary=k == 0)
    out = _labels(fr, fr.Z.reshape(camera.height, camera.width).copy())
    assert out is not None
    return out


def points_in_sight(camera: PinholeCamera, world_T_cam: SE3, world_p: ArrayLike,
                    depth: NDArray[np.floating], margin_m: float = 3.0,
                    margin_rel: float = 0.02) -> NDArray[np.bool_]:
    """Which world points (M, 3) the camera sees: in front of it, inside the image and
    not behind a turbine surface of ``depth`` (:func:`render_image_and_depth`, same
    camera) nearer than the point by more than ``margin_m`` + ``margin_rel`` x its
    distance at the point's pixel (the margin lets a point inside its own part, e.g. a
    blade tip on the blade's axis or the hub inside the spinner, count as seen)."""
    p = np.asarray(world_p, dtype=np.float64).reshape(-1, 3)
    uv, ok, _ = camera.project_unbounded(world_T_cam.inverse().apply(p))
    seen = ok & camera.in_image(uv)
    dist = np.linalg.norm(p - world_T_cam.translation, axis=-1)
    for k in np.flatnonzero(seen):
        j = min(max(round(float(uv[k, 0])), 0), camera.width - 1)
        i = min(max(round(float(uv[k, 1])), 0), camera.height - 1)
        seen[k] = float(depth[i, j]) >= dist[k] - margin_m - margin_rel * dist[k]
    return seen




def render_flight_images(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine: ArrayLike,
    seed: int,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
    progress: bool = False,
) -> Iterator[NDArray[np.uint8]]:
    """Images (H, W, 3) uint8 of every keyframe of ``world_T_cam`` (N,), one at a time.

    One :class:`Scene` for the whole flight is sampled from ``seed``; each keyframe's
    effects get their own generator, spawned from the same seed (keyframe k's image depends
    only on the seed and k). ``progress`` shows a tqdm bar.
    """
    poses = SE3(world_T_cam.wxyz_xyz.reshape(-1, 7))
    n = poses.batch_shape[0]
    theta = np.asarray(turbine, dtype=np.float64).ravel()
    scene = flight_scene(theta, seed)
    for k in tqdm(range(n), desc="rendering images", unit="img", disable=not progress):
        yield render_image(camera, poses[k], theta, scene, keyframe_rng(seed, k), geometry)


def keyframe_rng(seed: int, k: int) -> np.random.Generator:
    """The generator of keyframe ``k``'s camera effects in the flight of ``seed``: child
    ``k`` of the second child of ``SeedSequence(seed)`` (whatever the flight's length)."""
    _, frames_ss = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(np.random.SeedSequence(
        frames_ss.entropy, spawn_key=(*frames_ss.spawn_key, k)))
