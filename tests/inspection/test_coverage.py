"""What keyframes show (:mod:`turbinefit.inspection.coverage`): spans, sides, GSD,
occlusion and the per-side grids, on hand-made cameras."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import look_at

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.inspection.coverage import flight_coverage, part_samples
from turbinefit.inspection.surface import PARTS, TurbineSurface
from turbinefit.turbine.model import TurbineParams

TURBINE = TurbineParams(0.0, 0.0, 80.0, 0.0, 5.0, 0.0, 40.0)  # blade A up, upwind is +x
CAM = PinholeCamera(1000, 800, 5000.0, 5000.0, 499.5, 399.5)  # narrow: 2 mm/px at 10 m


def test_gsd_side_and_span_of_a_close_up() -> None:
    s = TurbineSurface(TURBINE)
    target = s.hub + np.array([0.0, 0.0, 25.0])
    half_thick = float(s.blade_section(25.0)[1])
    cov = flight_coverage(s, CAM, look_at(target + np.array([10.0 + half_thick, 0.0, 0.0]), target), 0.5)
    rows = [r for r in cov.rows if PARTS[r.part] == "blade_A"]
    assert len(rows) == 1 and len(cov.rows) == 1
    r = rows[0]
    assert r.sides == ("pressure_side",)
    # the view is 800 px * 2 mm = 1.6 m tall round span 25 m
    assert 23.9 < r.span_from < 24.4 and 25.5 < r.span_to < 26.1
    assert r.gsd_mm_px == pytest.approx(2.0, abs=0.005)  # 1000 * 10 m / 5000 px
    assert r.distance_m == pytest.approx(10.0, abs=0.01)
    grid = cov.grids[0]
    seen = np.isfinite(grid.best_gsd)
    assert seen[1].sum() == 3 and not seen[[0, 2, 3]].any()  # pressure side only
    assert grid.covered(2.01)[1] == pytest.approx(3 / grid.spans.size)
    assert grid.covered(1.9)[1] == 0.0
    assert (grid.best_keyframe[1][seen[1]] == 0).all()


def test_blade_behind_the_tower_is_hidden() -> None:
    s = TurbineSurface(TurbineParams(0.0, 0.0, 80.0, 0.0, 5.0, math.radians(60.0), 40.0))
    down = next(bl for bl in s.blades if bl.axis[2] < -0.99)  # tip at 40 m above the ground
    z = s.hub[2] - 20.0
    back = flight_coverage(s, CAM, look_at(np.array([-30.0, 0.0, z]), np.array([0.0, 0.0, z])))
    name = f"blade_{down.name}"
    assert name not in {PARTS[r.part] for r in back.rows}  # behind the tower: hidden
    wide = PinholeCamera(1000, 800, 800.0, 800.0, 499.5, 399.5)
    front = flight_coverage(s, wide, look_at(np.array([120.0, 0.0, 40.0]),
                                             np.array([0.0, 0.0, 40.0])))
    assert name in {PARTS[r.part] for r in front.rows}
    tower = next(r for r in front.rows if PARTS[r.part] == "tower")
    # from the front the blade hides the tower's axis from its tip up
    assert tower.span_from == 0.0 and 39.0 < tower.span_to < 41.0
    behind = flight_coverage(s, wide, look_at(np.array([-120.0, 0.0, 40.0]),
                                              np.array([0.0, 0.0, 40.0])))
    assert next(r.span_to for r in behind.rows if PARTS[r.part] == "tower") > 78.0


def test_samples_skip_the_hub_and_the_nacelle() -> None:
    s = TurbineSurface(TURBINE)
    spans, pts = part_samples(s, 0, 0.5)
    assert spans[0] > s.spinner_radii[1] and spans[-1] < 40.0
    np.testing.assert_allclose(pts[:, 2], s.hub[2] + spans)
    t_spans, _ = part_samples(s, 3, 1.0)
    assert t_spans[0] == 0.5 and t_spans[-1] < 80.0 - 0.5 * 0.06 * 40.0


def test_keyframes_out_of_sight_give_no_rows() -> None:
    s = TurbineSurface(TURBINE)
    away = look_at(np.array([100.0, 0.0, 50.0]), np.array([200.0, 0.0, 50.0]))
    cov = flight_coverage(s, CAM, away)
    assert cov.rows == [] and all(not np.isfinite(g.best_gsd).any() for g in cov.grids)
