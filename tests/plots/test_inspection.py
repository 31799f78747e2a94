"""The inspection figures: coverage.png names why nothing reaches the resolution asked for,
and path.png draws georeferenced and local paths (waypoint order, start, north)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from support import assert_valid_png

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import world_T_cam_from_angles
from turbinefit.inspection.coverage import flight_coverage
from turbinefit.inspection.plan import PlanOptions, plan_path
from turbinefit.inspection.surface import TurbineSurface
from turbinefit.io.georef import Georef
from turbinefit.plots.inspection import coverage_note, plot_coverage, plot_path
from turbinefit.turbine.model import TurbineParams

TURBINE = TurbineParams(0.0, 0.0, 60.0, math.radians(40.0), 4.0, math.radians(25.0), 30.0)


@pytest.fixture(scope="module")
def surface() -> TurbineSurface:
    return TurbineSurface(TURBINE)


def _coverage(surface: TurbineSurface, f: float):
    """Photos of the rotor from 20 m upwind, at focal length ``f`` [px]."""
    cam = PinholeCamera(640, 480, f, f, 319.5, 239.5)
    hub = surface.hub
    look = -surface.shaft
    pos = np.array([hub - 20.0 * look + [dx, 0.0, dz] for dx in (-5, 5) for dz in (-5, 5)])
    yaw = np.full(4, math.atan2(look[1], look[0]))
    return cam, flight_coverage(surface, cam, world_T_cam_from_angles(pos, yaw, np.zeros(4), 0.0),
                                0.5)


def test_coverage_note_says_when_the_camera_cannot_reach_the_resolution(
        surface: TurbineSurface, tmp_path: Path) -> None:
    cam, cov = _coverage(surface, 500.0)  # 20 m at 500 px: 40 mm/px
    finest = min(float(np.nanmin(np.where(np.isfinite(g.best_gsd), g.best_gsd, np.nan)))
                 for g in cov.grids if np.isfinite(g.best_gsd).any())
    note = coverage_note(cov, 2.0, cam.fx)
    assert note == (f"no photo reaches 2 mm/px anywhere: the finest is {finest:.1f} mm/px; at "
                    "2 mm/px this camera (focal length 500 px) must be within 1.00 m of the "
                    "surface")
    assert coverage_note(cov, 2.0 * finest, cam.fx) is None
    assert_valid_png(plot_coverage(tmp_path / "coverage.png", cov, 2.0, cam.fx))


@pytest.mark.parametrize("georef", [None, Georef(51.45, -2.51, 40.0)])
def test_path_figure(surface: TurbineSurface, georef: Georef | None, tmp_path: Path) -> None:
    plan = plan_path(surface, PinholeCamera(640, 480, 800.0, 800.0, 319.5, 239.5),
                     PlanOptions(8.0, max_gimbal_up_deg=20.0))
    assert_valid_png(plot_path(tmp_path / "path.png", plan, surface, georef))
