"""Known defects: drawn on the blades, refused off them, painted where they are and boxed
only where a photo shows them."""

from __future__ import annotations

import numpy as np
import pytest
from support import look_at

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.inspection.defects import Defect, check_defects, defect_point
from turbinefit.inspection.surface import SurfaceShape, TurbineSurface
from turbinefit.sim.defects import draw_defects
from turbinefit.sim.images import render_flight_images
from turbinefit.sim.photos import FlightPhotos
from turbinefit.turbine.model import TurbineParams
from turbinefit.turbine.solid import ROOT_TWIST

TURBINE = TurbineParams(0.0, 0.0, 90.0, 0.5, 5.0, 0.4, 60.0)
CAMERA = PinholeCamera(200, 150, 180.0, 180.0, 99.5, 74.5)


def test_drawn_defects_lie_on_the_blades_and_follow_the_seed() -> None:
    a = draw_defects(200, TURBINE, np.random.default_rng(3))
    check_defects(a, TURBINE)
    assert a == draw_defects(200, TURBINE, np.random.default_rng(3))
    assert {d.kind for d in a} == {"erosion", "crack", "burn"}
    assert {d.part for d in a} == {"blade_A", "blade_B", "blade_C"}
    assert all(0.05 <= d.size_m <= 0.5 for d in a)
    assert [d.defect for d in a[:2]] == ["D001", "D002"]


@pytest.mark.parametrize(("defect", "field"), [
    (Defect("X", "blade_A", "pressure_side", 60.5, 0.0, 0.1), "span_m"),
    (Defect("X", "blade_A", "pressure_side", 1.0, 0.0, 0.1), "span_m"),
    (Defect("X", "blade_A", "pressure_side", 30.0, 1.01, 0.1), "chord"),
    (Defect("X", "blade_A", "trailing_edge", 30.0, 1.0, 0.1), "chord"),
    (Defect("X", "tower", "pressure_side", 30.0, 0.0, 0.1), "part"),
    (Defect("X", "blade_A", "front", 30.0, 0.0, 0.1), "side"),
    (Defect("X", "blade_A", "pressure_side", 30.0, 0.0, 0.1, "dent"), "kind"),
])
def test_defects_off_the_blade_are_refused(defect: Defect, field: str) -> None:
    with pytest.raises(InputError, match=rf"d\.csv:7 \[{field}\]: defect X"):
        check_defects([defect], TURBINE, "d.csv", [7])


def _photos(defects: list[Defect]) -> tuple[FlightPhotos, TurbineSurface]:
    photos = FlightPhotos(CAMERA, TURBINE, 5, defects=defects)
    shape = SurfaceShape(-photos.scene.blade_pitch, -ROOT_TWIST)
    return photos, TurbineSurface(TURBINE, shape=shape)


def test_a_defect_is_boxed_where_it_is_and_hidden_from_behind() -> None:
    d = Defect("D1", "blade_B", "pressure_side", 40.0, 0.3, 0.4, "burn")
    photos, surface = _photos([d])
    p, n = defect_point(surface, d)
    front, back = look_at(np.stack([p + 6.0 * n, p - 6.0 * n]), np.stack([p, p]))
    seen = photos.photo(0, front)
    (box,) = seen.boxes
    uv = CAMERA.project(front.inverse().apply(p[None]))[0][0]
    x0, y0, x1, y1 = box.box
    assert x0 <= uv[0] + 0.5 <= x1 and y0 <= uv[1] + 0.5 <= y1
    assert (box.defect, box.kind) == ("D1", "burn")
    # 0.4 m across at 6 m with f = 180 px: about 12 px
    assert 6 <= x1 - x0 <= 20 and 6 <= y1 - y0 <= 20
    # the burn darkens the photo there
    plain = FlightPhotos(CAMERA, TURBINE, 5, surface=True).image(0, front)
    i, j = round(float(uv[1])), round(float(uv[0]))
    assert seen.image[i, j].mean() < plain[i, j].mean() - 30
    assert photos.photo(0, back).boxes == ()  # on the face turned away


def test_photos_without_defects_are_the_flights_photos() -> None:
    poses = look_at(np.array([[150.0, 20.0, 60.0]]), np.array([[0.0, 0.0, 80.0]]))
    photos = FlightPhotos(CAMERA, TURBINE, 9)
    first = next(render_flight_images(CAMERA, poses, TURBINE.to_vector(), 9))
    np.testing.assert_array_equal(photos.image(0, poses[0]), first)
    np.testing.assert_array_equal(photos.photo(0, poses[0]).image, first)
