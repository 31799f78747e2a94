"""The catalogue of turbine types: every entry read, in metres, plausible, with a source."""

from __future__ import annotations

import pytest

from turbinefit.errors import InputError
from turbinefit.io.turbine_types import turbine_type, turbine_types
from turbinefit.turbine.model import THETA_LOWER, THETA_UPPER


def test_every_type_is_in_metres_and_plausible() -> None:
    types = turbine_types()
    assert len(types) >= 10
    for key, t in types.items():
        # rotor diameters of grid turbines: 40-250 m (not radii, not feet, not km)
        assert 40.0 <= t.rotor_diameter <= 250.0, key
        for h in t.hub_heights:
            assert THETA_LOWER[2] <= h <= THETA_UPPER[2], key
            assert h > t.rotor_diameter / 2 + 10.0, key  # tips clear the ground
        # overhang: a few percent of the rotor, inside the model's bounds
        assert 0.01 * t.rotor_diameter <= t.overhang <= 0.1 * t.rotor_diameter, key
        assert THETA_LOWER[4] <= t.overhang <= THETA_UPPER[4], key
        assert t.source.strip() and str(int(t.rotor_diameter)) in t.source, key
        p = t.prior()
        assert p.blade_length == pytest.approx(t.rotor_diameter / 2)
        assert p.hub_height == t.hub_heights[0]


def test_an_unknown_type_names_the_known_ones() -> None:
    assert turbine_type("Vestas-V90").rotor_diameter == 90.0
    with pytest.raises(InputError, match=r"--type: unknown turbine type 'v91'; known: .*vestas-v90"):
        turbine_type("v91")
