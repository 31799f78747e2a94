"""Box and mask figures of heat-maps on synthetic maps with known answers."""

from __future__ import annotations

import math

import numpy as np

from turbinefit.eval.regions import (
    RegionStats,
    bottom_rows,
    box_region,
    grow_box,
    line_mass_inside,
    mask_region,
    polygon_region,
    skeleton,
    skeleton_covered,
)


def _maps(region: np.ndarray, point: tuple[int, int] | None = None) -> np.ndarray:
    """Maps (7, h, w): the blade line channel 0.9 on ``region``, a hub peak at ``point``."""
    m = np.zeros((7, *region.shape), dtype=np.float32)
    m[6][region] = 0.9
    if point is not None:
        m[2, point[1], point[0]] = 0.8
    return m


def test_box_region_takes_map_pixels_whose_centres_are_inside() -> None:
    # a 100x50 photo on 10x5 maps: map pixel j covers photo u in [10 j, 10 j + 10)
    r = box_region([(20.0, 10.0, 50.0, 30.0)], (100, 50), (10, 5))
    assert r.shape == (5, 10)
    assert np.array_equal(np.flatnonzero(r.any(axis=0)), [2, 3, 4])  # centres 25, 35, 45
    assert np.array_equal(np.flatnonzero(r.any(axis=1)), [1, 2])       # centres 15, 25
    assert grow_box((20.0, 10.0, 50.0, 30.0), 0.1, 100, 50) == (17.0, 8.0, 53.0, 32.0)
    assert grow_box((0.0, 0.0, 100.0, 50.0), 0.1, 100, 50) == (0.0, 0.0, 100.0, 50.0)


def test_polygon_region_fills_the_pixels_whose_centres_are_inside() -> None:
    # a rectangle outline is the mask of its pixels (pixel edges: x 20-50, y 10-30)
    mask = np.zeros((50, 100), dtype=bool)
    mask[10:30, 20:50] = True
    rect = (20.0, 10.0, 50.0, 10.0, 50.0, 30.0, 20.0, 30.0)
    assert np.array_equal(polygon_region([rect], (100, 50), (100, 50)), mask)
    assert np.array_equal(polygon_region([rect], (100, 50), (10, 5)),
                          mask_region(mask, (10, 5)))
    # a right triangle (0, 0)-(40, 0)-(0, 40) at a quarter scale: the map pixels wholly
    # inside (i + j <= 8 of 10 x 10) are in, those beyond the diagonal out (the diagonal's
    # own pixels are half covered)
    tri = polygon_region([(0.0, 0.0, 40.0, 0.0, 0.0, 40.0)], (40, 40), (10, 10))
    ii, jj = np.mgrid[0:10, 0:10]
    assert tri[ii + jj <= 8].all() and not tri[ii + jj >= 10].any()
    # two outlines: their union; none: nothing
    two = polygon_region([rect, (60.0, 0.0, 70.0, 0.0, 70.0, 10.0, 60.0, 10.0)], (100, 50),
                         (100, 50))
    assert two.sum() == mask.sum() + 100
    assert not polygon_region([], (100, 50), (10, 5)).any()


def test_a_perfect_map_scores_one_and_a_background_map_zero() -> None:
    region = np.zeros((40, 60), dtype=bool)
    region[10:30, 20:26] = True
    stats = RegionStats(threshold=0.3, tip_threshold=0.3)
    perfect = stats.add("perfect", ("blade",), _maps(region, (22, 15)), region, mask=True)
    assert perfect.line_mass_inside == 1.0 and perfect.skeleton_covered == 1.0
    assert perfect.found and (perfect.peaks, perfect.peaks_outside) == (1, 0)
    background = stats.add("background", ("turbine",), _maps(~region, (5, 5)), region,
                           mask=True)
    assert background.line_mass_inside == 0.0 and background.skeleton_covered == 0.0
    assert (background.peaks, background.peaks_outside) == (1, 1)
    # half the mass inside
    half = _maps(region)
    half[6, 0, :] = 0.0
    half[6, 0, :20] = 0.9 * region.sum() / 20
    assert math.isclose(line_mass_inside(half, region), 0.5, rel_tol=1e-6)
    nothing = stats.add("nothing", ("blade",), np.zeros((7, 40, 60), np.float32), region)
    assert math.isnan(nothing.line_mass_inside) and not nothing.found
    s = stats.summary()
    assert s["overall"]["photos"] == 3 and s["blade"]["photos"] == 2
    assert s["blade"]["line_mass_inside"] == 1.0 and s["turbine"]["line_mass_inside"] == 0.0
    assert math.isclose(s["overall"]["found"], 2 / 3)
    assert s["overall"]["peaks_outside_share"] == 0.5
    assert stats.worst(2) == [2, 1]  # nothing found first, then the least mass inside


def test_skeleton_is_one_pixel_wide_along_a_bar() -> None:
    bar = np.zeros((30, 50), dtype=bool)
    bar[10:17, 5:45] = True
    sk = skeleton(bar)
    assert sk.sum() > 25 and (sk & ~bar).sum() == 0
    cols = sk[:, 10:40]
    assert np.all(cols.sum(axis=0) == 1)  # one pixel per column along the bar
    assert np.all(np.flatnonzero(cols.any(axis=1)) == 13)  # on its middle row
    # a line covering only the left half of the skeleton
    m = _maps(np.zeros_like(bar))
    m[6, 13, :25] = 0.9
    assert 0.3 < skeleton_covered(m, bar, 0.3) < 0.7


def test_mask_region_and_bottom_rows() -> None:
    mask = np.zeros((100, 200), dtype=bool)
    mask[:, :100] = True
    r = mask_region(mask, (20, 10))
    assert r[:, :10].all() and not r[:, 10:].any()
    m = np.zeros((7, 10, 20), np.float32)
    m[4, -2:] = 1.0
    assert np.allclose(bottom_rows(m, 2), (1.0, 0.2))
