"""Heat-map targets: what a perfect detector would give for labelled 2-D keypoints.

Targets are the training labels of the CNN (rendered samples, labelled photos) and the
reference the detector's maps are scored against. Pixels follow
:mod:`turbinefit.geometry.camera` (pixel (0, 0) is the centre of the top-left pixel;
element ``[c, i, j]`` is at ``u = j, v = i``); channel order is that of
:mod:`turbinefit.heatmaps.channels`; values float32 in [0, 1].

A point is a Gaussian blob of standard deviation ``sigma`` and peak 1 in its point
channel; a line is a Gaussian-profile ridge (same ``sigma``, peak 1, rounded ends) in its
line channel, drawn as straight pieces each within its own bounding box (+ 4 sigma);
overlapping responses combine by maximum. The drawing primitives here are also those of
the simulator's heat-maps (:mod:`turbinefit.sim.render`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.heatmaps.channels import NUM_CHANNELS
from turbinefit.turbine.model import LINES, POINT_CHANNELS

FloatArray = NDArray[np.float64]
F32Array = NDArray[np.float32]

#: Blob / ridge standard deviation of the CNN's training targets [px at the model's input
#: size].
TARGET_SIGMA_PX = 1.5
#: Blobs and ridges are cut off this many sigma from the centre (exp(-8) = 3e-4).
CUTOFF_SIGMAS = 4.0


def draw_blob(img: F32Array, u: float, v: float, amp: float, sigma: float) -> None:
    """Max-composite a separable Gaussian blob centred at pixel (u, v) into ``img`` (H, W)."""
    h, w = img.shape
    rad = CUTOFF_SIGMAS * sigma
    j0, j1 = max(0, math.ceil(u - rad)), min(w, math.floor(u + rad) + 1)
    i0, i1 = max(0, math.ceil(v - rad)), min(h, math.floor(v + rad) + 1)
    if j0 >= j1 or i0 >= i1:
        return
    k = -0.5 / (sigma * sigma)
    gx = np.exp(k * (np.arange(j0, j1) - u) ** 2)
    gy = np.exp(k * (np.arange(i0, i1) - v) ** 2)
    patch = (amp * gy[:, None] * gx[None, :]).astype(np.float32)
    view = img[i0:i1, j0:j1]
    np.maximum(view, patch, out=view)


def _draw_piece(img: F32Array, x0: float, y0: float, x1: float, y1: float, amp: float,
                sigma: float) -> None:
    """Max-composite a Gaussian ridge along the pixel segment (x0, y0)-(x1, y1)."""
    h, w = img.shape
    rad = CUTOFF_SIGMAS * sigma
    j0, j1 = max(0, math.ceil(min(x0, x1) - rad)), min(w, math.floor(max(x0, x1) + rad) + 1)
    i0, i1 = max(0, math.ceil(min(y0, y1) - rad)), min(h, math.floor(max(y0, y1) + rad) + 1)
    if j0 >= j1 or i0 >= i1:
        return
    ex, ey = x1 - x0, y1 - y0
    l2 = ex * ex + ey * ey
    xs = (np.arange(j0, j1) - x0)[None, :]
    ys = (np.arange(i0, i1) - y0)[:, None]
    if l2 < 1e-12:
        d2 = xs * xs + ys * ys
    else:
        t = np.clip((xs * ex + ys * ey) * (1.0 / l2), 0.0, 1.0)
        dx = xs - t * ex
        dy = ys - t * ey
        d2 = dx * dx + dy * dy
    # hard cut-off at CUTOFF_SIGMAS from the segment (not at the box's corners), so that
    # the pieces of a line add up to exactly the whole line
    patch = (amp * np.exp((-0.5 / (sigma * sigma)) * d2)).astype(np.float32)
    patch[d2 > rad * rad] = 0.0
    view = img[i0:i1, j0:j1]
    np.maximum(view, patch, out=view)


def draw_polyline(img: F32Array, uv: FloatArray, amp: float, sigma: float,
                  piece_px: float) -> None:
    """Draw consecutive points ``uv`` (n, 2) as pieces, each split to <= piece_px."""
    for k in range(len(uv) - 1):
        x0, y0 = float(uv[k, 0]), float(uv[k, 1])
        x1, y1 = float(uv[k + 1, 0]), float(uv[k + 1, 1])
        n = max(1, math.ceil(math.hypot(x1 - x0, y1 - y0) / piece_px))
        for m in range(n):
            a, b = m / n, (m + 1) / n
            _draw_piece(img, x0 + a * (x1 - x0), y0 + a * (y1 - y0),
                        x0 + b * (x1 - x0), y0 + b * (y1 - y0), amp, sigma)


def clip_segment_rect(p0: FloatArray, p1: FloatArray, lo: FloatArray,
                      hi: FloatArray) -> tuple[float, float] | None:
    """Liang-Barsky: parameter range [t0, t1] of p0 + t (p1 - p0) inside the box, or None."""
    t0, t1 = 0.0, 1.0
    d = p1 - p0
    for k in range(2):
        if abs(d[k]) < 1e-15:
            if p0[k] < lo[k] or p0[k] > hi[k]:
                return None
            continue
        ta = (lo[k] - p0[k]) / d[k]
        tb = (hi[k] - p0[k]) / d[k]
        if ta > tb:
            ta, tb = tb, ta
        t0, t1 = max(t0, ta), min(t1, tb)
        if t0 > t1:
            return None
    return t0, t1


def render_keypoint_heatmaps(
    height: int,
    width: int,
    turbines_uv: Sequence[ArrayLike],
    turbines_labelled: Sequence[ArrayLike],
    sigma_px: float = 2.0,
    piece_px: float = 24.0,
) -> F32Array:
    """Heat-maps (7, H, W) float32 drawn from labelled 2-D keypoints (e.g. COCO labels).

    Args:
        height, width: image size [px].
        turbines_uv: per turbine, (6, 2) pixel positions of the model points in the order
            of :data:`turbinefit.turbine.model.POINT_NAMES` (pixel convention of the module
            docstring; positions outside the image are allowed).
        turbines_labelled: per turbine, (6,) booleans: which points are labelled.
        sigma_px: blob / ridge standard deviation [px].
        piece_px: lines are drawn as straight pieces at most this long [px].

    Each labelled point is a blob in its point channel; each model line whose two end
    points are both labelled is a straight ridge between them (clipped to the image), the
    same drawing as :func:`turbinefit.sim.render.render_heatmaps` without lens distortion.
    A line with an unlabelled end is not drawn (its extent is unknown).
    """
    if not (sigma_px > 0 and math.isfinite(sigma_px)):
        raise ValueError(f"sigma_px must be positive, got {sigma_px}")
    out = np.zeros((NUM_CHANNELS, int(height), int(width)), dtype=np.float32)
    lo = np.array([-CUTOFF_SIGMAS * sigma_px] * 2)
    hi = np.array([width - 1 + CUTOFF_SIGMAS * sigma_px, height - 1 + CUTOFF_SIGMAS * sigma_px])
    for uv_in, lab_in in zip(turbines_uv, turbines_labelled, strict=True):
        uv = np.asarray(uv_in, dtype=np.float64).reshape(6, 2)
        lab = np.asarray(lab_in, dtype=bool).reshape(6) & np.isfinite(uv).all(axis=1)
        for i, ch in enumerate(POINT_CHANNELS.tolist()):
            if lab[i]:
                draw_blob(out[ch], float(uv[i, 0]), float(uv[i, 1]), 1.0, sigma_px)
        for a_i, b_i, ch in LINES:
            if not (lab[a_i] and lab[b_i]):
                continue
            pa, pb = uv[a_i], uv[b_i]
            t = clip_segment_rect(pa, pb, lo, hi)
            if t is None:
                continue
            d = pb - pa
            draw_polyline(out[ch], np.stack([pa + t[0] * d, pa + t[1] * d]), 1.0, sigma_px,
                          piece_px)
    return out
