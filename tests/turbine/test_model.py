"""The turbine model (turbinefit.turbine.model): Jacobians against finite differences, the
paper's formulas, geometry of blades and nacelle, canonical ranges, validation."""

import math

import numpy as np
import pytest

from turbinefit.turbine.model import (
    BLADE_PERIOD,
    LINES,
    TurbineGeometry,
    TurbineParams,
    line_samples,
    model_point_error,
    model_points,
    param_errors,
)

THETA = TurbineParams(3.0, -2.0, 85.0, 0.7, 5.0, 0.4, 55.0)


def numeric_jacobian(theta, geometry):
    eps = 1e-6
    cols = []
    for i in range(7):
        d = np.zeros(7)
        d[i] = eps
        cols.append((model_points(theta + d, geometry)[0] - model_points(theta - d, geometry)[0])
                    / (2 * eps))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("geometry", [TurbineGeometry(), TurbineGeometry(0.087, 0.044, 2.5)])
def test_model_jacobian_matches_finite_differences(geometry):
    theta = THETA.to_vector()
    _, J = model_points(theta, geometry, with_jacobian=True)
    np.testing.assert_allclose(J, numeric_jacobian(theta, geometry), atol=1e-6)


def test_paper_model_formulas():
    cx, cy, h, w, r, phi, b = THETA.to_vector()
    P, _ = model_points(THETA.to_vector())
    np.testing.assert_allclose(P[0], [cx, cy, 0])
    np.testing.assert_allclose(P[1], [cx, cy, h])
    np.testing.assert_allclose(P[2], [cx + r * math.cos(w), cy + r * math.sin(w), h])
    for i in range(3):
        ph = phi + 2 * math.pi * i / 3
        local = np.array([r, -b * math.sin(ph), h + b * math.cos(ph)])
        Rz = np.array([[math.cos(w), -math.sin(w), 0], [math.sin(w), math.cos(w), 0], [0, 0, 1]])
        np.testing.assert_allclose(P[3 + i], np.array([cx, cy, 0]) + Rz @ local, atol=1e-12)


def test_blades_lie_in_rotor_plane_and_nacelle_is_horizontal():
    P, _ = model_points(THETA.to_vector())
    heading = np.array([math.cos(THETA.heading), math.sin(THETA.heading), 0.0])
    for i in range(3):
        assert abs((P[3 + i] - P[2]) @ heading) < 1e-9
        assert np.linalg.norm(P[3 + i] - P[2]) == pytest.approx(THETA.blade_length)
    assert P[2, 2] == pytest.approx(P[1, 2])
    # tips 120 degrees apart
    d = P[3:] - P[2]
    cos = d @ d.T / THETA.blade_length**2
    np.testing.assert_allclose(cos[np.triu_indices(3, 1)], -0.5, atol=1e-12)


def test_canonical_ranges_and_periodic_errors():
    t = TurbineParams(0, 0, 80, -0.1, 5, -0.05 + 4 * BLADE_PERIOD, -50).canonical()
    assert 0 <= t.heading < 2 * math.pi and 0 <= t.blade_rotation < BLADE_PERIOD
    assert t.blade_length == 50
    # the canonical turbine has the same model points (tips permuted)
    orig = TurbineParams(0, 0, 80, -0.1, 5, -0.05 + 4 * BLADE_PERIOD, -50)
    assert model_point_error(t, orig) < 1e-9
    e = param_errors(TurbineParams(0, 0, 80, 0.01, 5, BLADE_PERIOD - 0.01, 50),
                     TurbineParams(0, 0, 80, 2 * math.pi - 0.01, 5, 0.01, 50))
    np.testing.assert_allclose(e[[3, 5]], [0.02, -0.02], atol=1e-12)


def test_model_point_error_is_metric_of_shift():
    shifted = TurbineParams(THETA.base_x + 1.0, *THETA.to_vector()[1:])
    assert model_point_error(shifted, THETA) == pytest.approx(1.0)


def test_line_samples_lie_on_lines_with_jacobian():
    theta = THETA.to_vector()
    P, JP = model_points(theta, with_jacobian=True)
    S, JS, ch = line_samples(P, JP, 4)
    assert S.shape == (20, 3) and JS is not None and JS.shape == (20, 3, 7)
    assert ch.tolist() == [4] * 4 + [5] * 4 + [6] * 12
    for li, (a, b, _) in enumerate(LINES):
        seg = S[li * 4:(li + 1) * 4]
        d = P[b] - P[a]
        cross = np.cross(seg - P[a], d)
        assert np.allclose(cross, 0, atol=1e-9)
    eps = 1e-6
    for i in range(7):
        d = np.zeros(7)
        d[i] = eps
        num = (line_samples(model_points(theta + d)[0], None, 4)[0]
               - line_samples(model_points(theta - d)[0], None, 4)[0]) / (2 * eps)
        np.testing.assert_allclose(JS[:, :, i], num, atol=1e-6)


def test_rejects_non_finite():
    with pytest.raises(ValueError):
        TurbineParams(0, 0, float("nan"), 0, 5, 0, 50)


def test_geometry_accepts_real_numbers_as_floats():
    g = TurbineGeometry(np.float32(0.5), 1, np.int64(-2))
    assert (g.shaft_tilt, g.blade_cone, g.hub_offset) == (0.5, 1.0, -2.0)
    assert all(type(v) is float for v in (g.shaft_tilt, g.blade_cone, g.hub_offset))
    assert g == TurbineGeometry(0.5, 1.0, -2.0)


@pytest.mark.parametrize("field", ["shaft_tilt", "blade_cone", "hub_offset"])
@pytest.mark.parametrize("value", ["abc", "0.1", True, None, [0.1], float("nan"), float("inf"),
                                   np.bool_(True), 1j])
def test_geometry_rejects_non_numbers_naming_the_field(field, value):
    with pytest.raises(ValueError, match=rf"^geometry\.{field}: must be a finite real number"):
        TurbineGeometry(**{field: value})
