"""The inspection's surface model: blade names, sides, ray casting and the pixel lookup,
against configurations worked out by hand and against the renderer's labels."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import pose_looking_at

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.inspection.surface import (
    BLADE_SIDES,
    PARTS,
    SurfaceShape,
    TurbineSurface,
    blade_clock_angles,
    blade_names,
    lookup_pixel,
    lookup_pixels,
    name_margin_deg,
    sector,
)
from turbinefit.turbine.model import TurbineParams


def turbine(phi_deg: float = 0.0, heading_deg: float = 0.0) -> TurbineParams:
    """Tower 80 m at the origin, hub 5 m ahead along the heading, blades 40 m."""
    return TurbineParams(0.0, 0.0, 80.0, math.radians(heading_deg), 5.0, math.radians(phi_deg),
                         40.0)


CAM = PinholeCamera(400, 300, 500.0, 500.0, 199.5, 149.5)


def centre_hit(surface: TurbineSurface, eye, target):
    return lookup_pixel(surface, CAM, pose_looking_at(eye, target),
                        CAM.cx, CAM.cy)


@pytest.mark.parametrize("phi, names", [
    (0.0, ["A", "C", "B"]),     # blade 0 up (12 o'clock); blade 1 at 8, blade 2 at 4 o'clock
    (10.0, ["C", "B", "A"]),    # blade 0 just left of 12 (350 deg clockwise)
    (100.0, ["C", "B", "A"]),   # = -20 deg modulo 120: blade 0 at 260 deg
])
def test_blade_names_follow_the_clockwise_rule(phi: float, names: list[str]) -> None:
    assert blade_names(turbine(phi)) == names


def test_clock_angles_and_name_margin() -> None:
    np.testing.assert_allclose(sorted(blade_clock_angles(turbine(10.0))), [110, 230, 350])
    assert name_margin_deg(turbine(10.0)) == pytest.approx(10.0)
    assert name_margin_deg(turbine(60.0)) == pytest.approx(60.0)


def test_sector_boundaries() -> None:
    deg = np.radians([0, 44, 46, 90, 134, 136, 180, -170, -100, -46, -44, 359])
    assert sector(deg).tolist() == [0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 0, 0]


@pytest.mark.parametrize("heading", [0.0, 73.0])
def test_sides_of_the_upward_blade(heading: float) -> None:
    """Blade A up, rotor turning clockwise seen from upwind: its leading edge faces the
    right of an observer upwind, its pressure side faces upwind."""
    s = TurbineSurface(turbine(0.0, heading))
    fwd = s.heading_dir
    right = s.tower_right  # the observer's right, seen from upwind
    a = s.blades[0]
    assert a.name == "A" and a.axis[2] == pytest.approx(1.0)
    np.testing.assert_allclose(a.chord, right, atol=1e-12)
    np.testing.assert_allclose(a.normal, fwd, atol=1e-12)
    dirs = np.stack([right, fwd, -right, -fwd, right + 0.2 * fwd])
    assert [BLADE_SIDES[i] for i in s.blade_side(0, dirs)] == [
        "leading_edge", "pressure_side", "trailing_edge", "suction_side", "leading_edge"]
    assert s.tower_face(np.stack([fwd, right, -fwd, -right])).tolist() == [0, 1, 2, 3]


def test_pitch_turns_the_leading_edge_upwind() -> None:
    s = TurbineSurface(turbine(), shape=SurfaceShape(blade_pitch=math.radians(90.0)))
    np.testing.assert_allclose(s.blades[0].chord, s.heading_dir, atol=1e-12)
    assert BLADE_SIDES[int(s.blade_side(0, s.heading_dir[None])[0])] == "leading_edge"


def test_ray_casting_known_configurations() -> None:
    s = TurbineSurface(turbine(0.0))  # heading 0: rotor at x = 5 m, upwind is +x
    hub = s.hub
    # from upwind at the height of 20 m up blade A: the pressure side, span 20 m
    hit = centre_hit(s, hub + np.array([30.0, 0.0, 20.0]), hub + np.array([0.0, 0.0, 20.0]))
    assert hit is not None and hit.part == "blade_A" and hit.blade == "A"
    assert hit.side == "pressure_side"
    assert hit.span_m == pytest.approx(20.0, abs=0.05)
    half_thick = s.blade_section(20.0)[1]
    assert hit.distance_m == pytest.approx(30.0 - float(half_thick), abs=0.05)
    # from the right of the rotor (seen from upwind): the leading edge of blade A
    hit = centre_hit(s, hub + np.array([0.0, 30.0, 20.0]), hub + np.array([0.0, 0.0, 20.0]))
    assert hit.part == "blade_A" and hit.side == "leading_edge"
    # the tower from behind at 30 m: the back face, 30 m above the ground
    hit = centre_hit(s, [-40.0, 0.0, 30.0], [0.0, 0.0, 30.0])
    assert hit.part == "tower" and hit.side == "back"
    assert hit.span_m == pytest.approx(30.0, abs=0.05)
    assert hit.distance_m == pytest.approx(40.0 - float(s.tower_radius(30.0)), abs=0.05)
    # the hub straight on, and the sky above the tips
    assert centre_hit(s, hub + np.array([30.0, 0.0, 0.0]), hub).part == "hub"
    assert centre_hit(s, hub + np.array([30.0, 0.0, 60.0]), hub + np.array([0.0, 0.0, 60.0])) is None


def test_blade_in_front_of_the_tower_hides_it_and_not_from_behind() -> None:
    s = TurbineSurface(turbine(60.0))  # blade 1 at phi 180: pointing straight down
    down = next(bl for bl in s.blades if bl.axis[2] < -0.99)
    target = s.hub + 20.0 * down.axis
    front = centre_hit(s, target + np.array([40.0, 0.0, 0.0]), target)
    assert front.part == f"blade_{down.name}" and front.side == "pressure_side"
    back_target = np.array([0.0, 0.0, target[2]])
    back = centre_hit(s, back_target + np.array([-40.0, 0.0, 0.0]), back_target)
    assert back.part == "tower" and back.side == "back"


def test_miss_beside_a_thin_blade() -> None:
    s = TurbineSurface(turbine(0.0))
    half_chord = float(s.blade_section(30.0)[0][()])
    eye = s.hub + np.array([0.0, 30.0, 30.0])  # looking along the chord: the silhouette is the thickness
    pose = pose_looking_at(eye, s.hub + np.array([0.0, 0.0, 30.0]))
    # a pixel whose ray passes 0.5 m beside the axis, wider than the thickness, inside the chord
    u, v = CAM.cx, CAM.cy
    hits, _ = lookup_pixels(s, CAM, pose, np.array([[u, v], [u + 500.0 * 0.5 / 30.0, v]]))
    assert hits.part[0] == PARTS.index("blade_A")
    assert hits.part[1] == -1 and half_chord > 0.5


def test_sections_are_the_solids() -> None:
    """The surface is turbinefit.turbine.solid's (the renderer's and turbine.glb's): a
    blade of 40 m is 3.2 m wide at 22 % span and round at the root; the tower tapers from
    h / 30 to h / 45."""
    s = TurbineSurface(turbine())
    a, b = s.blade_section(np.array([0.0, 0.22 * 40.0, 40.0]))
    np.testing.assert_allclose(a, [0.88, 1.6, 0.3], rtol=1e-5)
    assert b[0] == pytest.approx(a[0]) and b[1] < 0.5 * a[1]
    assert s.max_half_chord() == pytest.approx(1.6)
    assert s.tower_radius(0.0) == pytest.approx(80.0 / 30.0)
    assert s.tower_radius(80.0) == pytest.approx(80.0 / 45.0)


def test_lookup_agrees_with_the_renderers_labels() -> None:
    """Ground-truth poses and turbine: the renderer's part, side and span in nearly every
    turbine pixel (edges and the renderer's twist account for the rest)."""
    from support import simulated_flight

    from turbinefit.sim.images.painter import LABEL_CODES
    from turbinefit.sim.images.render import render_labels
    from turbinefit.sim.images.scene import flight_scene

    flight = simulated_flight(30, seed=1)
    gt = flight.gt_turbine
    scene = flight_scene(gt.to_vector(), 1)
    surface = TurbineSurface(gt, shape=SurfaceShape(blade_pitch=-scene.blade_pitch))
    cam = PinholeCamera(160, 120, 114.25, 114.25, 79.5, 59.5)
    names = blade_names(gt)
    code_to_part = {1: "tower", 2: "nacelle", 3: "hub"} | {4 + i: f"blade_{names[i]}"
                                                            for i in range(3)}
    vv, uu = np.mgrid[0:120, 0:160]
    uv = np.stack([uu.ravel(), vv.ravel()], -1).astype(float)
    right = sides_right = spans_right = total = blades = 0
    for k in range(0, 30, 2):
        lab = render_labels(cam, flight.gt_world_T_cam[k], gt.to_vector(), scene)
        hits, _ = lookup_pixels(surface, cam, flight.gt_world_T_cam[k], uv)
        code = lab.part.ravel()
        for c, name in code_to_part.items():
            m = code == c
            total += int(m.sum())
            right += int(np.sum(hits.part[m] == PARTS.index(name)))
            if name.startswith("blade"):
                ok = m & (hits.part == PARTS.index(name))
                blades += int(m.sum())
                sides_right += int(np.sum(hits.side[ok] == sector(lab.side_angle.ravel()[ok])))
                spans_right += int(np.sum(np.abs(hits.span[ok] - lab.span.ravel()[ok]) < 0.5))
    assert LABEL_CODES[4] == "blade_0"
    assert total > 5000 and blades > 2000
    assert right / total > 0.95
    assert sides_right / blades > 0.93
    assert spans_right / blades > 0.9


@pytest.mark.parametrize("phi_deg", [0.0, 30.0, 170.0, 250.0, -100.0, 400.0])
@pytest.mark.parametrize("blade_length", [40.0, -40.0])
@pytest.mark.parametrize("heading_deg", [0.0, 135.0])
def test_clock_angles_follow_each_model_blade_whatever_the_parameters(
        phi_deg: float, blade_length: float, heading_deg: float) -> None:
    """Each model blade's clock angle is that of its own tip, seen from upwind, for blade
    rotations outside one period and a negative blade length too (not those of the
    canonical turbine's blades)."""
    from turbinefit.inspection.surface import blade_clock_angles
    from turbinefit.turbine.model import model_points

    t = TurbineParams(0.0, 0.0, 80.0, math.radians(heading_deg), 5.0, math.radians(phi_deg),
                      blade_length)
    p, _ = model_points(t.to_vector())
    w = math.radians(heading_deg)
    right = np.array([-math.sin(w), math.cos(w), 0.0])  # seen from upwind
    for i, clock in enumerate(blade_clock_angles(t)):
        d = p[3 + i] - p[2]
        expected = math.degrees(math.atan2(d @ right, d[2])) % 360.0
        assert min(abs(clock - expected), 360.0 - abs(clock - expected)) < 1e-6
