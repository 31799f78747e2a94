"""Sampled turbines (turbinefit.sim.turbines)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from turbinefit.sim import preset_turbine, sample_turbine


def test_sampled_turbines_are_realistic():
    rng = np.random.default_rng(0)
    for _ in range(200):
        t = sample_turbine(rng)
        assert 70.0 <= t.tower_height <= 100.0
        assert 40.0 <= t.blade_length <= 63.0 and t.blade_length <= t.tower_height - 20.0
        assert 4.0 <= t.nacelle_length <= 7.0
        assert math.hypot(t.base_x, t.base_y) <= 3.0
        assert t == t.canonical()
    assert preset_turbine("nrel5mw").tower_height == 87.6
    with pytest.raises(ValueError):
        preset_turbine("nonesuch")
