"""The paper's correspondence cost E_unary(1): 2-D points found by search in the heat-maps.

* Model points: search a circular window of radius ``radius`` px around the projection in
  the matching point channel; the maximum, if above ``threshold`` and not on the image
  border (where it is not bracketed), is the correspondence,
  refined to sub-pixel precision by a parabola through the logarithms of its
  4-neighbourhood (exact for a Gaussian peak).
* Line samples: search along the normal of the projected line, ``+-half_length`` px
  (bilinear samples, coarse-to-fine), in the matching line channel; the maximum above
  ``threshold`` (bracketed by two searched pixels inside the image), refined by a
  log-parabola along the normal, is the correspondence.

Both searches take a ``step`` [px]: the spacing of their samples (coarse 2 steps, fine 1
step, neighbours of the log-parabola 1 step away). 1 on maps of the reference width;
maps ``k`` times wider (``k`` times wider peaks, :attr:`FitConfig.pixel_scale
<turbinefit.solver.config.FitConfig.pixel_scale>`) are searched with ``step = k``: the same
samples over the same part of the view, whatever the resolution.

Residual (:func:`correspondence_terms`): ``sqrt(lambda) (uv - a') / sigma_px`` for each
point with a correspondence (the paper's squared 2-D distance, whitened by the expected
detection noise ``sigma_px``), or, for line samples, optionally its component along the
search normal (the model is then free to slide along its lines). Correspondences are held
fixed while the solver iterates and re-found as the estimate moves (the rounds of
:mod:`turbinefit.solver.rounds`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from turbinefit import _native
from turbinefit.costs.projection import Projection
from turbinefit.heatmaps import HeatmapStack

FloatArray = NDArray[np.float64]


@dataclass
class CorrespondenceTerms:
    """The correspondence cost of N x M points: ``1/2 s`` (N, M) with ``s`` the squared
    whitened residual (0 without a correspondence), ``used`` (N, M) the points with a
    correspondence in front of the camera, and with derivatives the gradient ``g``
    (N, M, 2) of ``1/2 s`` w.r.t. uv and its Gauss-Newton Hessian ``H`` (N, M, 2, 2)."""

    s: FloatArray
    used: NDArray[np.bool_]
    g: FloatArray | None = None
    H: FloatArray | None = None


def correspondence_terms(pr: Projection, target: FloatArray, found: NDArray[np.bool_],
                         normal: FloatArray | None, lam: float, pixel_sigma: float,
                         with_derivatives: bool) -> CorrespondenceTerms:
    """The residual ``sqrt(lam) (uv - target) / pixel_sigma`` of the projections ``pr``
    (N, M) against their ``target`` (N, M, 2) where ``found``; with unit ``normal``
    (N, M, 2), only its component along the normal."""
    use = found & pr.front
    info = lam / pixel_sigma**2
    d = (pr.uv - target) * use[..., None]
    g: FloatArray | None = None
    H: FloatArray | None = None
    if normal is None:  # 2-D distance to the found point (the paper's)
        s = info * np.sum(d * d, axis=-1)
        if with_derivatives:
            g = info * d
            H = np.zeros((*s.shape, 2, 2))
            H[..., 0, 0] = H[..., 1, 1] = info * use
    else:  # distance along the search normal: free to slide along the line
        dn = np.sum(d * normal, axis=-1)
        s = info * dn * dn
        if with_derivatives:
            g = (info * dn)[..., None] * normal
            H = (info * use)[..., None, None] * (normal[..., :, None] * normal[..., None, :])
    return CorrespondenceTerms(s, use, g, H)


@lru_cache(maxsize=16)
def _disc_offsets(radius: int, step: int) -> NDArray[np.int64]:
    r = np.arange(-radius, radius + 1, step)
    dv, du = np.meshgrid(r, r, indexing="ij")
    keep = du * du + dv * dv <= radius * radius
    return np.stack([du[keep], dv[keep]], axis=-1).astype(np.int64)  # (K, 2) (du, dv)


@lru_cache(maxsize=16)
def _square5(step: int) -> NDArray[np.int64]:
    """The 5 x 5 offsets (du, dv) ``step`` px apart (25, 2)."""
    r = step * np.arange(-2, 3)
    return np.ascontiguousarray(np.stack(np.meshgrid(r, r), -1).reshape(-1, 2), dtype=np.int64)


#: Values below this are raised to it before the log in :func:`_peak_offset`.
_LOG_FLOOR = 1e-6


def _peak_offset(vm: FloatArray, v0: FloatArray, vp: FloatArray) -> FloatArray:
    """Sub-sample offset of a peak from three samples at -1, 0, 1: the vertex of the
    parabola through their logarithms (exact for Gaussian profiles, which blurred
    heat-map peaks and ridges are; a parabola through the values themselves is biased by
    up to 0.1-0.2 px on a 1-2 px wide peak). Clipped to [-0.5, 0.5]."""
    lm = np.log(np.maximum(vm, _LOG_FLOOR))
    l0 = np.log(np.maximum(v0, _LOG_FLOOR))
    lp = np.log(np.maximum(vp, _LOG_FLOOR))
    den = lm - 2.0 * l0 + lp
    ok = den < -1e-12
    off = np.where(ok, 0.5 * (lm - lp) / np.where(ok, den, -1.0), 0.0)
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
    step: int = 1,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Circular-window search. Returns targets (N, M, 2) [px] and found (N, M).

    The window is searched coarse-to-fine: every second ``step`` of the disc, then the
    5x5 samples ``step`` px apart around the best one; the sub-pixel peak is the
    log-parabola through the neighbours ``step`` px away. With ``step`` 1 and heat-map
    peaks at least ~1.5 px wide (any blurred CNN output) this finds the same maximum as a
    dense search at a quarter of the cost; peaks ``step`` times wider are searched the
    same way at the same cost.
    """
    H, W = heatmaps.height, heatmaps.width
    R = max(1, round(radius))
    s = max(1, int(step))
    maps = _native.native_maps(heatmaps) if _native.available() else None
    if maps is not None:
        return _native.point_search(maps, W, H, keyframes, channels, uv,
                                    usable, R, _disc_offsets(R, 2 * s), _square5(s), s,
                                    threshold)
    centre = np.rint(uv).astype(np.int64)
    base = (channels.astype(np.int64) * (H * W))[None, :, None]
    _, bu, bv = _window_max(heatmaps, keyframes, base, centre, _disc_offsets(R, 2 * s),
                            usable, centre, R)
    coarse = np.stack([bu, bv], axis=-1)
    peak, bu, bv = _window_max(heatmaps, keyframes, base, coarse, _square5(s), usable,
                               centre, R)
    # a peak on the image border is not bracketed: the true maximum may lie outside
    inner = (bu >= s) & (bu <= W - 1 - s) & (bv >= s) & (bv <= H - 1 - s)
    found = usable & (peak >= threshold) & inner
    # sub-pixel refinement from the neighbours one step away
    nb = np.stack([
        np.clip(bu - s, 0, W - 1) + bv * W, np.clip(bu + s, 0, W - 1) + bv * W,
        bu + np.clip(bv - s, 0, H - 1) * W, bu + np.clip(bv + s, 0, H - 1) * W], -1)
    nvals = heatmaps.gather(keyframes, base + nb)
    du = s * _peak_offset(nvals[..., 0], peak, nvals[..., 1])
    dv = s * _peak_offset(nvals[..., 2], peak, nvals[..., 3])
    target = np.stack([bu + du, bv + dv], axis=-1).astype(np.float64)
    return target, found


def _profile(heatmaps: HeatmapStack, keyframes: NDArray[np.int_], channels: NDArray[np.int_],
             uv: FloatArray, normal: FloatArray, usable: NDArray[np.bool_],
             steps: FloatArray) -> FloatArray:
    """Bilinear heat-map values at ``uv + steps * normal`` (steps (N, M, K)); -1 where the
    position is outside the image or the point not usable."""
    H, W = heatmaps.height, heatmaps.width
    pu = uv[..., 0, None] + steps * normal[..., 0, None]
    pv = uv[..., 1, None] + steps * normal[..., 1, None]
    ok = (pu >= 0) & (pu <= W - 1) & (pv >= 0) & (pv <= H - 1) & usable[..., None]
    u0 = np.clip(np.floor(pu), 0, W - 2).astype(np.int64)
    v0 = np.clip(np.floor(pv), 0, H - 2).astype(np.int64)
    fu = np.clip(pu - u0, 0.0, 1.0)
    fv = np.clip(pv - v0, 0.0, 1.0)
    i00 = (channels.astype(np.int64) * (H * W))[None, :, None] + v0 * W + u0
    t = heatmaps.gather(keyframes, np.stack([i00, i00 + 1, i00 + W, i00 + W + 1], -1))
    vals = ((1 - fv) * ((1 - fu) * t[..., 0] + fu * t[..., 1])
            + fv * ((1 - fu) * t[..., 2] + fu * t[..., 3]))
    return np.where(ok, vals, -1.0)


def find_line_correspondences(
    heatmaps: HeatmapStack,
    keyframes: NDArray[np.int_],
    channels: NDArray[np.int_],
    uv: FloatArray,
    normal: FloatArray,
    usable: NDArray[np.bool_],
    half_length: float,
    threshold: float,
    step: float = 1.0,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Search along unit normals (N, M, 2). Returns targets (N, M, 2) [px] and found (N, M).

    The profile is sampled bilinearly at exact positions on the normal (rounding them to
    pixels would sample it unevenly and bias the peak), coarse-to-fine: every 2 steps of
    ``step`` px over ``+-L`` (``half_length`` in whole steps), then 1 step either side of
    the best. For ridges at least ~1.5 steps wide (any blurred CNN output) this finds the
    same maximum as a dense search of one step, in a little over half the reads. The
    maximum must be bracketed by two valid samples 1 step away (strictly inside the
    search, inside the image).
    """
    H, W = heatmaps.height, heatmaps.width
    st = float(step)
    L = max(1, round(half_length / st))
    maps = _native.native_maps(heatmaps) if _native.available() else None
    if maps is not None:
        return _native.line_search(maps, W, H, keyframes, channels, uv, normal,
                                   usable, L, st, threshold)
    N, M = uv.shape[:2]
    coarse = np.arange(-L, L + 1, 2, dtype=np.float64) * st
    vc = _profile(heatmaps, keyframes, channels, uv, normal, usable,
                  np.broadcast_to(coarse, (N, M, coarse.size)))
    kc = np.argmax(vc, axis=-1)
    sc = coarse[kc]
    vf = _profile(heatmaps, keyframes, channels, uv, normal, usable,
                  sc[..., None] + np.array([-st, st]))
    take = np.take_along_axis
    v_c = take(vc, kc[..., None], axis=-1)[..., 0]
    v_cm = np.where(kc > 0, take(vc, np.maximum(kc - 1, 0)[..., None], axis=-1)[..., 0], -1.0)
    v_cp = np.where(kc < coarse.size - 1,
                    take(vc, np.minimum(kc + 1, coarse.size - 1)[..., None], axis=-1)[..., 0],
                    -1.0)
    cand = np.stack([vf[..., 0], v_c, vf[..., 1]], axis=-1)  # at sc - 1, sc, sc + 1
    j = np.argmax(cand, axis=-1)
    peak = take(cand, j[..., None], axis=-1)[..., 0]
    vm = np.choose(j, [v_cm, vf[..., 0], v_c])
    vp = np.choose(j, [v_c, vf[..., 1], v_cp])
    best = sc + (j - 1) * st
    bracketed = (best > -L * st) & (best < L * st) & (vm >= 0.0) & (vp >= 0.0)
    found = usable & (peak >= threshold) & bracketed
    s = best + st * _peak_offset(vm, peak, vp)
    target = uv + s[..., None] * normal
    return target, found
