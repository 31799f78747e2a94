"""The ``simulate`` job: a simulated flight written as a flight folder with ground truth."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import yaml

from turbinefit import __version__
from turbinefit.io.flight_folder import SIMULATION_FILE, check_flight_destination, write_flight
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
    the heat-maps are at their own size (:attr:`SimConfig.heatmap_size`: by default at
    most 320 px wide whatever the camera).

    The whole folder, ``simulation.yaml`` included, is written atomically. ``out_dir`` is
    checked before simulating: a file or symbolic link is refused, and an existing
    non-empty folder unless ``overwrite`` and it is a flight folder (e.g. one this wrote).
    """
    cfg = config or SimConfig()
    out = Path(out_dir)
    check_flight_destination(out, overwrite, OVERWRITE_HINT)
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
