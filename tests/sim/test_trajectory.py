"""Inspection trajectories (turbinefit.sim.trajectory): clear of the turbine, looking at it,
smooth and independent of the number of keyframes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import SIM_CAMERA

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, quat_conjugate, quat_log, quat_multiply
from turbinefit.sim import inspection_trajectory, plan_inspection, preset_turbine, sample_turbine
from turbinefit.sim.trajectory import PHASES, distance_to_segments
from turbinefit.sim.turbines import REALISTIC_GEOMETRY
from turbinefit.turbine.model import (
    LINES,
    PAPER_GEOMETRY,
    TurbineGeometry,
    TurbineParams,
    model_points,
    skeleton_segments,
)


def visible_parts(poses: SE3, theta: TurbineParams, geometry: TurbineGeometry = PAPER_GEOMETRY,
                  camera: PinholeCamera = SIM_CAMERA) -> tuple[np.ndarray, np.ndarray]:
    """Per keyframe: how many of the 6 model points, and whether any of 6 points + 250
    line samples, project inside the image."""
    pts, _ = model_points(theta.to_vector(), geometry)
    s = np.linspace(0.0, 1.0, 50)[:, None]
    samples = np.concatenate([pts[a] * (1 - s) + pts[b] * s for a, b, _ in LINES])
    allp = np.concatenate([pts, samples])
    cam_p = poses.inverse()[:, None] @ allp[None]
    _, valid, _ = camera.project(cam_p)
    return valid[:, :6].sum(axis=1), valid.any(axis=1)


@pytest.mark.parametrize("seed,n,geometry", [
    (0, 2, PAPER_GEOMETRY), (1, 60, REALISTIC_GEOMETRY), (2, 400, PAPER_GEOMETRY),
    (3, 1500, REALISTIC_GEOMETRY), (4, 250, PAPER_GEOMETRY), (5, 250, REALISTIC_GEOMETRY),
])
def test_trajectory_keeps_clear_and_looks_at_the_turbine(seed, n, geometry):
    rng = np.random.default_rng(seed)
    theta = sample_turbine(rng) if seed % 2 else preset_turbine("nrel5mw", rng)
    path = plan_inspection(theta, n, rng, geometry)
    poses = path.world_T_cam
    assert poses.batch_shape == (n,)
    p = poses.translation
    d, _ = distance_to_segments(p, skeleton_segments(theta, geometry))
    assert d.min() >= 3.0
    assert p[:, 2].min() >= 2.0
    R = poses.rotation_matrix()
    assert np.all(R[:, 2, 1] < -0.5)  # camera y points down in the world
    assert np.abs(R[:, 2, 0]).max() < math.sin(math.radians(5.0))  # (almost) no roll
    n_pts, any_part = visible_parts(poses, theta, geometry)
    assert any_part.mean() >= 0.95
    if n >= 60:
        assert set(np.unique(path.phase)) == set(range(len(PHASES)))
        close = path.phase == PHASES.index("blades")
        assert np.mean(n_pts[close] < 6) > 0.9  # close views are partial
        assert n_pts[0] == 6  # the approach starts with the whole turbine in view


def test_trajectory_is_smooth_and_independent_of_n():
    rng_state = 7
    theta = preset_turbine("v80", np.random.default_rng(1))
    dense = inspection_trajectory(theta, 3000, np.random.default_rng(rng_state))
    sparse = inspection_trajectory(theta, 30, np.random.default_rng(rng_state))
    step = np.linalg.norm(np.diff(dense.translation, axis=0), axis=-1)
    assert step.max() < 3.0 * np.median(step)  # evenly spread, no jumps
    dq = quat_multiply(quat_conjugate(dense.wxyz[:-1]), dense.wxyz[1:])
    assert np.degrees(np.linalg.norm(quat_log(dq), axis=-1)).max() < 5.0
    # the sparse flight's keyframes lie on the dense flight's path
    gap = np.linalg.norm(sparse.translation[:, None] - dense.translation[None], axis=-1)
    assert gap.min(axis=1).max() < 1.0
    np.testing.assert_allclose(sparse.translation[[0, -1]], dense.translation[[0, -1]])
    one = inspection_trajectory(theta, 1, np.random.default_rng(rng_state))
    np.testing.assert_allclose(one.translation[0], dense.translation[0])
