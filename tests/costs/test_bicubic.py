"""Bicubic interpolation of heat-maps (turbinefit.costs.bicubic): exact at pixels and on
ramps, gradients, both storages, non-finite maps."""

import numpy as np
import pytest
from support import smooth_heatmaps

from turbinefit.costs.bicubic import interpolate
from turbinefit.heatmaps import HeatmapStack


def test_bicubic_reproduces_pixels_and_linear_ramps():
    rng = np.random.default_rng(0)
    maps = rng.uniform(0, 1, (2, 7, 12, 16)).astype(np.float32)
    st = HeatmapStack(maps)
    ii, jj = np.meshgrid(np.arange(2, 10), np.arange(2, 14), indexing="ij")
    uv = np.stack([jj.ravel(), ii.ravel()], -1).astype(float)[None].repeat(2, 0)
    ch = np.full(uv.shape[1], 5)
    val, _, _ = interpolate(st, np.array([0, 1]), ch, uv)
    np.testing.assert_allclose(val, maps[:, 5, ii.ravel(), jj.ravel()], atol=1e-6)
    # a linear ramp is reproduced exactly between pixels, with the exact gradient
    v, u = np.mgrid[0:12, 0:16]
    ramp = np.zeros((1, 7, 12, 16), np.float32)
    ramp[0, 2] = (0.01 * u + 0.02 * v).astype(np.float32)
    uvq = rng.uniform([2, 2], [13, 9], (1, 30, 2))
    val, grad, _ = interpolate(HeatmapStack(ramp), np.array([0]), np.full(30, 2), uvq)
    np.testing.assert_allclose(val, 0.01 * uvq[..., 0] + 0.02 * uvq[..., 1], atol=1e-6)
    np.testing.assert_allclose(grad, np.broadcast_to([0.01, 0.02], grad.shape), atol=1e-6)


def test_bicubic_gradient_matches_finite_differences():
    maps = smooth_heatmaps(1, 40, 50, seed=3)
    st = HeatmapStack(maps)
    rng = np.random.default_rng(1)
    uv = rng.uniform([3, 3], [46, 36], (1, 40, 2))
    ch = np.full(40, 1)
    _, g, _ = interpolate(st, np.array([0]), ch, uv)
    assert g is not None
    for a in range(2):
        d = np.zeros(2)
        d[a] = 1e-5
        num = (interpolate(st, np.array([0]), ch, uv + d)[0]
               - interpolate(st, np.array([0]), ch, uv - d)[0]) / 2e-5
        np.testing.assert_allclose(g[..., a], num, atol=2e-5)


def test_list_and_stacked_storage_agree():
    maps = smooth_heatmaps(3, 30, 40, seed=5)
    rng = np.random.default_rng(2)
    uv = rng.uniform([0, 0], [39, 29], (2, 9, 2))
    ch = np.arange(9) % 7
    kf = np.array([2, 0])
    a = interpolate(HeatmapStack(maps), kf, ch, uv)
    b = interpolate(HeatmapStack(list(maps)), kf, ch, uv)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_non_finite_heatmap_is_reported():
    maps = np.full((2, 7, 10, 10), 0.5, np.float32)
    maps[1, 3, 5, 5] = np.nan
    st = HeatmapStack(list(maps))
    with pytest.raises(ValueError, match="keyframe 1"):
        interpolate(st, np.array([0, 1]), np.array([3]), np.array([[[5.0, 5.0]], [[5.2, 5.1]]]))
