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
def _disc_offsets(radius: int) -> NDArray[np.int64]:
    r = np.arange(-radius, radius + 1)
    dv, du = np.meshgrid(r, r, indexing="ij")
    keep = du * du + dv * dv <= radius * radius
    return np.stack([du[keep], dv[keep]], axis=-1).astype(np.int64)  # (K, 2) (du, dv)


def _parabola_offset(vm: FloatArray, v0: FloatArray, vp: FloatArray) -> FloatArray:
    """Sub-sample offset of a parabola's vertex through (-1, vm), (0, v0), (1, vp)."""
    den = vm - 2.0 * v0 + vp
    off = np.where(den < -1e-12, 0.5 * (vm - vp) / np.where(den < -1e-12, den, -1.0), 0.0)
    return np.clip(off, -0.5, 0.5)


def find_point_correspondences(
    heatmaps: HeatmapStack,
    keyframes: NDArray[np.int_],
    channels: NDArray[np.int_],
    uv: FloatArray,
    usable: NDArray[np.bool_],
    radius: float,
    threshold: float,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Circular-window search. Returns targets (N, M, 2) [px] and found (N, M)."""
    H, W = heatmaps.height, heatmaps.width
    off = _disc_offsets(max(1, round(radius)))
    centre = np.rint(uv).astype(np.int64)
    cu = centre[..., 0, None] + off[:, 0]  # (N, M, K)
    cv = centre[..., 1, None] + off[:, 1]
    in_img = (cu >= 0) & (cu < W) & (cv >= 0) & (cv < H) & usable[..., None]
    cuc = np.clip(cu, 0, W - 1)
    cvc = np.clip(cv, 0, H - 1)
    base = (channels.astype(np.int64) * (H * W))[None, :, None]
    vals = heatmaps.gather(keyframes, base + cvc * W + cuc)
    vals = np.where(in_img, vals, -1.0)
    best = np.argmax(vals, axis=-1)
    peak = np.take_along_axis(vals, best[..., None], axis=-1)[..., 0]
    found = usable & (peak >= threshold)
    bu = np.take_along_axis(cuc, best[..., None], axis=-1)[..., 0]
    bv = np.take_along_axis(cvc, best[..., None], axis=-1)[..., 0]
    # sub-pixel refinement from the 4-neighbourhood
    nb = np.stack([
        np.clip(bu - 1, 0, W - 1) + bv * W, np.clip(bu + 1, 0, W - 1) + bv * W,
        bu + np.clip(bv - 1, 0, H - 1) * W, bu + np.clip(bv + 1, 0, H - 1) * W], -1)
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
    vals = heatmaps.gather(keyframes, base + np.clip(pv, 0, H - 1) * W + np.clip(pu, 0, W - 1))
    vals = np.where(in_img, vals, -1.0)
    best = np.argmax(vals, axis=-1)
    peak = np.take_along_axis(vals, best[..., None], axis=-1)[..., 0]
    found = usable & (peak >= threshold)
    S = steps.size
    vm = np.take_along_axis(vals, np.clip(best - 1, 0, S - 1)[..., None], axis=-1)[..., 0]
    vp = np.take_along_axis(vals, np.clip(best + 1, 0, S - 1)[..., None], axis=-1)[..., 0]
    vm = np.where(best > 0, vm, peak)
    vp = np.where(best < S - 1, vp, peak)
    s = steps[best] + _parabola_offset(np.maximum(vm, 0.0), peak, np.maximum(vp, 0.0))
    target = uv + s[..., None] * normal
    return target, found
