"""The edge term's search (turbinefit.costs.edges): the midpoint of a bar's two silhouette
edges in a photo four times finer than the maps, to a small fraction of a map pixel, over
a textured background; nothing where there is no bar or it is far wider than expected."""

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from turbinefit.costs.edges import PhotoStack, find_edge_correspondences

S = 4  # photo px per map px


def _photo(centre_u: float, half_width: float, seed: int = 0) -> np.ndarray:
    """A 400 x 300 grey photo: textured ground, a vertical bright bar (anti-aliased)."""
    rng = np.random.default_rng(seed)
    bg = gaussian_filter(rng.uniform(60, 120, (300, 400)), 3.0)
    u = np.arange(400)[None, :]
    cover = np.clip(half_width + 0.5 - np.abs(u - centre_u), 0, 1)
    img = bg * (1 - cover) + 220 * cover
    return np.clip(img + rng.normal(0, 1.5, img.shape), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("centre", [200.0, 201.3, 197.75])
def test_midpoint_of_a_bar(centre: float) -> None:
    photos = PhotoStack(np.stack([_photo(centre, 9.0)]), float(S))
    rows = np.arange(10, 65, 5, dtype=float)  # map rows
    # searched from the net's correspondence, one map px off, along the normal (1, 0)
    guess_map = (centre + 0.5) / S - 0.5 + 1.0
    cen = np.stack([np.full_like(rows, guess_map), rows], axis=-1)[None]
    normal = np.broadcast_to([1.0, 0.0], cen.shape)
    hw = np.full((1, rows.size, 2), 9.0 / S)
    tgt, found, sep = find_edge_correspondences(photos, np.array([0]), cen, normal,
                                                np.ones((1, rows.size), bool), hw, reach=2.0)
    assert found.all()
    want = (centre + 0.5) / S - 0.5
    np.testing.assert_allclose(tgt[0, :, 0], want, atol=0.05)  # map px (0.2 photo px)
    # the apparent width: the two edges 18 photo px apart (where the bar's cover is half)
    np.testing.assert_allclose(sep[0], 2 * 9.0 / S, atol=0.1)
    np.testing.assert_allclose(tgt[0, :, 1], rows, atol=1e-9)


def test_nothing_without_a_bar_of_that_width() -> None:
    plain = np.clip(_photo(-100.0, 1.0) * 0 + 128, 0, 255).astype(np.uint8)
    wide = _photo(200.0, 40.0)
    photos = PhotoStack(np.stack([plain, wide]), float(S))
    cen = np.array([[[50.0, 30.0]], [[50.0, 30.0]]])
    normal = np.array([[[1.0, 0.0]], [[1.0, 0.0]]])
    hw = np.full((2, 1, 2), 9.0 / S)
    _, found, _ = find_edge_correspondences(photos, np.array([0, 1]), cen, normal,
                                            np.ones((2, 1), bool), hw, reach=2.0)
    assert not found.any()
