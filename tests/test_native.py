"""The compiled kernels against their numpy twins: same normal equations, costs,
correspondences, projections and linear solves, on flights with faults and distortion."""

import numpy as np
import pytest
from support import simulated_flight

from turbinefit import _native
from turbinefit.costs.projection import project_points
from turbinefit.heatmaps import HeatmapStack, NonFiniteHeatmapError
from turbinefit.solver.config import FitConfig
from turbinefit.solver.linalg import solve_block_tridiagonal
from turbinefit.solver.problem import FitProblem

pytestmark = pytest.mark.skipif(not _native.available(), reason="compiled kernels not built")


def both(monkeypatch, fn):
    """``fn()`` with numpy, then with the compiled kernels."""
    monkeypatch.setenv("TURBINEFIT_NATIVE", "0")
    assert not _native.available()
    a = fn()
    monkeypatch.setenv("TURBINEFIT_NATIVE", "1")
    assert _native.available()
    return a, fn()


@pytest.fixture(scope="module", params=["hard", "distorted", "hard, float16 maps"])
def flight(request):
    """Flights with faults and distortion; the last with its heat-maps stored as float16,
    which the kernels read as such and numpy converts."""
    name, _, half = request.param.partition(", ")
    f = simulated_flight(12, name, seed=3, width=320)
    if half:
        maps = np.stack([f.heatmaps[k] for k in range(f.num_keyframes)]).astype(np.float16)
        f = type(f)(**{**f.__dict__, "heatmaps": HeatmapStack(maps)})
        assert f.heatmaps.half and f.heatmaps.pointers() is not None
    return f


@pytest.mark.parametrize("kw", [
    {},
    {"points": "interp", "lines": "corr", "robust": "none"},
    {"lines": "corr", "line_residual": "normal", "robust": "cauchy"},
    {"line_sampling": "uniform", "mode": "pose"},
    {"points": "interp", "lines": "interp", "border_margin": 0.0},
])
def test_linearization_matches_numpy(monkeypatch, flight, kw):
    prob = FitProblem(flight, FitConfig(**kw))
    poses, theta = flight.world_T_cam, flight.turbine.to_vector()
    monkeypatch.setenv("TURBINEFIT_NATIVE", "0")
    corr = prob.find_correspondences(poses, theta)
    a, b = both(monkeypatch, lambda: prob.linearize(poses, theta, corr))
    assert a.in_view == b.in_view and a.num_residuals == b.num_residuals
    assert a.cost == pytest.approx(b.cost, rel=1e-12)
    for k in a.terms:
        assert a.terms[k] == pytest.approx(b.terms[k], rel=1e-12, abs=1e-12)
    for name in ("D", "B", "C", "E", "g_p", "g_t"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None:
            assert y is None
            continue
        np.testing.assert_allclose(y, x, rtol=1e-10, atol=1e-10 * np.abs(x).max())
    c, d = both(monkeypatch, lambda: prob.linearize(poses, theta, corr, with_jacobian=False))
    assert c.cost == pytest.approx(d.cost, rel=1e-12) and d.D is None


@pytest.mark.parametrize("pixel_scale", [None, 3.0])
def test_correspondences_match_numpy(monkeypatch, flight, pixel_scale):
    """Also with searches of wider range and sample spacing (the pixel settings of maps
    three times wider than the reference)."""
    prob = FitProblem(flight, FitConfig(lines="corr", pixel_scale=pixel_scale))
    poses, theta = flight.world_T_cam, flight.turbine.to_vector()
    a, b = both(monkeypatch, lambda: prob.find_correspondences(poses, theta))
    for kind in ("point", "line"):
        fa, fb = getattr(a, f"{kind}_found"), getattr(b, f"{kind}_found")
        np.testing.assert_array_equal(fa, fb)
        assert fa.sum() > 0
        np.testing.assert_allclose(getattr(b, f"{kind}_target")[fb],
                                   getattr(a, f"{kind}_target")[fa], atol=1e-9)
    np.testing.assert_allclose(b.line_fractions, a.line_fractions)


def test_projection_matches_numpy(monkeypatch, flight):
    rng = np.random.default_rng(0)
    up = np.array([0.0, 0.0, 60.0])
    for pts in (rng.normal(scale=60, size=(40, 3)) + up,
                rng.normal(scale=60, size=(flight.num_keyframes, 40, 3)) + up):
        a, b = both(monkeypatch, lambda p=pts: project_points(
            flight.camera, flight.world_T_cam, p, None, with_jacobian=False))
        np.testing.assert_array_equal(a.front, b.front)
        np.testing.assert_array_equal(a.inside, b.inside)
        np.testing.assert_allclose(b.uv[a.front], a.uv[a.front], rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("n", [1, 2, 5, 40])
def test_block_tridiagonal_solve_matches_numpy(monkeypatch, n):
    rng = np.random.default_rng(n)
    D = rng.normal(size=(n, 6, 6))
    D = D @ np.swapaxes(D, 1, 2) + 6 * np.eye(6)
    B = 0.5 * rng.normal(size=(max(n - 1, 0), 6, 6))
    b = rng.normal(size=(n, 6, 8))
    x0, x1 = both(monkeypatch, lambda: solve_block_tridiagonal(D, B, b))
    np.testing.assert_allclose(x1, x0, rtol=1e-10, atol=1e-12)


def test_not_positive_definite_raises(monkeypatch):
    monkeypatch.setenv("TURBINEFIT_NATIVE", "1")
    D = np.tile(np.eye(6), (3, 1, 1))
    D[1, 2, 2] = -1.0
    with pytest.raises(np.linalg.LinAlgError):
        solve_block_tridiagonal(D, np.zeros((2, 6, 6)), np.ones((3, 6, 1)))


def test_non_finite_heatmap_is_reported_with_its_keyframe(monkeypatch, flight):
    maps = np.stack([flight.heatmaps[k] for k in range(flight.num_keyframes)]).copy()
    maps[4] = np.nan
    bad = type(flight)(**{**flight.__dict__, "heatmaps": HeatmapStack(maps)})
    prob = FitProblem(bad, FitConfig(lines="corr"))
    poses, theta = bad.world_T_cam, bad.turbine.to_vector()
    for native in ("0", "1"):
        monkeypatch.setenv("TURBINEFIT_NATIVE", native)
        with pytest.raises(NonFiniteHeatmapError) as info:
            prob.find_correspondences(poses, theta)
        assert info.value.keyframe == 4
        prob2 = FitProblem(bad, FitConfig(points="interp", lines="interp",
                                         line_sampling="uniform"))
        with pytest.raises(NonFiniteHeatmapError) as info:
            prob2.linearize(poses, theta, prob2.find_correspondences(poses, theta))
        assert info.value.keyframe == 4


@pytest.mark.parametrize("copy", ["pickle", "deepcopy"])
def test_copied_stack_points_at_its_own_arrays(flight, copy):
    """A pickled or deep-copied stack (a flight sent to a worker process) hands the
    kernels the addresses of its own arrays, not those of the original's (which would
    read freed memory in another process)."""
    import copy as copy_module
    import pickle

    stack = flight.heatmaps
    dup = pickle.loads(pickle.dumps(stack)) if copy == "pickle" else copy_module.deepcopy(stack)
    assert dup.pointers() is not None
    assert set(dup.pointers()).isdisjoint(stack.pointers())
    assert list(dup.pointers()) == [dup[k].ctypes.data for k in range(len(dup))]
    for k in range(len(dup)):
        np.testing.assert_array_equal(dup[k], stack[k])



def test_value_check_of_float16_maps():
    """tf_first_out_of_range reads float16 storage: every bit pattern from +0 to 1.0 is in
    [0, 1], the next one (1 + 2^-10) and a NaN, an infinity or a negative value are not."""
    patterns = np.arange(0x3C01, dtype=np.uint16)  # +0 ... 1.0, subnormals included
    maps = np.stack([patterns, patterns]).view(np.float16)
    ptr = lambda a: np.array([row.ctypes.data for row in a], dtype=np.uint64)  # noqa: E731
    assert _native.first_out_of_range(ptr(maps), True, maps.shape[1], 0.0, 1.0) == 2
    for bad in (np.float16(1.0009765625), np.nan, np.inf, np.float16(-6e-8)):
        m = maps.copy()
        m[1, 1234] = bad
        assert _native.first_out_of_range(ptr(m), True, m.shape[1], 0.0, 1.0) == 1
