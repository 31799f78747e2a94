"""The solid turbine round the skeleton (turbinefit.turbine.solid): closed, outward meshes
of the renderer's proportions, blades along the model's lines at its blade rotation."""

import math

import numpy as np
import pytest

from turbinefit.turbine.model import BLADE_PERIOD, TurbineGeometry, TurbineParams, model_points
from turbinefit.turbine.solid import (
    TYPICAL_NACELLE,
    TurbineSolid,
    blade_profile,
    blade_twist,
    solid_mesh,
)

THETA = TurbineParams(3.0, -2.0, 85.0, 0.7, 5.0, 0.4, 55.0)
GEOMETRIES = [TurbineGeometry(), TurbineGeometry(0.087, 0.044, 2.5)]


def _signed_volume(v: np.ndarray, f: np.ndarray) -> float:
    return float(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6)


def _closed_and_oriented(f: np.ndarray) -> bool:
    """Every directed edge once, and its reverse once: a closed, consistently wound mesh."""
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    directed = {tuple(e) for e in edges.tolist()}
    return len(directed) == len(edges) and all((b, a) in directed for a, b in directed)


@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_parts_are_closed_outward_meshes(geometry: TurbineGeometry) -> None:
    solid = TurbineSolid(THETA.to_vector(), geometry)
    parts = solid_mesh(solid)
    assert [p.name for p in parts] == ["tower", "nacelle", "spinner", "blade_1", "blade_2",
                                       "blade_3"]
    for p in parts:
        assert np.isfinite(p.vertices).all()
        assert p.faces.min() >= 0 and p.faces.max() < len(p.vertices)
        v, f = p.vertices, p.faces
        area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                    axis=1)
        assert area.min() > 1e-8, p.name  # no degenerate triangle
        assert _closed_and_oriented(f), p.name
        assert _signed_volume(v, f) > 0, p.name  # faces wound counter-clockwise from outside
    # the tower: a frustum of radius h/30 -> h/45 (the polygon is a little inside it)
    h = THETA.tower_height
    r0, r1 = h / 30, h / 45
    frustum = math.pi * solid.tower_top_z / 3 * (r0 * r0 + r0 * r1 + r1 * r1)
    tower = parts[0]
    assert _signed_volume(tower.vertices, tower.faces) == pytest.approx(frustum, rel=0.01)
    assert tower.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert tower.vertices[:, 2].max() == pytest.approx(solid.tower_top_z)
    # the nacelle box: its volume, and it holds the tower top and reaches the hub
    nac = parts[1]
    assert _signed_volume(nac.vertices, nac.faces) == pytest.approx(
        8 * float(np.prod(solid.nac_half)))


@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_blades_lie_along_the_model_lines(geometry: TurbineGeometry) -> None:
    p, _ = model_points(THETA.to_vector(), geometry)
    hub, tips = p[2], p[3:]
    b = THETA.blade_length
    for i, part in enumerate(solid_mesh(TurbineSolid(THETA.to_vector(), geometry))[3:]):
        d = part.vertices - hub
        axis = (tips[i] - hub) / b
        along = d @ axis
        across = np.linalg.norm(d - along[:, None] * axis, axis=1)
        assert along.min() == pytest.approx(0.0, abs=1e-9)
        assert along.max() == pytest.approx(b)
        # never wider than the widest chord (0.08 b), thin at the tip
        assert across.max() <= 0.04 * b + 1e-9
        assert across[along > 0.999 * b].max() <= 0.0075 * b + 1e-9


def test_blade_rotation_turns_the_blades_about_the_shaft() -> None:
    """Blade 1 points up at rotation 0, and a third of a turn moves each blade to the next
    one's place: the mesh follows the fitted rotation."""
    up = THETA.to_dict() | {"blade_rotation": 0.0}
    solid = TurbineSolid(TurbineParams(**up).to_vector())
    blade_1 = solid_mesh(solid)[3].vertices
    assert blade_1[:, 2].max() == pytest.approx(solid.hub[2] + THETA.blade_length)
    turned = TurbineParams(**(up | {"blade_rotation": BLADE_PERIOD}))
    parts = solid_mesh(TurbineSolid(turned.to_vector()))
    np.testing.assert_allclose(parts[3].vertices[-1], solid_mesh(solid)[4].vertices[-1],
                               atol=1e-9)


def test_chord_in_the_rotor_plane_at_the_tip() -> None:
    """At zero pitch the chord lies in the rotor plane where the twist has run out (the tip)
    and is turned by the root's 14 degrees near the hub."""
    u = np.array([0.0, 0.2, 0.6, 1.0], dtype=np.float32)
    np.testing.assert_allclose(np.degrees(blade_twist(u, 0.0)),
                               [14.0, 14.0, 14.0 * 0.5 ** 1.5, 0.0], atol=1e-4)
    assert np.degrees(blade_twist(u[-1:], math.radians(80.0)))[0] == pytest.approx(80.0)
    solid = TurbineSolid(THETA.to_vector())
    for i in range(3):
        c = solid.chord_axis(i)
        assert abs(c @ solid.shaft) < 1e-12 and abs(c @ (solid.tips[i] - solid.hub)) < 1e-9


def test_blade_profile_widest_near_the_root() -> None:
    u = np.linspace(0.0, 1.0, 101, dtype=np.float32)
    A, B = blade_profile(u, 50.0)
    assert A.dtype == np.float32 and np.all(B <= A + 1e-6)
    assert float(u[np.argmax(A)]) == pytest.approx(0.22, abs=0.011)
    assert 2 * A.max() == pytest.approx(0.08 * 50.0, rel=1e-5)
    assert 2 * A[-1] == pytest.approx(0.015 * 50.0, rel=1e-5)
    assert A[0] == B[0] == pytest.approx(0.022 * 50.0, rel=1e-5)  # round root


def test_typical_nacelle_is_the_middle_of_the_renderers_ranges() -> None:
    assert TYPICAL_NACELLE == pytest.approx((2.3, 0.06, 0.975))


def test_rings_a_given_step_apart_keep_the_tower_and_refine_the_blades() -> None:
    solid = TurbineSolid(THETA.to_vector())
    coarse = {p.name: p for p in solid_mesh(solid)}
    fine = {p.name: p for p in solid_mesh(solid, ring_step=1.0)}
    for name, p in fine.items():
        assert _closed_and_oriented(p.faces) and _signed_volume(p.vertices, p.faces) > 0, name
        np.testing.assert_allclose(p.vertices.min(0), coarse[name].vertices.min(0), atol=1e-6)
        np.testing.assert_allclose(p.vertices.max(0), coarse[name].vertices.max(0), atol=1e-6)
    tower = fine["tower"].vertices
    z = np.unique(np.round(tower[:, 2], 9))
    assert np.diff(z).max() <= 1.0 + 1e-9  # rings at most 1 m apart
    assert _signed_volume(tower, fine["tower"].faces) == pytest.approx(
        _signed_volume(coarse["tower"].vertices, coarse["tower"].faces), rel=1e-9)
    # the blades' rings: along the blade at most 1 m apart (denser towards the tip)
    hub = solid.hub
    for i in range(3):
        v = fine[f"blade_{i + 1}"].vertices
        e = (solid.tips[i] - hub) / np.linalg.norm(solid.tips[i] - hub)
        spans = np.unique(np.round((v - hub) @ e, 6))
        assert np.diff(spans).max() <= 1.0 + 1e-6
        assert _signed_volume(v, fine[f"blade_{i + 1}"].faces) == pytest.approx(
            _signed_volume(coarse[f"blade_{i + 1}"].vertices, coarse[f"blade_{i + 1}"].faces),
            rel=0.02)
