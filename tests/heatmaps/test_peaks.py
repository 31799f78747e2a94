"""Local maxima and strongest peaks of heat-map channels (turbinefit.heatmaps.peaks)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from turbinefit.heatmaps.peaks import local_maxima, strongest_peaks


def blob(h: int, w: int, u: float, v: float, sigma: float = 1.5, peak: float = 1.0
         ) -> np.ndarray:
    jj, ii = np.meshgrid(np.arange(w), np.arange(h))
    return peak * np.exp(-((jj - u) ** 2 + (ii - v) ** 2) / (2 * sigma**2))


@pytest.mark.parametrize("size", [3, 7])
def test_local_maxima_are_the_maximum_filters_on_maps_without_ties(size: int) -> None:
    rng = np.random.default_rng(5)
    m = ndimage.gaussian_filter(rng.uniform(size=(60, 80)), 1.5)
    m = (m - m.min()) / (m.max() - m.min())
    mx = ndimage.maximum_filter(m, size=size, mode="constant", cval=0.0)
    ii, jj = np.nonzero((m >= mx) & (m > 0.3))
    want = np.stack([jj, ii], axis=-1)
    got = local_maxima(m, 0.3, size)
    assert len(want) > 3
    np.testing.assert_array_equal(got, want)
    # float16, as heat-map files store them: the same maxima
    np.testing.assert_array_equal(local_maxima(m.astype(np.float16), 0.3, size),
                                  local_maxima(m.astype(np.float16).astype(np.float32), 0.3,
                                               size))


def test_a_flat_top_gives_one_maximum_and_a_tie_beside_a_larger_value_does_not_hide_one(
) -> None:
    m = np.zeros((10, 12))
    m[3, 4] = m[3, 5] = m[4, 4] = 1.0  # a flat top: its first pixel in row-major order
    assert local_maxima(m, 0.1, 3).tolist() == [[4.0, 3.0]]
    assert local_maxima(np.full((20, 30), 0.5), 0.1, 7).tolist() == [[0.0, 0.0]]
    m = np.zeros((5, 8))
    m[2, 1], m[2, 2], m[2, 3] = 0.9, 0.5, 0.5  # (2, 2) is no maximum, so (2, 3) is one
    assert local_maxima(m, 0.1, 3).tolist() == [[1.0, 2.0], [3.0, 2.0]]
    assert local_maxima(np.zeros((8, 8)), 0.1, 3).shape == (0, 2)


def test_strongest_peaks_place_blobs_strongest_first_and_leave_the_border_out() -> None:
    m = (blob(40, 50, 12.3, 20.6, peak=0.6) + blob(40, 50, 33.7, 9.2, peak=0.9)
         + blob(40, 50, 25.0, 39.4, peak=1.0))  # the last one cut by the bottom edge
    uv, val = strongest_peaks(m, 0.3, 5)
    np.testing.assert_allclose(uv, [[33.7, 9.2], [12.3, 20.6]], atol=0.01)
    np.testing.assert_allclose(val, m[[9, 21], [34, 12]])
    uv1, val1 = strongest_peaks(m, 0.3, 1)
    np.testing.assert_array_equal(uv1, uv[:1])
    np.testing.assert_array_equal(val1, val[:1])
    empty_uv, empty_val = strongest_peaks(np.zeros((10, 10)), 0.3, 4)
    assert empty_uv.shape == (0, 2) and empty_val.shape == (0,)
