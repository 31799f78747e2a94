"""Resizing heat-maps (turbinefit.heatmaps.resize)."""

from __future__ import annotations

import numpy as np

from turbinefit.heatmaps.resize import resize_maps
from turbinefit.io.images import resize_image


def test_resize_keeps_pixel_centres() -> None:
    maps = np.zeros((1, 20, 20), np.float32)
    maps[0, 10, 6] = 1.0
    big = resize_maps(maps, 40, 40)
    i, j = np.unravel_index(np.argmax(big[0]), big[0].shape)
    # pixel centre 6 maps to (6 + 0.5) * 2 - 0.5 = 12.5: the two pixels 12 and 13 share it
    assert j in (12, 13) and i in (20, 21)
    assert resize_image(np.zeros((30, 40, 3), np.uint8), 20, 15).shape == (15, 20, 3)
