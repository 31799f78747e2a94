"""The initial turbine from heat-maps and poses (turbinefit.solver.init): noiseless maps give
θ to millimetres and millidegrees from any heading (the world turned about z) and any blade
rotation (three-fold symmetry); one side of the turbine still gives base and height; a
turbine never seen is a NotDetermined naming it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.sim import preset, simulate_flight
from turbinefit.solver.init import NotDetermined, TurbinePrior, initial_turbine
from turbinefit.turbine.model import BLADE_PERIOD, TurbineParams, param_errors


@pytest.fixture(scope="module", params=[0, 3])
def exact_flight(request: pytest.FixtureRequest):
    """60 keyframes, exact poses, noiseless 160 x 120 maps."""
    return simulate_flight(preset("exact", n_keyframes=60, seed=request.param,
                                  heatmap_size=(160, 120)))


def _turned(poses: SE3, turbine: TurbineParams, alpha: float) -> tuple[SE3, TurbineParams]:
    """The same scene with the world turned by ``alpha`` about z (the maps do not change)."""
    c, s = math.cos(alpha), math.sin(alpha)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    turn = SE3.from_rotation_translation(np.broadcast_to(Rz, (len(poses), 3, 3)),
                                         np.zeros((len(poses), 3)))
    v = turbine.to_vector()
    v[:2] = Rz[:2, :2] @ v[:2]
    v[3] += alpha
    return turn @ poses, TurbineParams.from_vector(v).canonical()


def _assert_close(estimate: TurbineParams, truth: TurbineParams) -> None:
    e = param_errors(estimate, truth)
    assert np.all(np.abs(e[[0, 1, 2, 4, 6]]) < 0.03), e  # metres
    assert np.all(np.abs(np.degrees(e[[3, 5]])) < 0.05), np.degrees(e)


@pytest.mark.parametrize("alpha_deg", [0.0, 100.0, 200.0, 310.0])
def test_noiseless_maps_give_theta_from_any_heading(exact_flight, alpha_deg: float) -> None:
    poses, truth = _turned(exact_flight.gt_world_T_cam, exact_flight.gt_turbine,
                           math.radians(alpha_deg))
    res = initial_turbine(exact_flight.heatmaps, exact_flight.camera, poses)
    _assert_close(res.turbine, truth)
    assert 0.0 <= res.turbine.blade_rotation < BLADE_PERIOD
    assert set(res.source.values()) == {"images"}


def test_blade_rotation_is_found_modulo_120_degrees(exact_flight) -> None:
    """The truth's blade rotation given as phi + 120 deg or phi - 240 deg is the same
    turbine: the estimate matches each."""
    res = initial_turbine(exact_flight.heatmaps, exact_flight.camera, exact_flight.gt_world_T_cam)
    for shift in (BLADE_PERIOD, -2 * BLADE_PERIOD):
        v = exact_flight.gt_turbine.to_vector()
        v[5] += shift
        _assert_close(res.turbine, TurbineParams.from_vector(v))


def test_one_side_of_the_turbine_still_gives_base_and_height(exact_flight) -> None:
    truth = exact_flight.gt_turbine
    centre = np.array([truth.base_x, truth.base_y])
    ahead = np.array([math.cos(truth.heading), math.sin(truth.heading)])
    xy = exact_flight.gt_world_T_cam.translation[:, :2]
    front = np.nonzero((xy - centre) @ ahead > 0)[0]
    assert 5 < front.size < 55  # really one side
    res = initial_turbine(exact_flight.heatmaps, exact_flight.camera,
                          exact_flight.gt_world_T_cam, TurbinePrior(blade_length=63.0),
                          keyframes=front)
    e = param_errors(res.turbine, truth)
    assert np.hypot(e[0], e[1]) < 0.3 and abs(e[2]) < 0.3, e


def test_a_turbine_never_seen_names_what_to_add(exact_flight) -> None:
    n = 8
    maps = HeatmapStack(np.zeros((n, 7, 120, 160), dtype=np.float32))
    with pytest.raises(NotDetermined, match=r"cannot determine turbine: .*--near") as exc:
        initial_turbine(maps, exact_flight.camera, exact_flight.gt_world_T_cam[:n])
    assert exc.value.parameter == "turbine"


def test_without_tips_the_blade_length_needs_a_type(exact_flight) -> None:
    maps = np.stack([exact_flight.heatmaps[k] for k in range(len(exact_flight.heatmaps))])
    maps[:, 3] = 0.0  # no tip seen
    with pytest.raises(NotDetermined, match=r"cannot determine blade_length: .*--type"):
        initial_turbine(HeatmapStack(maps), exact_flight.camera, exact_flight.gt_world_T_cam)
