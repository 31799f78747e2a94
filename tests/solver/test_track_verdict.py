"""The tracker's verdict and theta's standard deviations follow the batch fit's rules
(turbinefit.solver.tracker.Tracker.assess, turbinefit.solver.verdict): the same verdict
on a normal flight, standard deviations that cover the errors on short flights, and an
estimate the tracker has not converged is not called ``ok``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import simulated_flight

from turbinefit.flight import Flight
from turbinefit.sim.noise import DEFAULT_TURBINE_SIGMA
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import fit
from turbinefit.solver.tracker import TrackAssessment, Tracker, TrackerConfig
from turbinefit.solver.verdict import ImageEvidence
from turbinefit.turbine.model import param_errors

#: the command-line defaults for heat-map files
CLI = FitConfig(lines="corr", line_residual="normal", robust="cauchy")
#: chi-square(7) 99.9 % quantile
CHI2_7_999 = 24.32


def track(flight: Flight) -> tuple[Tracker, TrackAssessment]:
    """Replay ``flight`` through the tracker (the command line's defaults) and judge it."""
    tr = Tracker(flight.camera, flight.turbine, TrackerConfig(fit=CLI))
    image = []
    for k in range(flight.num_keyframes):
        tr.update(float(flight.timestamps[k]), flight.world_T_cam[k], flight.heatmaps[k])
        image.append(tr.arrival_evidence())
    return tr, tr.assess(ImageEvidence.concat(image), flight.world_T_cam, flight.world_T_cam)


def nees(tr: Tracker, a: TrackAssessment, flight: Flight) -> float:
    assert flight.gt_turbine is not None and a.theta_covariance is not None
    e = param_errors(tr.turbine, flight.gt_turbine)
    return float(e @ np.linalg.solve(a.theta_covariance, e))


def test_normal_flight_ok_for_both_with_the_same_standard_deviations() -> None:
    flight = simulated_flight(30, seed=4, width=320)
    res = fit(flight, CLI)
    _, a = track(flight)
    assert res.verdict == "ok" and a.verdict == "ok", (res.reasons, a.reasons)
    assert res.theta_std is not None and a.theta_std is not None
    assert a.signals.theta_step_sigmas is not None and a.signals.theta_step_sigmas < 3.0
    np.testing.assert_allclose(a.theta_std, res.theta_std, rtol=0.5)


def short_flight(n: int, seed: int, turbine_scale: float = 1.0) -> Flight:
    """``n`` keyframes whose GPS/IMU steps drift as the pairwise term assumes (0.1 m and
    0.1 deg per step and axis; the simulator's default spreads 2 m and 2 deg over the
    flight, 1.2 deg per step and axis for two keyframes where the term allows 0.1 deg),
    the initial turbine ``turbine_scale`` times as far off as the simulator's default."""
    total = 0.1 * math.sqrt(3.0 * max(n - 1, 1))
    return simulated_flight(n, seed=seed, width=320, drift_pos_m=total, drift_rot_deg=total,
                            turbine_sigma=tuple(s * turbine_scale
                                                for s in DEFAULT_TURBINE_SIGMA))


@pytest.mark.parametrize("n", [1, 5])
def test_standard_deviations_cover_the_errors_of_short_flights(n: int) -> None:
    """NEES of theta (e^T Sigma^-1 e, 7 on average if Sigma is honest) over seeds 0-3, the
    verdict's covariance: mean under 14, none beyond the chi-square(7) 99.9 % quantile
    (measured: means 0.35 for one keyframe, 1.4 for five)."""
    values = []
    for seed in range(4):
        flight = short_flight(n, seed)
        tr, a = track(flight)
        if a.theta_covariance is None:  # a view that leaves theta unfixed: failed
            assert a.verdict == "failed"
            continue
        values.append(nees(tr, a, flight))
    assert len(values) >= 3
    assert np.mean(values) < 14.0 and max(values) < CHI2_7_999, values


def test_an_estimate_short_of_its_optimum_is_not_ok() -> None:
    """One keyframe, the initial turbine five times as far off as the simulator's default:
    the tracker's few iterations leave theta several of its standard deviations from the
    optimum on some seeds (errors of 5-8 sigma). Whatever its errors, a track called
    ``ok`` has them covered; one left short of its optimum says so."""
    short = 0
    for seed in range(6):
        flight = short_flight(1, seed, turbine_scale=5.0)
        tr, a = track(flight)
        step = a.signals.theta_step_sigmas
        if a.verdict == "ok":
            assert nees(tr, a, flight) < CHI2_7_999
        if step is not None and step > 3.0:
            short += 1
            assert a.verdict != "ok"
            assert any("sigma from the optimum" in r for r in a.reasons), a.reasons
    assert short >= 1
