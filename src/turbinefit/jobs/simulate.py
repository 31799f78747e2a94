"""The ``simulate`` job: a simulated flight written as a flight folder with ground truth.

A simulation is checked before anything is allocated (:func:`check_simulation`): at most
:data:`MAX_KEYFRAMES` keyframes, a camera and heat-maps of sane sizes
(:func:`turbinefit.io.limits.check_image_size`), and an estimate of its peak memory and
of the bytes it writes within what the machine has (:func:`simulation_estimate`).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import yaml

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.heatmaps import NUM_CHANNELS
from turbinefit.io.flight_folder import SIMULATION_FILE, check_flight_destination, write_flight
from turbinefit.io.heatmap_files import WRITTEN_HEATMAP_DTYPE
from turbinefit.io.limits import MIN_IMAGE_SIDE, check_image_size, human_bytes
from turbinefit.io.yaml_files import plain
from turbinefit.jobs.outputs import OVERWRITE_HINT
from turbinefit.sim.scenario import SimConfig, simulate_flight


def simulate_folder(
    out_dir: str | os.PathLike[str],
    config: SimConfig | None = None,
    *,
    overwrite: bool = False,
    progress: bool = False,
    images: bool = False,
) -> Path:
    """Simulate a flight (:func:`turbinefit.sim.simulate_flight`) and write it as a flight
    folder with ground truth; the resolved simulation settings go to ``simulation.yaml``.
    With ``images``, photos of every keyframe rendered from the ground truth
    (:func:`turbinefit.sim.images.render_flight_images`, scene from the seed) go to
    ``images/<t>.png``. ``camera.yaml`` is the photos' camera (:meth:`SimConfig.camera`),
    the heat-maps (float16 files) are at their own size (:attr:`SimConfig.heatmap_size`:
    by default at most 320 px wide whatever the camera).

    The whole folder, ``simulation.yaml`` included, is written atomically. ``out_dir`` is
    checked before simulating: a file or symbolic link is refused, and an existing
    non-empty folder unless ``overwrite`` and it is a flight folder (e.g. one this wrote),
    and so is the simulation itself (:func:`check_simulation`).
    """
    cfg = config or SimConfig()
    out = Path(out_dir)
    check_flight_destination(out, overwrite, OVERWRITE_HINT)
    check_simulation(cfg, out, images)
    flight = simulate_flight(cfg, progress=progress)
    settings = {"turbinefit_version": __version__, **plain(dataclasses.asdict(cfg))}
    photos = None
    if images:
        from turbinefit.sim.images import render_flight_images

        assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
        photos = render_flight_images(cfg.camera(), flight.gt_world_T_cam,
                                      flight.gt_turbine.to_vector(), cfg.seed, cfg.geometry,
                                      progress=progress)
    write_flight(flight, out, overwrite=overwrite,
                 extra_texts={SIMULATION_FILE: yaml.safe_dump(settings, sort_keys=False)},
                 images=photos, camera=cfg.camera(), overwrite_hint=OVERWRITE_HINT)
    return out


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
