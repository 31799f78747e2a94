"""Bicubic (Catmull-Rom, i.e. cubic Hermite with central-difference tangents) interpolation
of heat-map channels, with its gradient.

Written by hand because the cost needs, in one vectorised call over all keyframes, the
value *and* the analytic gradient of a C1 interpolant at arbitrary sub-pixel positions of
per-keyframe images (possibly memory-mapped); ``scipy.ndimage.map_coordinates`` gives
B-spline values only, for one image at a time. This is the interpolant Ceres'
``BiCubicInterpolator`` (the paper's toolchain) uses.

Pixel ``[i, j]`` sits at ``u = j, v = i``; outside the image the border pixels are
repeated (callers fade weights to zero there anyway).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from turbinefit.heatmaps import HeatmapStack

FloatArray = NDArray[np.float64]


def _weights(t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Catmull-Rom weights (..., 4) for taps -1, 0, 1, 2 at fraction t, d/dt and d2/dt2."""
    t2 = t * t
    t3 = t2 * t
    w = np.stack(
        [0.5 * (-t3 + 2 * t2 - t), 0.5 * (3 * t3 - 5 * t2 + 2),
         0.5 * (-3 * t3 + 4 * t2 + t), 0.5 * (t3 - t2)], axis=-1)
    dw = np.stack(
        [0.5 * (-3 * t2 + 4 * t - 1), 0.5 * (9 * t2 - 10 * t),
         0.5 * (-9 * t2 + 8 * t + 1), 0.5 * (3 * t2 - 2 * t)], axis=-1)
    d2w = np.stack([-3 * t + 2, 9 * t - 5, -9 * t + 4, 3 * t - 1], axis=-1)
    return w, dw, d2w


_TAPS = np.arange(-1, 3)


def interpolate(
    heatmaps: HeatmapStack,
    keyframes: NDArray[np.int_],
    channels: NDArray[np.int_],
    uv: FloatArray,
    with_gradient: bool = True,
    with_hessian: bool = False,
) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
    """Interpolate channel ``channels[m]`` of keyframe ``keyframes[n]`` at ``uv[n, m]``.

    Args:
        heatmaps: the flight's heat-maps.
        keyframes: (N,) keyframe indices into ``heatmaps``.
        channels: (M,) channel of each point.
        uv: (N, M, 2) pixel positions (finite).

    Returns:
        values: (N, M); gradient: (N, M, 2) d value / d (u, v), or None; Hessian
        (N, M, 3) = (d2/du2, d2/du dv, d2/dv2), or None (only with the gradient). The
        interpolant is C1: the Hessian is exact inside a pixel cell, discontinuous across.
    """
    H, W = heatmaps.height, heatmaps.width
    u = np.minimum(np.maximum(uv[..., 0], -1.0), float(W))
    v = np.minimum(np.maximum(uv[..., 1], -1.0), float(H))
    u0 = np.floor(u)
    v0 = np.floor(v)
    wu, dwu, d2wu = _weights(u - u0)
    wv, dwv, d2wv = _weights(v - v0)
    cols = u0.astype(np.int64)[..., None] + _TAPS  # (N, M, 4)
    np.maximum(cols, 0, out=cols)
    np.minimum(cols, W - 1, out=cols)
    rows = v0.astype(np.int64)[..., None] + _TAPS
    np.maximum(rows, 0, out=rows)
    np.minimum(rows, H - 1, out=rows)
    rows *= W
    rows += (channels.astype(np.int64) * (H * W))[None, :, None]
    flat = rows[..., :, None] + cols[..., None, :]  # (N, M, 4, 4)
    P = heatmaps.gather(keyframes, flat)
    Pu = np.einsum("nmij,nmj->nmi", P, wu)  # interpolate along u for each of 4 rows
    val = np.einsum("nmi,nmi->nm", Pu, wv)
    if not with_gradient:
        return val, None, None
    Pdu = np.einsum("nmij,nmj->nmi", P, dwu)  # d/du along each of the 4 rows
    grad = np.empty((*val.shape, 2))
    grad[..., 0] = np.einsum("nmi,nmi->nm", Pdu, wv)
    grad[..., 1] = np.einsum("nmi,nmi->nm", Pu, dwv)
    if not with_hessian:
        return val, grad, None
    hess = np.empty((*val.shape, 3))
    hess[..., 0] = np.einsum("nmij,nmj,nmi->nm", P, d2wu, wv)
    hess[..., 1] = np.einsum("nmi,nmi->nm", Pdu, dwv)
    hess[..., 2] = np.einsum("nmi,nmi->nm", Pu, d2wv)
    return val, grad, hess
