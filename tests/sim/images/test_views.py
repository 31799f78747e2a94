"""Random training views (turbinefit.sim.images.views)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import CAMERA

from turbinefit.sim.images import sample_closeup_view, sample_training_view
from turbinefit.sim.images.views import CLOSEUP_RANGE_M
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


def test_sample_closeup_view() -> None:
    """Close-ups: 3-30 m (plus the part's radius) from a blade or the tower, which crosses
    the frame, above the ground, clear of the solid; deterministic by rng state."""
    rng = np.random.default_rng(1)
    near = 0
    for _ in range(60):
        t = sample_turbine(rng)
        state = rng.bit_generator.state
        T = sample_closeup_view(rng, t, CAMERA)
        rng.bit_generator.state = state
        again = sample_closeup_view(rng, t, CAMERA)
        np.testing.assert_array_equal(T.wxyz_xyz, again.wxyz_xyz)
        pos = T.translation
        assert pos[2] >= 3.0 - 1e-9
        segs = skeleton_segments(t)
        d, _ = distance_to_segments(pos[None], segs)
        assert d[0] >= 2.0
        near += d[0] <= 5.0 + CLOSEUP_RANGE_M[1]
        # some blade or tower line crosses the middle half of the frame
        cam_p = T.inverse().apply(segs.reshape(-1, 3)).reshape(-1, 2, 3)
        s = np.linspace(0.0, 1.0, 200)[:, None, None]
        pts = cam_p[None, :, 0] + s * (cam_p[None, :, 1] - cam_p[None, :, 0])
        uv, front, _ = CAMERA.project_unbounded(pts.reshape(-1, 3))
        mid = front & (np.abs(uv[:, 0] - CAMERA.cx) < CAMERA.width / 4) \
            & (np.abs(uv[:, 1] - CAMERA.cy) < CAMERA.height / 4)
        assert mid.any()
    assert near >= 55
