"""Heat-map sources of the jobs (turbinefit.jobs.sources): photos detected at the fit width."""

from __future__ import annotations

from pathlib import Path

import pytest

from turbinefit.cli import main


def test_wide_photos_are_detected_at_the_fit_width(tmp_path: Path) -> None:
    from turbinefit.io.flight_folder import read_flight, read_flight_folder
    from turbinefit.jobs.sources import FIT_DETECT_WIDTH, PhotoHeatmaps

    flight = tmp_path / "f"
    assert main(["simulate", str(flight), "--keyframes", "3", "--seed", "1", "--width", "640",
                 "--height", "480", "--images", "--quiet"]) == 0
    folder = read_flight_folder(flight)
    source = PhotoHeatmaps(folder, threads=1)
    f = folder.flight(source.stack(), source.camera)
    assert (f.camera.width, f.camera.height) == (FIT_DETECT_WIDTH, 240)
    assert (f.heatmaps.height, f.heatmaps.width) == (240, FIT_DETECT_WIDTH)
    full = read_flight_folder(flight)
    assert read_flight(flight).camera == f.camera  # the simulated maps are at 320 x 240 too
    assert f.camera.fx == pytest.approx(full.camera.fx / 2)
    assert f.camera.cx == pytest.approx((full.camera.cx + 0.5) / 2 - 0.5)
