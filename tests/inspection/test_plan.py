"""The inspection path (:mod:`turbinefit.inspection.plan`): stations at the stand-off
seeing the intended side, clearance from the rotor along the whole path, the coverage its
photos reach, and the plans refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import world_T_cam_from_angles
from turbinefit.inspection.coverage import flight_coverage
from turbinefit.inspection.plan import PlanError, PlanOptions, _Clearance, _densify, plan_path
from turbinefit.inspection.surface import TOWER, TurbineSurface
from turbinefit.turbine.model import TurbineParams

TURBINE = TurbineParams(3.0, -2.0, 60.0, math.radians(40.0), 4.0, math.radians(25.0), 30.0)
CAM = PinholeCamera(1200, 900, 2000.0, 2000.0, 599.5, 449.5)  # 4 mm/px at 8 m


@pytest.fixture(scope="module")
def surface() -> TurbineSurface:
    return TurbineSurface(TURBINE)


@pytest.fixture(scope="module")
def plan(surface: TurbineSurface):
    return plan_path(surface, CAM, PlanOptions(8.0, 4.0))


def poses(photos):
    return world_T_cam_from_angles(np.array([w.position for w in photos]),
                                   np.array([w.yaw for w in photos]),
                                   np.array([w.pitch for w in photos]), 0.0)


def test_photos_see_their_side_from_the_standoff(surface: TurbineSurface, plan) -> None:
    assert plan.gsd_mm == pytest.approx(4.0)
    photos = plan.photos
    assert len(photos) > 40
    for w in photos:
        view = np.array([math.cos(w.pitch) * math.cos(w.yaw),
                         math.cos(w.pitch) * math.sin(w.yaw), math.sin(w.pitch)])
        hit = surface.cast_rays(w.position[None], view[None])
        assert int(hit.part[0]) == w.part
        # the stand-off, from the widest section within half a step (legs stay clear)
        assert 8.0 - 0.05 < hit.distance[0] < 8.6
        if w.part < TOWER:
            assert int(surface.blade_side(w.part, -view[None])[0]) == w.side
        else:
            assert int(surface.tower_face(-view[None])[0]) == w.side
    assert {(w.part, w.side) for w in photos} == {(p, k) for p in range(4) for k in range(4)}


def test_the_path_keeps_the_standoff_from_the_rotor(surface: TurbineSurface, plan) -> None:
    pts = _densify(np.array([w.position for w in plan.waypoints]), 0.1)
    clear = _Clearance(surface)
    assert clear.rotor(pts).min() >= 8.0 - 0.01
    assert clear.tower(pts).min() >= 2.0 - 0.01
    assert pts[:, 2].min() >= 2.0 - 1e-9
    assert plan.min_rotor_clearance >= 8.0 - 1e-6
    assert plan.length_m > 4 * 30.0


def test_the_photos_cover_every_blade_side(surface: TurbineSurface, plan) -> None:
    cov = flight_coverage(surface, CAM, poses(plan.photos))
    for g in cov.grids[:3]:
        assert g.covered(4.4).min() > 0.9, g.covered(4.4)  # 4 mm/px at the stand-off


def test_gimbal_limit(surface: TurbineSurface) -> None:
    free = plan_path(surface, CAM, PlanOptions(8.0))
    p = plan_path(surface, CAM, PlanOptions(8.0, max_gimbal_up_deg=30.0))
    assert max(math.degrees(w.pitch) for w in free.photos) > 60.0
    assert max(math.degrees(w.pitch) for w in p.photos) <= 30.0 + 1e-9
    assert sum(p.skipped.values()) > sum(free.skipped.values())


@pytest.mark.parametrize("options, option, words", [
    (PlanOptions(8.0, 3.0), "max_gsd_mm", "4.00 mm/px at a stand-off of 8 m"),
    (PlanOptions(35.0), "standoff", "meets the rotor"),
    (PlanOptions(0.0), "standoff", "positive"),
    (PlanOptions(8.0, overlap=0.95), "overlap", "overlap"),
])
def test_plans_refused(surface: TurbineSurface, options: PlanOptions, option: str,
                       words: str) -> None:
    with pytest.raises(PlanError, match=words) as info:
        plan_path(surface, CAM, options)
    assert info.value.option == option
