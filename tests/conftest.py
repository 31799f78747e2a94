"""Fixtures several test areas share: small simulated flight folders (as ``turbinefit
simulate`` writes them, made once per session and copied where a test changes them), held-out
rendered photos and the shipped heat-map detector. Plain helpers are in ``support.py``."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

pytest.register_assert_rewrite("support")

from support import SIM_ARGS  # noqa: E402

from turbinefit.cli import main  # noqa: E402


@pytest.fixture(scope="session")
def sim_flight_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small simulated flight with ground truth (12 keyframes, 160 x 120 heat-maps), made
    by ``turbinefit simulate``. Read only: copy it (``flight_copy``) to change it."""
    folder = tmp_path_factory.mktemp("sim") / "flight"
    assert main(["simulate", str(folder), *SIM_ARGS, "--quiet"]) == 0
    return folder


@pytest.fixture
def flight_copy(sim_flight_dir: Path, tmp_path: Path) -> Path:
    """A private copy of ``sim_flight_dir`` (``tmp_path/flight``) to corrupt or fit."""
    return Path(shutil.copytree(sim_flight_dir, tmp_path / "flight"))


@pytest.fixture(scope="session")
def photo_flight_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated flight of 6 keyframes with 160 x 120 photos (``--images``). Read only."""
    folder = tmp_path_factory.mktemp("photos") / "flight"
    assert main(["simulate", str(folder), "--keyframes", "6", "--seed", "2", "--width", "160",
                 "--height", "120", "--images", "--quiet"]) == 0
    return folder


@pytest.fixture
def photo_flight(photo_flight_dir: Path, tmp_path: Path) -> Path:
    """A private copy of ``photo_flight_dir`` (``tmp_path/flight``)."""
    return Path(shutil.copytree(photo_flight_dir, tmp_path / "flight"))


@pytest.fixture(scope="session")
def held_out_samples() -> list:
    """Six held-out renders (a seed never used for training) with the hub and the tower
    top in view."""
    from turbinefit.sim.dataset import DatasetSpec, render_sample

    spec = DatasetSpec(1, seed=987_654, closeup_fraction=0.0)
    out = []
    i = 0
    while len(out) < 6:
        s = render_sample(spec, i)
        if s.visible[2] and s.visible[1]:
            out.append(s)
        i += 1
    return out


@pytest.fixture(scope="session")
def detector():
    """The shipped heat-map detector on one thread."""
    from turbinefit.detect import HeatmapDetector

    return HeatmapDetector(threads=1)
