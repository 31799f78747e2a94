"""Random training views (turbinefit.sim.images.views)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import CAMERA

from turbinefit.sim.images import sample_training_view
from turbinefit.sim.trajectory import distance_to_segments
from turbinefit.sim.turbines import sample_turbine
from turbinefit.turbine.model import TurbineParams, skeleton_segments

pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")  # no NaN/inf on the way


def test_sample_training_view() -> None:
    rng = np.random.default_rng(0)
    dists, pitches, rolls = [], [], []
    for k in range(200):
        t = sample_turbine(rng) if k % 4 == 0 else TurbineParams(*sample_turbine(rng).to_vector())
        T = sample_training_view(rng, t, CAMERA)
        pos = T.translation
        assert pos[2] >= 3.0 - 1e-9
        d, _ = distance_to_segments(pos[None], skeleton_segments(t))
        assert d[0] >= 6.0 - 1e-9
        dists.append(d[0])
        R = T.rotation_matrix()
        pitches.append(math.asin(R[2, 2]))  # camera z (forward) elevation
        rolls.append(math.asin(np.clip(R[2, 0] / math.cos(pitches[-1]), -1.0, 1.0)))
    dists_a = np.array(dists)
    assert (dists_a < 40.0).sum() >= 20
    assert (dists_a > 150.0).sum() >= 20
    assert np.all(np.abs(np.degrees(pitches)) <= 60.0 + 1e-6)
    assert np.all(np.abs(np.degrees(rolls)) <= 5.0 + 1e-6)
