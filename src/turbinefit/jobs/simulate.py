"""The ``simulate`` job: a simulated flight written as a flight folder with ground truth.

A simulation is checked before anything is allocated (:func:`check_simulation`): at most
:data:`MAX_KEYFRAMES` keyframes, a camera and heat-maps of sane sizes
(:func:`turbinefit.io.limits.check_image_size`), and an estimate of its peak memory and
of the bytes it writes within what the machine has (:func:`simulation_estimate`). A path
to fly (``path``, TUM) must stay above the ground and out of the true turbine
(:func:`check_path_clear`); given defects (``defects_file``) must lie on its blades.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml
from numpy.typing import NDArray

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.heatmaps import NUM_CHANNELS
from turbinefit.io.flight_folder import (
    DEFECT_BOXES_FILE,
    DEFECTS_FILE,
    SIMULATION_FILE,
    check_flight_destination,
    write_flight,
)
from turbinefit.io.heatmap_files import WRITTEN_HEATMAP_DTYPE
from turbinefit.io.limits import MIN_IMAGE_SIDE, check_image_size, human_bytes
from turbinefit.io.quantities import Quantity
from turbinefit.io.tum import TumTrajectory
from turbinefit.io.yaml_files import plain
from turbinefit.jobs.outputs import OVERWRITE_HINT
from turbinefit.sim.scenario import SimConfig
from turbinefit.turbine.model import TurbineGeometry, TurbineParams
from turbinefit.turbine.solid import ROOT_TWIST

if TYPE_CHECKING:
    from turbinefit.sim.photos import FlightPhotos

#: ``--photo-scale``: the photos' size as a fraction of the camera's.
PHOTO_SCALE = Quantity("photo scale", "", 0.0, 1.0, lo_open=True)


def simulate_folder(
    out_dir: str | os.PathLike[str],
    config: SimConfig | None = None,
    *,
    overwrite: bool = False,
    progress: bool = False,
    images: bool = False,
    camera: PinholeCamera | None = None,
    photo_scale: float = 1.0,
    path: str | os.PathLike[str] | None = None,
    defects_file: str | os.PathLike[str] | None = None,
) -> Path:
    """Simulate a flight (:func:`turbinefit.sim.simulate`) and write it as a flight
    folder with ground truth; the resolved simulation settings go to ``simulation.yaml``.
    With ``images``, photos of every keyframe rendered from the ground truth
    (:class:`turbinefit.sim.photos.FlightPhotos`, scene from the seed) go to
    ``images/<t>.png``. ``camera.yaml`` is the photos' camera (:meth:`SimConfig.camera`,
    or ``camera``, in both cases scaled by ``photo_scale``), the heat-maps (float16 files)
    are at their own size (:attr:`SimConfig.heatmap_size`: by default at most 320 px wide
    whatever the camera).

    ``path``: a TUM file of ground-truth poses to fly (timestamps from the file) instead of
    the simulator's inspection; it must stay above the ground and out of the true turbine
    (:func:`check_path_clear`). Known defects, :attr:`SimConfig.defects` drawn ones or
    those of ``defects_file`` (:func:`turbinefit.io.defects.read_defects_csv`), go to
    ``defects_groundtruth.csv``, and with ``images`` the box of each in view on each photo
    to ``defect_boxes.csv``. A flight along a path or with defects shows the blades'
    surface in its photos (:attr:`SimConfig.surface_detail`); ``simulation.yaml`` then says
    the blades' pitch and twist in ``coverage``'s terms (``blade_pitch_deg``,
    ``blade_twist_deg``).

    The whole folder, ``simulation.yaml`` included, is written atomically. ``out_dir`` is
    checked before simulating: a file or symbolic link is refused, and an existing
    non-empty folder unless ``overwrite`` and it is a flight folder (e.g. one this wrote),
    and so is the simulation itself (:func:`check_simulation`).

    Raises:
        InputError: bad input (one line naming the file, line and field); nothing is
            written.
    """
    from turbinefit.inspection.defects import check_defects
    from turbinefit.io.defects import (
        format_defect_boxes_csv,
        format_defects_csv,
        read_defects_csv,
    )
    from turbinefit.io.tum import read_tum_lines
    from turbinefit.sim.scenario import FlightPath, simulate, true_turbine, with_camera

    cfg = config or SimConfig()
    out = Path(out_dir)
    photo_scale = PHOTO_SCALE.check(photo_scale, field="--photo-scale")
    check_flight_destination(out, overwrite, OVERWRITE_HINT)
    if camera is not None or photo_scale != 1.0:
        cam = camera or cfg.camera()
        check_image_size(cam.width, cam.height, field="--camera", what="the camera")
        cfg = with_camera(cfg, cam.scaled(photo_scale) if photo_scale != 1.0 else cam)
    flight_path = None
    if path is not None:
        traj = read_tum_lines(path)
        cfg = dataclasses.replace(cfg, n_keyframes=len(traj.timestamps), surface_detail=True)
        check_simulation(cfg, out, images)  # before anything is cast through the turbine
        check_path_clear(traj, true_turbine(cfg), cfg.geometry, path)
        flight_path = FlightPath(traj.timestamps, traj.poses)
    defects = None
    if defects_file is not None:
        given = read_defects_csv(defects_file)
        check_defects(given.defects, true_turbine(cfg), defects_file, given.lines)
        defects = given.defects
    if defects or cfg.defects:
        cfg = dataclasses.replace(cfg, surface_detail=True)
    check_simulation(cfg, out, images)
    sim = simulate(cfg, flight_path, defects, progress=progress)
    flight = sim.flight
    assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
    settings = {"turbinefit_version": __version__, **plain(dataclasses.asdict(cfg))}
    if path is not None:
        settings["path"] = str(path)
    if defects_file is not None:
        settings["defects_file"] = str(defects_file)
    photos = None
    if images or cfg.surface_detail:
        from turbinefit.sim.photos import FlightPhotos

        photos = FlightPhotos(cfg.camera(), flight.gt_turbine, cfg.seed, cfg.geometry,
                              sim.defects, surface=cfg.surface_detail)
    if photos is not None and cfg.surface_detail:  # the blades as drawn, in coverage's terms
        settings["blade_pitch_deg"] = round(-math.degrees(photos.scene.blade_pitch), 4)
        settings["blade_twist_deg"] = round(-math.degrees(ROOT_TWIST), 4)
    texts = {SIMULATION_FILE: yaml.safe_dump(settings, sort_keys=False)}
    known = bool(sim.defects) or cfg.defects > 0 or defects_file is not None
    if known:
        texts[DEFECTS_FILE] = format_defects_csv(sim.defects)
    rows: list[tuple[str, int, int, str, tuple[int, int, int, int], str]] = []
    images_iter = None
    if photos is not None and images:
        images_iter = _photos(photos, flight, rows, known, progress)
    write_flight(flight, out, overwrite=overwrite, extra_texts=texts, images=images_iter,
                 camera=cfg.camera(), overwrite_hint=OVERWRITE_HINT,
                 after_images=(lambda: {DEFECT_BOXES_FILE: format_defect_boxes_csv(rows)})
                 if images and known else None)
    return out


def _photos(photos: FlightPhotos, flight: Flight,
            rows: list[tuple[str, int, int, str, tuple[int, int, int, int], str]],
            boxes: bool, progress: bool) -> Iterator[NDArray[np.uint8]]:
    """Every keyframe's photo, one at a time; with ``boxes`` the defects each shows are
    added to ``rows`` (``defect_boxes.csv``'s)."""
    from tqdm import tqdm

    from turbinefit.io.heatmap_files import keyframe_stem

    assert flight.gt_world_T_cam is not None
    cam = photos.camera
    for k in tqdm(range(flight.num_keyframes), desc="rendering images", unit="img",
                  disable=not progress):
        pose = flight.gt_world_T_cam[k]
        if not boxes:
            yield photos.image(k, pose)
            continue
        photo = photos.photo(k, pose)
        name = keyframe_stem(float(flight.timestamps[k])) + ".png"
        rows += [(name, cam.width, cam.height, b.kind, b.box, b.defect) for b in photo.boxes]
        yield photo.image


def check_path_clear(traj: TumTrajectory, turbine: TurbineParams, geometry: TurbineGeometry,
                     path: str | os.PathLike[str]) -> None:
    """Refuse a path to fly with a pose below the ground or inside ``turbine``'s solid
    (:class:`~turbinefit.inspection.surface.TurbineSurface`): the first such pose, named by
    its line. A pose is inside a part if rays cast at it from far away, along three
    directions both ways, all meet the turbine before reaching it. The poses are the
    photos' (what happens between them, e.g. ``plan``'s detours round the rotor, is not
    known).

    Raises:
        InputError: naming the file and line.
    """
    # TODO: use inspection.plan.path_clearance (the plan's clearance check) once it lands
    from turbinefit.inspection.surface import PARTS, TurbineSurface

    p = traj.poses.translation
    below = np.flatnonzero(p[:, 2] < 0.0)
    if below.size:
        k = int(below[0])
        raise InputError(f"pose below the ground (z = {p[k, 2]:.2f} m)", path=path,
                         line=int(traj.lines[k]))
    surface = TurbineSurface(turbine, geometry)
    far = 1000.0
    inside = np.ones(len(p), dtype=bool)
    parts = []
    for u in _INSIDE_DIRECTIONS:
        for d in (u, -u):
            hits = surface.cast_rays(p - far * d, np.broadcast_to(d, p.shape))
            with np.errstate(invalid="ignore"):
                inside &= hits.distance < far
            parts.append(hits.part)
    if np.any(inside):
        k = int(np.argmax(inside))
        part = int(np.bincount(np.array([q[k] for q in parts])).argmax())  # most rays'
        raise InputError(f"pose at ({p[k, 0]:.1f}, {p[k, 1]:.1f}, {p[k, 2]:.1f}) m is inside "
                         f"the simulated turbine ({PARTS[part]}; the turbine of --seed and "
                         "--turbine)", path=path, line=int(traj.lines[k]))


#: Directions of :func:`check_path_clear`'s rays (oblique: none along an axis of the
#: turbine's parts).
_INSIDE_DIRECTIONS = [v / np.linalg.norm(v) for v in
                      (np.array([1.0, 0.31, 0.17]), np.array([-0.23, 1.0, 0.41]),
                       np.array([0.37, -0.29, 1.0]))]


#: Most keyframes a simulation may have (a 1000-keyframe flight is a long inspection).
MAX_KEYFRAMES = 1_000_000
#: Bytes of memory per heat-map pixel and keyframe: 7 float32 channels (measured with
#: ``ru_maxrss``: 27.7 per pixel for 200 and 2000 keyframes of 320 x 240 maps).
HEATMAP_BYTES_PER_PX = 28
#: Bytes written per heat-map pixel and keyframe: 7 channels as heat-map files store them.
HEATMAP_FILE_BYTES_PER_PX = NUM_CHANNELS * np.dtype(WRITTEN_HEATMAP_DTYPE).itemsize
#: Peak working memory of rendering one photo, per photo pixel (measured 146-170 bytes
#: at 1280 x 960 and 2560 x 1920; photos are rendered and written one at a time).
PHOTO_WORK_BYTES_PER_PX = 200
#: Bytes written per photo pixel (PNG; measured 0.53-0.61 on rendered photos).
PNG_BYTES_PER_PX = 1.0
#: Memory of the process apart from the above (interpreter, numpy, simulator).
BASE_BYTES = 200 << 20


@dataclasses.dataclass(frozen=True)
class SimulationEstimate:
    """What a simulation needs: ``memory`` (peak bytes), ``disk`` (bytes written)."""

    memory: int
    disk: int


def simulation_estimate(cfg: SimConfig, images: bool = False) -> SimulationEstimate:
    """Peak memory and bytes written of simulating ``cfg`` (with photos if ``images``):
    every keyframe's heat-maps are held in memory until written; one photo is rendered at
    a time."""
    hm = cfg.heatmap_camera()
    maps = cfg.n_keyframes * HEATMAP_BYTES_PER_PX * hm.width * hm.height
    photo_px = cfg.width * cfg.height
    memory = BASE_BYTES + maps + (PHOTO_WORK_BYTES_PER_PX * photo_px if images else 0)
    disk = (cfg.n_keyframes * HEATMAP_FILE_BYTES_PER_PX * hm.width * hm.height
            + (int(PNG_BYTES_PER_PX * photo_px) * cfg.n_keyframes if images else 0))
    return SimulationEstimate(int(memory), int(disk))


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (``MemAvailable`` of
    ``/proc/meminfo``, else free physical pages), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return None


def _free_disk(path: Path) -> int | None:
    """Free bytes on the file system ``path`` (or its nearest existing ancestor) is on."""
    import shutil

    p = path.absolute()
    while not p.exists() and p.parent != p:
        p = p.parent
    try:
        return int(shutil.disk_usage(p).free)
    except OSError:
        return None


def check_simulation(cfg: SimConfig, out: Path | None = None, images: bool = False) -> None:
    """Refuse a simulation before anything is allocated: more than :data:`MAX_KEYFRAMES`
    keyframes, a camera or heat-maps outside the sizes a flight folder may have
    (:func:`turbinefit.io.limits.check_image_size`), or an estimated peak memory
    (:func:`simulation_estimate`) above the memory available, or bytes to write above the
    free space at ``out``; each message gives the estimate.

    Raises:
        InputError: naming the option.
    """
    if cfg.n_keyframes > MAX_KEYFRAMES:
        raise InputError(f"{cfg.n_keyframes} keyframes; at most {MAX_KEYFRAMES} can be "
                         "simulated", field="--keyframes")
    check_image_size(cfg.width, cfg.height, field="--width, --height", what="the camera")
    hm = cfg.heatmap_camera()
    if min(hm.width, hm.height) < MIN_IMAGE_SIDE:
        raise InputError(f"heat-maps of {hm.width}x{hm.height} px for a {cfg.width}x"
                         f"{cfg.height} camera; each side must be at least {MIN_IMAGE_SIDE} "
                         "px (--heatmap-size, or a less elongated camera)",
                         field="--heatmap-size")
    est = simulation_estimate(cfg, images)
    what = (f"{cfg.n_keyframes} keyframes of {hm.width}x{hm.height} heat-maps"
            + (f" and {cfg.width}x{cfg.height} photos" if images else ""))
    avail = available_memory()
    if avail is not None and est.memory > avail:
        raise InputError(f"{what} need about {human_bytes(est.memory)} of memory; "
                         f"{human_bytes(avail)} is available", field="simulate")
    free = _free_disk(out) if out is not None else None
    if free is not None and est.disk > free:
        raise InputError(f"{what} would write about {human_bytes(est.disk)}; "
                         f"{human_bytes(free)} is free there", path=out)
