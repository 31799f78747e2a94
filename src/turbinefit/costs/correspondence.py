"""The paper's correspondence cost E_unary(1): 2-D points found by search in the heat-maps.

* Model points: search a circular window of radius ``radius`` px around the projection in
  the matching point channel; the maximum, if above ``threshold``, is the correspondence,
  refined to sub-pixel precision by a parabola through its 3x3 neighbourhood.
* Line samples: search along the normal of the projected line, ``+-half_length`` px in
  1 px steps, in the matching line channel; the maximum above ``threshold``, refined by a
  parabola along the normal, is the correspondence.

Residual: ``sqrt(lambda) (uv - a') / sigma_px`` for each point with a correspondence (the
paper's squared 2-D distance, whitened by the expected detection noise ``sigma_px``).
Correspondences are held fixed while the solver iterates and re-found as the estimate moves
(an outer loop in :mod:`turbinefit.solver.problem`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from turbinefit.heatmaps import HeatmapStack

FloatArray = NDArray[np.float64]


@lru_cache(maxsize=8)
def _disc_offsets(radius: int, step: int) -> NDArray[np.int64]:
    r = np.arange(-radius, radius + 1, step)
    dv, du = np.meshgrid(r, r, indexing="ij")
    keep = du * du + dv * dv <= radius * radius
    return np.stack([du[keep], dv[keep]], axis=-1).astype(np.int64)  # (K, 2) (du, dv)


_SQUARE5 = np.stack(np.meshgrid(np.arange(-2, 3), np.arange(-2, 3)), -1).reshape(-1, 2)


def _parabola_offset(vm: FloatArray, v0: FloatArray, vp: FloatArray) -> FloatArray:
    """Sub-sample offset of a parabola's vertex through (-1, vm), (0, v0), (1, vp)."""
    den = vm - 2.0 * v0 + vp
    ok = den < -1e-12
    off = np.where(ok, 0.5 * (vm - vp) / np.where(ok, den, -1.0), 0.0)
    return np.minimum(np.maximum(off, -0.5), 0.5)


def _window_max(heatmaps: HeatmapStack, keyframes: NDArray[np.int_], base: NDArray[np.int64],
                centre: NDArray[np.int64], off: NDArray[np.int64], usable: NDArray[np.bool_],
                centre_uv: NDArray[np.int64] | None = None, radius: float = np.inf,
                ) -> tuple[FloatArray, NDArray[np.int64], NDArray[np.int64]]:
    """Max of the heat-map over ``centre + off`` (pixels outside the image, or farther than
    ``radius`` from ``centre_uv``, excluded). Returns peak value, u and v (each (N, M))."""
    H, W = heatmaps.height, heatmaps.width
    cu = centre[..., 0, None] + off[:, 0]  # (N, M, K)
    cv = centre[..., 1, None] + off[:, 1]
    ok = (cu >= 0) & (cu < W) & (cv >= 0) & (cv < H) & usable[..., None]
    if centre_uv is not None:
        du = cu - centre_uv[..., 0, None]
        dv = cv - centre_uv[..., 1, None]
        ok &= du * du + dv * dv <= radius * radius
    np.maximum(cu, 0, out=cu)
    np.minimum(cu, W - 1, out=cu)
    np.maximum(cv, 0, out=cv)
    np.minimum(cv, H - 1, out=cv)
    vals = heatmaps.gather(keyframes, base + cv * W + cu)
    vals[~ok] = -1.0
    best = np.argmax(vals, axis=-1)[..., None]
    peak = np.take_along_axis(vals, best, axis=-1)[..., 0]
    return (peak, np.take_along_axis(cu, best, axis=-1)[..., 0],
            np.take_along_axis(cv, best, axis=-1)[..., 0])


def find_point_correspondences(
    heatmaps: HeatmapStack,
    keyframes: NDArray[np.int_],
    channels: NDArray[np.int_],
    uv: FloatArray,
    usable: NDArray[np.bool_],
    radius: float,
    threshold: float,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Circular-window search. Returns targets (N, M, 2) [px] and found (N, M).

    The window is searched coarse-to-fine: every second pixel of the disc, then the 5x5
    pixels around the best one. For heat-map peaks at least ~1.5 px wide (any blurred CNN
    output) this finds the same maximum as a dense search at a quarter of the cost.
    """
    H, W = heatmaps.height, heatmaps.width
    R = max(1, round(radius))
    centre = np.rint(uv).astype(np.int64)
    base = (channels.astype(np.int64) * (H * W))[None, :, None]
    _, bu, bv = _window_max(heatmaps, keyframes, base, centre, _disc_offsets(R, 2), usable,
                            centre, R)
    coarse = np.stack([bu, bv], axis=-1)
    peak, bu, bv = _window_max(heatmaps, keyframes, base, coarse, _SQUARE5, usable, centre, R)
    found = usable & (peak >= threshold)
    # sub-pixel refinement from the 4-neighbourhood
    nb = np.stack([
        np.maximum(bu - 1, 0) + bv * W, np.minimum(bu + 1, W - 1) + bv * W,
        bu + np.maximum(bv - 1, 0) * W, bu + np.minimum(bv + 1, H - 1) * W], -1)
    nvals = heatmaps.gather(keyframes, base + nb)
    du = _parabola_offset(nvals[..., 0], peak, nvals[..., 1])
    dv = _parabola_offset(nvals[..., 2], peak, nvals[..., 3])
    target = np.stack([bu + du, bv + dv], axis=-1).astype(np.float64)
    return target, found


def find_line_correspondences(
    heatmaps: HeatmapStack,
    keyframes: NDArray[np.int_],
    channels: NDArray[np.int_],
    uv: FloatArray,
    normal: FloatArray,
    usable: NDArray[np.bool_],
    half_length: float,
    threshold: float,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Search along unit normals (N, M, 2). Returns targets (N, M, 2) [px] and found (N, M)."""
    H, W = heatmaps.height, heatmaps.width
    L = max(1, round(half_length))
    steps = np.arange(-L, L + 1, dtype=np.float64)
    pos = uv[..., None, :] + steps[:, None] * normal[..., None, :]  # (N, M, S, 2)
    pu = np.rint(pos[..., 0]).astype(np.int64)
    pv = np.rint(pos[..., 1]).astype(np.int64)
    in_img = (pu >= 0) & (pu < W) & (pv >= 0) & (pv < H) & usable[..., None]
    base = (channels.astype(np.int64) * (H * W))[None, :, None]
    np.maximum(pu, 0, out=pu)
    np.minimum(pu, W - 1, out=pu)
    np.maximum(pv, 0, out=pv)
    np.minimum(pv, H - 1, out=pv)
    vals = heatmaps.gather(keyframes, base + pv * W + pu)
    vals[~in_img] = -1.0
    best = np.argmax(vals, axis=-1)
    peak = np.take_along_axis(vals, best[..., None], axis=-1)[..., 0]
    found = usable & (peak >= threshold)
    S = steps.size
    vm = np.take_along_axis(vals, np.maximum(best - 1, 0)[..., None], axis=-1)[..., 0]
    vp = np.take_along_axis(vals, np.minimum(best + 1, S - 1)[..., None], axis=-1)[..., 0]
    vm = np.where(best > 0, vm, peak)
    vp = np.where(best < S - 1, vp, peak)
    s = steps[best] + _parabola_offset(np.maximum(vm, 0.0), peak, np.maximum(vp, 0.0))
    target = uv + s[..., None] * normal
    return target, found
