"""Peaks of heat-maps: a channel's maximum and its local maxima, sub-pixel.

A peak at pixel ``(i, j)`` (row, column) is refined by a log-parabola through its
4-neighbourhood along each axis (exact for a Gaussian blob), clipped to half a pixel and
skipped where the neighbours do not bracket it. Positions are ``(u, v)`` = (column, row)
in the map's pixels. The detector (coarse to fine), the detection metrics, the region
metrics and ``init``'s triangulation share them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

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
    """(n, 2) pixel positions (u, v) of ``size`` x ``size`` local maxima above ``threshold``
    (pixels outside the map count as 0), in row-major order. Maxima within one window of
    each other are equal (a flat top): of those only the first in row-major order is kept.

    Only the pixels above ``threshold`` are compared with their neighbours, so the cost
    follows the responses, not the map's size (``init`` reads every keyframe's maps)."""
    h, w = channel.shape
    ii, jj = np.nonzero(channel > threshold)
    r = size // 2
    if ii.size and r > 0:
        v = channel[ii, jj]
        keep = np.ones(ii.size, dtype=bool)
        offsets = [(di, dj) for di in range(-r, r + 1) for dj in range(-r, r + 1) if di or dj]
        for di, dj in offsets:
            ni, nj = ii + di, jj + dj
            inside = (ni >= 0) & (ni < h) & (nj >= 0) & (nj < w)
            nb = channel[np.where(inside, ni, 0), np.where(inside, nj, 0)]
            keep &= ~inside | (v >= nb)
        if keep.sum() > 1:  # equal maxima within one window: the first in row-major order
            cand = np.zeros((h, w), dtype=bool)
            cand[ii[keep], jj[keep]] = True
            first = keep.copy()
            for di, dj in offsets:
                if di < 0 or (di == 0 and dj < 0):
                    ni, nj = ii + di, jj + dj
                    inside = (ni >= 0) & (nj >= 0) & (nj < w)
                    first &= ~(inside & cand[np.where(inside, ni, 0), np.where(inside, nj, 0)])
            keep = first
        ii, jj = ii[keep], jj[keep]
    return np.stack([jj, ii], axis=-1).astype(np.float64)


def peaks(channel: NDArray[np.floating], threshold: float, nms_px: int = 7
          ) -> NDArray[np.float64]:
    """(n, 2) sub-pixel positions (u, v) of a channel's local maxima above ``threshold``
    (``nms_px`` x ``nms_px`` non-maximum suppression)."""
    det = local_maxima(channel, threshold, nms_px)
    return np.array([refine(channel, int(v), int(u))[:2] for u, v in det]).reshape(-1, 2)


def strongest_peaks(channel: NDArray[np.floating], threshold: float, max_peaks: int,
                    size: int = 3) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(uv (n, 2), value (n,))`` of the ``max_peaks`` strongest ``size`` x ``size``
    local maxima above ``threshold``, strongest first, sub-pixel (:func:`refine`). Maxima
    on the map's border are left out: a blob cut by the frame peaks there wherever its
    centre is (as the searched correspondences reject a peak the border leaves unbracketed)."""
    det = local_maxima(channel, threshold, size)
    h, w = channel.shape
    det = det[(det[:, 0] > 0) & (det[:, 0] < w - 1) & (det[:, 1] > 0) & (det[:, 1] < h - 1)]
    if not len(det):
        return np.zeros((0, 2)), np.zeros(0)
    values = channel[det[:, 1].astype(np.intp), det[:, 0].astype(np.intp)]
    order = np.argsort(-values.astype(np.float64), kind="stable")[:max_peaks]
    ref = np.array([refine(channel, int(det[n, 1]), int(det[n, 0])) for n in order])
    return ref[:, :2].astype(np.float64), ref[:, 2].astype(np.float64)
