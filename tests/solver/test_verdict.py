"""The verdict on a fit (turbinefit.solver.verdict): evidence-free heat-maps fail, a
normal flight is ok, theta stays inside its bounds, its covariance is the inverse Hessian."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from support import simulated_flight

import turbinefit.solver.lm as lm
import turbinefit.solver.verdict as verdict
from turbinefit.heatmaps import HeatmapStack
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import fit
from turbinefit.solver.problem import FitProblem
from turbinefit.solver.rounds import initial_correspondences
from turbinefit.solver.verdict import Signals, judge, theta_covariance, theta_uncertainty
from turbinefit.turbine.model import THETA_UPPER, TurbineParams

#: the command-line defaults for heat-map files
CLI = FitConfig(lines="corr", line_residual="normal", robust="cauchy")


@pytest.fixture(scope="module")
def flight():
    return simulated_flight(30, seed=4, width=320)


def test_normal_flight_is_ok(flight) -> None:
    res = fit(flight, CLI)
    assert res.verdict == "ok", res.reasons
    assert res.reasons == []
    s = res.signals
    assert s is not None and s.evidence_share > 0.9 and s.inlier_share is not None
    assert s.inlier_share > 0.9 and s.pose_shift_sigmas is not None
    assert res.theta_std is not None and np.all(res.theta_std > 0)
    assert res.theta_std[2] < 1.0  # the tower is known to well under a metre


@pytest.mark.parametrize("value", [0.0, 1.0, 0.3])
@pytest.mark.parametrize("config", [CLI, FitConfig()], ids=["cli-defaults", "paper-best"])
def test_evidence_free_heatmaps_fail(flight, value: float, config: FitConfig) -> None:
    shape = (flight.num_keyframes, 7, flight.camera.height, flight.camera.width)
    blank = dataclasses.replace(flight, heatmaps=HeatmapStack(np.full(shape, value,
                                                                      np.float32)))
    res = fit(blank, config)
    assert res.verdict == "failed"
    assert "0 % of keyframes have heat-map evidence" in res.reasons
    th = res.turbine.to_vector()
    assert th[4] >= 0.0 and 10.0 <= th[2] <= 250.0 and 5.0 <= th[6] <= 150.0


def _signals(**kw: object) -> Signals:
    base = dict(keyframes=50, heatmap_width_px=320, evidence_share=1.0, inlier_share=0.98,
                reprojection_px=0.1, pose_shift_m=2.0, pose_shift_sigmas=0.5,
                pairwise_chi2=0.2, theta=TurbineParams(0, 0, 87.6, 1.0, 5.0, 0.3, 63.0),
                theta_std=np.array([0.5, 0.5, 0.2, 0.003, 0.05, 0.002, 0.2]), iterations=20,
                finite=True)
    base.update(kw)
    return Signals(**base)  # type: ignore[arg-type]


@pytest.mark.parametrize(("change", "expected", "words"), [
    ({}, "ok", ""),
    ({"finite": False}, "failed", "non-finite"),
    ({"iterations": 0}, "failed", "no step"),
    ({"heatmap_width_px": 7}, "failed", "7 px wide"),
    ({"evidence_share": 0.4}, "doubtful", "40 % of keyframes"),
    ({"inlier_share": 0.2}, "failed", "20 % of the image terms"),
    ({"pose_shift_sigmas": 3.0}, "doubtful", "3.0 sigma"),
    ({"pose_shift_sigmas": 28.0}, "failed", "28.0 sigma"),
    ({"pairwise_chi2": 30.0}, "failed", "chi-square 30.0"),
    ({"theta": TurbineParams(0, 0, 250.0, 1.0, 5.0, 0.3, 63.0)}, "failed", "tower_height"),
    ({"theta": TurbineParams(0, 0, 60.0, 1.0, 5.0, 0.3, 63.0)}, "failed", "hit the ground"),
    ({"theta_std": np.array([0.5, 0.5, 4.0, 0.003, 0.05, 0.002, 0.2])}, "doubtful",
     "tower_height standard deviation 4.00 m"),
    ({"theta_std": None}, "failed", "singular"),
    ({"theta_step_sigmas": 2.0}, "ok", ""),
    ({"theta_step_sigmas": 5.0}, "doubtful", "theta 5.0 sigma from the optimum"),
    ({"theta_step_sigmas": 12.0}, "failed", "theta 12.0 sigma from the optimum"),
])
def test_judge(change: dict, expected: str, words: str) -> None:
    v, reasons = judge(_signals(**change))
    assert v == expected
    assert (reasons == []) == (expected == "ok")
    assert words in "; ".join(reasons)


def test_theta_stays_inside_its_bounds(flight, monkeypatch: pytest.MonkeyPatch) -> None:
    """With an upper bound on the tower between its start and the truth, no step leaves it, the fit
    ends on it, and the verdict says so."""
    upper = THETA_UPPER.copy()
    upper[2] = 87.2  # the start is 86.98 m, the truth 87.6 m
    monkeypatch.setattr(lm, "THETA_UPPER", upper)
    monkeypatch.setattr(verdict, "THETA_UPPER", upper)
    seen: list[float] = []
    original = FitProblem.linearize

    def spy(self, poses, theta, corr, with_jacobian=True):  # type: ignore[no-untyped-def]
        seen.append(float(theta[2]))
        return original(self, poses, theta, corr, with_jacobian)

    monkeypatch.setattr(FitProblem, "linearize", spy)
    res = fit(flight, CLI)
    assert max(seen) <= 87.2
    assert res.turbine.tower_height == pytest.approx(87.2)
    assert res.verdict == "failed"
    assert any("tower_height 87.2 m on or beyond its bound" in r for r in res.reasons)


def test_theta_covariance_is_the_inverse_hessian(flight) -> None:
    """theta's covariance equals the theta block of the inverse of the cost's Hessian,
    taken by finite differences of the gradient at the optimum of a smooth (no robust
    loss, fixed correspondences) problem of 4 keyframes."""
    cfg = FitConfig(points="corr", lines="corr", line_residual="normal", robust="none",
                    warmup=False, pixel_sigma=1.0)
    kf = np.arange(4)
    res = fit(flight, cfg, keyframes=kf)
    prob = FitProblem(flight, cfg, kf)
    poses = res.world_T_cam
    theta = res.turbine.to_vector()
    corr = initial_correspondences(prob, poses, theta)
    # converge on these correspondences
    from turbinefit.solver.lm import levenberg_marquardt
    out = levenberg_marquardt(prob, poses, theta, corr, prob.linearize(poses, theta, corr),
                              max_iterations=50)
    poses, theta = out.poses, out.theta
    lin = prob.linearize(poses, theta, corr)
    cov = theta_covariance(lin)
    assert cov is not None

    def grad(x: np.ndarray) -> np.ndarray:
        dp = np.zeros((4, 6))
        dp[1:] = x[:18].reshape(3, 6)
        g = prob.linearize(poses.retract(dp), theta + x[18:], corr)
        assert g.g_p is not None and g.g_t is not None
        return np.concatenate([g.g_p[1:].ravel(), g.g_t])

    n = 18 + 7
    H = np.empty((n, n))
    eps = np.full(n, 1e-6)
    eps[18:] = [1e-4, 1e-4, 1e-4, 1e-6, 1e-4, 1e-6, 1e-4]
    for i in range(n):
        e = np.zeros(n)
        e[i] = eps[i]
        H[:, i] = (grad(e) - grad(-e)) / (2 * eps[i])
    H = 0.5 * (H + H.T)
    fd = np.linalg.inv(H)[18:, 18:]
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(fd)), rtol=0.05)
    assert math.isfinite(float(np.sum(cov)))
    # at the optimum no step is left; 2 sigma along theta's first principal direction
    # (poses following as the Hessian says) leaves one of 2 sigma
    _, step = theta_uncertainty(lin)
    assert step is not None and step < 0.05
    w, v = np.linalg.eigh(cov)
    dt = 2.0 * math.sqrt(w[-1]) * v[:, -1]
    x = np.linalg.solve(H, np.concatenate([np.zeros(18), np.linalg.solve(fd, dt)]))
    assert np.allclose(x[18:], dt, rtol=1e-3, atol=1e-9)
    moved = prob.linearize(poses.retract(np.concatenate([np.zeros((1, 6)),
                                                           x[:18].reshape(3, 6)])),
                           theta + dt, corr)
    _, step = theta_uncertainty(moved)
    assert step == pytest.approx(2.0, rel=0.1)
