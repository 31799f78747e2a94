"""Correspondence costs (turbinefit.costs.correspondence): sub-pixel point and line matches,
gradient and Gauss-Newton Hessian."""

import numpy as np
import pytest
from support import FD_EPS

from turbinefit.costs.correspondence import (
    correspondence_terms,
    find_line_correspondences,
    find_point_correspondences,
)
from turbinefit.costs.projection import Projection
from turbinefit.heatmaps import HeatmapStack


def _blob_maps(uv_pt, h=60, w=80, sigma=2.0):
    v, u = np.mgrid[0:h, 0:w].astype(float)
    maps = np.zeros((1, 7, h, w), np.float32)
    maps[0, 2] = np.exp(-((u - uv_pt[0]) ** 2 + (v - uv_pt[1]) ** 2) / (2 * sigma**2))
    return maps


def test_point_correspondence_subpixel():
    true = np.array([40.3, 25.7])
    st = HeatmapStack(_blob_maps(true))
    uv = np.array([[[48.0, 20.0], [5.0, 5.0]]])
    tgt, found = find_point_correspondences(st, np.array([0]), np.array([2, 2]), uv,
                                            np.array([[True, True]]), 15, 0.3)
    assert found.tolist() == [[True, False]]  # the second is too far from the blob
    np.testing.assert_allclose(tgt[0, 0], true, atol=0.15)


def test_line_correspondence_along_normal():
    h, w = 60, 80
    v = np.mgrid[0:h, 0:w][0].astype(float)
    maps = np.zeros((1, 7, h, w), np.float32)
    maps[0, 6] = np.exp(-((v - 30.4) ** 2) / 8.0)  # horizontal line at v = 30.4
    st = HeatmapStack(maps)
    uv = np.array([[[20.0, 38.0], [50.0, 22.0], [50.0, 5.0]]])
    normal = np.array([[[0.0, 1.0], [0.0, 1.0], [1.0, 0.0]]])
    tgt, found = find_line_correspondences(st, np.array([0]), np.array([6, 6, 6]), uv, normal,
                                           np.ones((1, 3), bool), 12, 0.3)
    assert found.tolist() == [[True, True, False]]
    np.testing.assert_allclose(tgt[0, :2, 1], 30.4, atol=0.15)
    np.testing.assert_allclose(tgt[0, :2, 0], [20.0, 50.0])


@pytest.mark.parametrize("k", [2, 4, 7])
def test_searches_at_k_times_the_resolution_find_the_same_picture(k):
    """The same blob and ridge at k times the resolution (k times wider), searched with
    steps of k px over k times the range, are found at k times the position (map pixel
    j is u = (j + 0.5) k - 0.5 at k times the size), to a fraction of the coarse pixel."""
    def fine(x):
        return (np.asarray(x) + 0.5) * k - 0.5

    h, w = 60, 80
    true = np.array([40.3, 25.7])
    v, u = np.mgrid[0:h * k, 0:w * k].astype(float)
    maps = np.zeros((1, 7, h * k, w * k), np.float32)
    maps[0, 2] = np.exp(-((u - fine(true[0])) ** 2 + (v - fine(true[1])) ** 2) / (2 * (2.0 * k) ** 2))
    maps[0, 6] = np.exp(-((v - fine(30.4)) ** 2) / (8.0 * k * k))  # horizontal line
    st = HeatmapStack(maps)
    uv = fine(np.array([[[48.0, 20.0], [5.0, 5.0]]]))
    tgt, found = find_point_correspondences(st, np.array([0]), np.array([2, 2]), uv,
                                            np.array([[True, True]]), 15 * k, 0.3, step=k)
    assert found.tolist() == [[True, False]]
    np.testing.assert_allclose(tgt[0, 0], fine(true), atol=0.15 * k)
    uv = fine(np.array([[[20.0, 38.0], [50.0, 22.0], [50.0, 5.0]]]))
    normal = np.array([[[0.0, 1.0], [0.0, 1.0], [1.0, 0.0]]])
    tgt, found = find_line_correspondences(st, np.array([0]), np.array([6, 6, 6]), uv, normal,
                                           np.ones((1, 3), bool), 12 * k, 0.3, step=k)
    assert found.tolist() == [[True, True, False]]
    np.testing.assert_allclose(tgt[0, :2, 1], fine(30.4), atol=0.15 * k)


@pytest.mark.parametrize("along_normal", [False, True])
def test_correspondence_gradient_and_gauss_newton_hessian(along_normal):
    rng = np.random.default_rng(5)
    uv = rng.uniform(0, 50, (2, 6, 2))
    front = np.ones((2, 6), dtype=bool)
    front[1, 0] = False
    found = rng.uniform(size=(2, 6)) > 0.3
    target = uv + rng.normal(scale=2.0, size=uv.shape)
    ang = rng.uniform(0, 2 * np.pi, (2, 6))
    normal = np.stack([np.cos(ang), np.sin(ang)], -1) if along_normal else None

    def terms(x, derivatives=False):
        return correspondence_terms(Projection(x, front, front, None), target, found, normal,
                                    2.0, 1.5, derivatives)

    ct = terms(uv, True)
    assert ct.g is not None and ct.H is not None
    assert np.array_equal(ct.used, found & front) and np.all(ct.s[~ct.used] == 0.0)
    for a in range(2):
        d = np.zeros_like(uv)
        d[..., a] = FD_EPS
        num = (terms(uv + d).s - terms(uv - d).s) / (4 * FD_EPS)  # of 1/2 s
        np.testing.assert_allclose(ct.g[..., a], num, atol=1e-6)
        # a quadratic: the Gauss-Newton Hessian is the exact one
        num_h = (terms(uv + d, True).g - terms(uv - d, True).g) / (2 * FD_EPS)
        np.testing.assert_allclose(ct.H[..., :, a], num_h, atol=1e-6)
