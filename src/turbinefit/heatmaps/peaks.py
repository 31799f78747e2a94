"""Peaks of heat-maps: a channel's maximum and its local maxima, sub-pixel.

A peak at pixel ``(i, j)`` (row, column) is refined by a log-parabola through its
4-neighbourhood along each axis (exact for a Gaussian blob), clipped to half a pixel and
skipped where the neighbours do not bracket it. Positions are ``(u, v)`` = (column, row)
in the map's pixels. The detector (coarse to fine), the detection metrics and the region
metrics share them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

_EPS = 1e-6


def peak(channel: NDArray[np.floating]) -> tuple[float, float, float]:
    """(u, v, value) of a channel's maximum, sub-pixel (log-parabola) where bracketed."""
    i, j = np.unravel_index(int(np.argmax(channel)), channel.shape)
    return refine(channel, int(i), int(j))


def refine(channel: NDArray[np.floating], i: int, j: int) -> tuple[float, float, float]:
    """(u, v, value) of the local maximum at row ``i``, column ``j``, sub-pixel
    (log-parabola through its 4-neighbourhood) where bracketed."""
    val = float(channel[i, j])
    u, v = float(j), float(i)
    h, w = channel.shape
    if 0 < j < w - 1:
        a, b, c = (np.log(max(float(x), _EPS)) for x in channel[i, j - 1:j + 2])
        den = a - 2 * b + c
        if den < 0:
            u += float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
    if 0 < i < h - 1:
        a, b, c = (np.log(max(float(x), _EPS)) for x in channel[i - 1:i + 2, j])
        den = a - 2 * b + c
        if den < 0:
            v += float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
    return u, v, val


def local_maxima(channel: NDArray[np.floating], threshold: float, size: int = 3
                 ) -> NDArray[np.float64]:
    """(n, 2) pixel positions (u, v) of ``size`` x ``size`` local maxima above ``threshold``."""
    mx = ndimage.maximum_filter(channel, size=size, mode="constant", cval=0.0)
    ii, jj = np.nonzero((channel >= mx) & (channel > threshold))
    return np.stack([jj, ii], axis=-1).astype(np.float64)


def peaks(channel: NDArray[np.floating], threshold: float, nms_px: int = 7
          ) -> NDArray[np.float64]:
    """(n, 2) sub-pixel positions (u, v) of a channel's local maxima above ``threshold``
    (``nms_px`` x ``nms_px`` non-maximum suppression)."""
    det = local_maxima(channel, threshold, nms_px)
    return np.array([refine(channel, int(v), int(u))[:2] for u, v in det]).reshape(-1, 2)
