"""The fit problem (turbinefit.solver.problem): gradients against finite differences, the
gauge, keyframe windows, the pairwise edge."""

import numpy as np
import pytest
from support import CAMERA, orbit_poses, smooth_heatmaps

from turbinefit.flight import Flight
from turbinefit.heatmaps import HeatmapStack
from turbinefit.solver.config import FitConfig
from turbinefit.solver.problem import FitProblem
from turbinefit.solver.window import Keyframes
from turbinefit.turbine.model import TurbineParams

N = 4


def make_flight(sigma: bool = False) -> Flight:
    """``sigma``: with RTK-like position standard deviations (the measured positions then
    differ from the poses', so the position priors have a gradient)."""
    poses = orbit_poses(N)
    rng = np.random.default_rng(0)
    meas = poses.retract(rng.normal(scale=0.05, size=(N, 6)))
    return Flight(
        camera=CAMERA, timestamps=np.arange(N, dtype=float), world_T_cam=poses,
        heatmaps=HeatmapStack(smooth_heatmaps(N, seed=11)),
        turbine=TurbineParams(0.0, 0.0, 80.0, 0.6, 5.0, 0.3, 50.0), odometry=meas,
        position_sigma=rng.uniform(0.02, 2.0, size=(N, 3)) if sigma else None)


@pytest.mark.parametrize("points,lines,mode,robust,gauge,frame,sigma", [
    ("interp", "interp", "joint", "none", "first", "measured", False),
    ("corr", "corr", "joint", "huber", "gps", "estimated", False),
    ("corr", "interp", "pose", "cauchy", "first", "measured", False),
    ("corr", "interp", "joint", "huber", "first", "estimated", False),
    ("interp", "corr", "turbine", "none", "first", "measured", False),
    ("corr", "corr", "joint", "cauchy", "first", "estimated", True),
    ("interp", "interp", "pose", "none", "gps", "measured", True),
])
def test_gradient_matches_finite_differences(points, lines, mode, robust, gauge, frame, sigma):
    flight = make_flight(sigma)
    cfg = FitConfig(points=points, lines=lines, mode=mode, robust=robust, gauge=gauge,
                    pair_frame=frame, samples_per_line=5, robust_scale=0.5,
                    corr_threshold=0.05)
    prob = FitProblem(flight, cfg)
    poses = flight.world_T_cam
    if sigma:  # away from the measured positions
        poses = poses.retract(np.c_[np.random.default_rng(3).normal(size=(N, 3)),
                                    np.zeros((N, 3))])
    theta = flight.turbine.to_vector()
    corr = prob.find_correspondences(poses, theta)
    lin = prob.linearize(poses, theta, corr)
    assert lin.g_p is not None
    eps = 1e-6

    def cost(p, t):
        return prob.linearize(p, t, corr, with_jacobian=False).cost

    assert ("position" in lin.terms) == (sigma and mode != "turbine")
    for k in range(N):
        for i in range(6):
            d = np.zeros((N, 6))
            d[k, i] = eps
            num = (cost(poses.retract(d), theta) - cost(poses.retract(-d), theta)) / (2 * eps)
            expected = 0.0 if prob.fixed[k] else num
            assert lin.g_p[k, i] == pytest.approx(expected, rel=1e-4, abs=1e-4 * (1 + abs(num)))
    if mode == "pose":
        assert lin.g_t is None and lin.C is None
        return
    assert lin.g_t is not None
    for i in range(7):
        t = np.zeros(7)
        t[i] = eps
        num = (cost(poses, theta + t) - cost(poses, theta - t)) / (2 * eps)
        assert lin.g_t[i] == pytest.approx(num, rel=1e-4, abs=1e-4 * (1 + abs(num)))


def test_gauge_holds_first_pose():
    prob = FitProblem(make_flight(), FitConfig())
    assert prob.fixed.tolist() == [True, False, False, False]
    assert FitProblem(make_flight(), FitConfig(gauge="gps")).fixed.sum() == 0
    assert FitProblem(make_flight(), FitConfig(mode="turbine")).fixed.all()


def test_keyframes_give_the_same_problem_as_their_flight():
    flight = make_flight()
    data = Keyframes(flight.camera, flight.timestamps, flight.world_T_cam, flight.heatmaps,
                     flight.odometry)
    cfg = FitConfig(gauge="gps")
    poses = flight.world_T_cam.retract(np.full((N, 6), 0.01))
    theta = flight.turbine.to_vector()
    lins = []
    for prob in (FitProblem(flight, cfg), FitProblem(data, cfg)):
        lins.append(prob.linearize(poses, theta, prob.find_correspondences(poses, theta)))
    assert lins[0].cost == lins[1].cost and lins[0].terms == lins[1].terms
    assert np.array_equal(lins[0].D, lins[1].D) and np.array_equal(lins[0].g_p, lins[1].g_p)


def test_pairwise_edge_is_the_edge_of_the_pairwise_term():
    flight = make_flight()
    cfg = FitConfig(gauge="gps")
    prob = FitProblem(flight, cfg)
    poses = flight.world_T_cam.retract(np.full((N, 6), 0.02))
    cost = 0.0
    for e in range(N - 1):
        r, Ji, Jj = prob.pairwise_edge(poses, e)
        assert r.shape == (6,) and Ji.shape == Jj.shape == (6, 6)
        cost += 0.5 * float(r @ r)
    lin = prob.linearize(poses, flight.turbine.to_vector(), prob.find_correspondences(
        poses, flight.turbine.to_vector()), with_jacobian=False)
    assert cost == pytest.approx(lin.terms["pairwise"], rel=1e-12)


def test_position_priors_only_with_sigmas() -> None:
    """Without position sigmas the problem is the one it always was (the same terms and
    cost); with them, one more term whose Hessian is 1/sigma^2 on each position."""
    plain, rtk = make_flight(), make_flight(sigma=True)
    theta = plain.turbine.to_vector()
    cfg = FitConfig(points="corr", lines="corr")
    a, b = FitProblem(plain, cfg), FitProblem(rtk, cfg)
    assert a.position_sigma is None
    corr = a.find_correspondences(plain.world_T_cam, theta)
    la = a.linearize(plain.world_T_cam, theta, corr)
    moved = plain.world_T_cam.retract(np.c_[np.full((N, 3), 0.1), np.zeros((N, 3))])
    lb = b.linearize(moved, theta, corr)
    lb0 = b.linearize(plain.world_T_cam, theta, corr)
    assert "position" not in la.terms and lb0.terms["position"] == 0.0
    assert {k: v for k, v in lb0.terms.items() if k != "position"} == la.terms
    assert lb.terms["position"] == pytest.approx(0.5 * np.sum((0.1 / rtk.position_sigma) ** 2))
    assert la.D is not None and lb0.D is not None
    np.testing.assert_allclose(lb0.D[1:, :3, :3] - la.D[1:, :3, :3],
                               np.stack([np.diag(1 / s**2) for s in rtk.position_sigma[1:]]))
    # a window of keyframes carries its sigmas
    sub = Keyframes(rtk.camera, rtk.timestamps, rtk.world_T_cam, rtk.heatmaps,
                    rtk.odometry, rtk.position_sigma)
    np.testing.assert_array_equal(FitProblem(sub, cfg, np.array([1, 2])).position_sigma,
                                  rtk.position_sigma[1:3])
