"""The independent clearance check (:mod:`turbinefit.inspection.clearance`): its samples
reach every point of the surface within their tolerance, its distances are lower bounds
within the tolerance of closed-form ones, inside is negative, and a leg that crosses a
part between two far samples is caught."""

from __future__ import annotations

import math

import numpy as np
import pytest

from turbinefit.inspection.clearance import (
    ROTOR,
    inside,
    path_clearance,
    point_clearance,
    solid_samples,
)
from turbinefit.inspection.surface import HUB, NACELLE, TOWER, SurfaceShape, TurbineSurface
from turbinefit.sim.turbines import REALISTIC_GEOMETRY
from turbinefit.turbine.model import TurbineParams

TURBINE = TurbineParams(3.0, -2.0, 60.0, math.radians(40.0), 4.0, math.radians(25.0), 30.0)


@pytest.fixture(scope="module")
def surface() -> TurbineSurface:
    # twisted and pitched blades, a tilted shaft: the frames the samples must follow
    return TurbineSurface(TURBINE, REALISTIC_GEOMETRY,
                          SurfaceShape(math.radians(5.0), math.radians(-14.0)))


@pytest.fixture(scope="module")
def samples(surface: TurbineSurface):
    return solid_samples(surface, spacing=0.4)


def _surface_points(surface: TurbineSurface, rng: np.random.Generator, n: int
                    ) -> dict[int, np.ndarray]:
    """Random points on each part's surface, from its parametrisation."""
    out = {}
    for i, bl in enumerate(surface.blades):
        s = rng.uniform(0.0, bl.length, n)
        phi = rng.uniform(0.0, 2.0 * math.pi, n)
        A, B = surface.blade_section(s)
        tw = surface.twist(s)[:, None]
        c = np.cos(tw) * bl.chord + np.sin(tw) * bl.normal
        m = np.cos(tw) * bl.normal - np.sin(tw) * bl.chord
        out[i] = (bl.root + s[:, None] * bl.axis + (A * np.cos(phi))[:, None] * c
                  + (B * np.sin(phi))[:, None] * m)
    so = surface.solid
    z = rng.uniform(surface.base[2], so.tower_top_z, n)
    r = so.r0 + (so.r1 - so.r0) * (z - surface.base[2]) / (so.tower_top_z - surface.base[2])
    a = rng.uniform(0.0, 2.0 * math.pi, n)
    out[TOWER] = np.column_stack([surface.base[0] + r * np.cos(a),
                                  surface.base[1] + r * np.sin(a), z])
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    E = np.stack([so.shaft, so.side, so.up])
    out[HUB] = so.spin_centre + (u * np.array([so.spin_len, so.spin_r, so.spin_r])) @ E
    box = rng.uniform(-1.0, 1.0, (n, 3))
    k = rng.integers(0, 3, n)
    box[np.arange(n), k] = np.sign(box[np.arange(n), k])  # on a face
    out[NACELLE] = so.nac_centre + (box * so.nac_half) @ E
    return out


def test_every_surface_point_is_within_the_tolerance_of_a_sample(surface, samples) -> None:
    assert 0.3 < samples.tolerance < 0.45
    for part, pts in _surface_points(surface, np.random.default_rng(0), 3000).items():
        d, _ = samples.trees[part].query(pts)
        assert d.max() <= samples.tolerance, (part, d.max())
        assert d.max() > 0.3 * samples.tolerance  # the bound is not loose by far


def test_distances_are_lower_bounds_within_the_tolerance(surface, samples) -> None:
    so = surface.solid
    tol = samples.tolerance
    # beside the tower at mid-height, 7 m off its surface (the cone's slope is negligible)
    z = surface.base[2] + 20.0
    r = so.r0 + (so.r1 - so.r0) * 20.0 / (so.tower_top_z - surface.base[2])
    away = -surface.heading_dir  # behind the tower, far from the rotor
    p = np.array([surface.base[0], surface.base[1], z]) + (r + 7.0) * away
    d = point_clearance(p[None], samples)[0]
    assert 7.0 - tol - 1e-9 <= d[TOWER] <= 7.0 + 0.01
    assert np.argmin(d) == TOWER
    # beyond blade A's tip along its axis: 5 m from the flat cap
    bl = surface.blades[0]
    q = bl.root + (bl.length + 5.0) * bl.axis
    d = point_clearance(q[None], samples)[0]
    assert 5.0 - tol - 1e-9 <= d[0] <= 5.0 + 1e-9
    # inside blade A and inside the nacelle: negative
    mid = bl.root + 0.5 * bl.length * bl.axis
    d = point_clearance(np.stack([mid, so.nac_centre]), samples)
    assert d[0, 0] < 0 and d[1, NACELLE] < 0
    assert inside(surface, mid[None])[0, 0] and not inside(surface, q[None])[0, 0]


def test_quick_search_is_exact_where_asked(surface, samples) -> None:
    rng = np.random.default_rng(1)
    p = surface.hub + rng.uniform(-40.0, 40.0, (400, 3))
    p = p[~inside(surface, p).any(axis=1)]
    exact = point_clearance(p, samples)
    quick = point_clearance(p, samples, exact_below=10.0)
    near = exact < 10.0
    np.testing.assert_allclose(quick[near], exact[near], atol=1e-9)
    assert np.all(quick <= exact + 1e-9) and np.all(quick[~near] >= 10.0 - 1e-9)


def test_a_leg_through_a_blade_is_caught_between_far_samples(surface, samples) -> None:
    bl = surface.blades[1]
    mid = bl.root + 0.6 * bl.length * bl.axis
    path = np.stack([mid - 12.0 * bl.normal, mid + 12.0 * bl.normal, mid + 30.0 * bl.normal])
    c = path_clearance(path, samples, leg_step=30.0)  # no sample inside the blade
    assert c.distance[0] > 10.0 and c.distance[1] > 10.0
    assert c.leg_distance[0] <= 0.0 and c.leg_part[0] == 1 and c.leg_distance[1] > 10.0
    assert c.first_below(5.0, ROTOR) == 0
    assert c.least(ROTOR)[1:] == (1, 0, True)
    assert path_clearance(path[2:], samples).first_below(5.0) is None
