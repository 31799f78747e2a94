"""The paper's direct heat-map cost E_unary(2): -log of the bicubically interpolated
heat-map under each projected model point.

Residual (documented choice; method notes ask for a well-behaved one)::

    r = sqrt(lambda) * w(uv) * sqrt(C + rho),   rho = -log((clamp(G, 0, 1) + eps) / (1 + eps))

``1/2 r^2 = 1/2 lambda w^2 (C + rho)``: C is a constant, so with ``eps -> 0`` this has the
paper's minimiser (``-log G``), but unlike ``sqrt(rho)`` its derivative stays bounded as
G -> 1 (``|dr/dG| <= 1 / (2 sqrt(C))``), ``rho(1) = 0``, and G -> 0 (an empty heat-map)
costs the finite ``-log(eps / (1 + eps))`` instead of infinity.

``eps`` (the ``heatmap_floor`` option) reads the heat-map as a mixture of the CNN's
response and a uniform background of weight eps. It is what keeps the cost usable on real
heat-maps: with a tiny floor (the bare -log, or a clamp at 1e-4) low-level background
noise of a few percent turns into large random cost and gradient everywhere off the
structure (-log 0.02 vs -log 0.0001), which stalls the solver; with eps = 0.05 such noise
barely changes the cost. Off the structure the cost is then nearly flat.

``w(uv)`` treats points outside the image or behind the camera as *no evidence*: it is 1
inside the image, falls smoothly (smoothstep) to 0 over ``margin`` pixels at the border, and
is 0 outside. Charging such points the background cost instead makes the solver shrink the
model to pull samples into view (measured: 3-9x worse fits).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.bicubic import interpolate
from turbinefit.costs.projection import Projection
from turbinefit.heatmaps import HeatmapStack

FloatArray = NDArray[np.float64]

#: Smallest allowed heat-map floor eps (-log 1e-4 ~ 9.2).
G_MIN = 1e-4
#: Default heat-map floor eps.
DEFAULT_FLOOR = 0.05
#: Constant added under the square root (keeps dr/dG bounded at G = 1).
RHO_OFFSET = 1e-6


def border_weight(uv: FloatArray, width: int, height: int, margin: float
                  ) -> tuple[FloatArray, FloatArray]:
    """Smooth in-image weight (..., ) and its gradient (..., 2) w.r.t. uv."""
    d = np.stack([uv[..., 0], width - 1 - uv[..., 0], uv[..., 1], height - 1 - uv[..., 1]], -1)
    which = np.argmin(d, axis=-1)
    dmin = np.take_along_axis(d, which[..., None], axis=-1)[..., 0]
    if margin <= 0:
        w = (dmin >= 0).astype(np.float64)
        return w, np.zeros((*w.shape, 2))
    x = np.clip(dmin / margin, 0.0, 1.0)
    w = x * x * (3.0 - 2.0 * x)
    dw_dd = np.where((x > 0) & (x < 1), 6.0 * x * (1.0 - x) / margin, 0.0)
    # d dmin / d uv: +-1 on u or v depending on the nearest border
    sign = np.array([1.0, -1.0, 1.0, -1.0])[which]
    grad = np.zeros((*w.shape, 2))
    axis = which // 2
    grad[..., 0] = np.where(axis == 0, sign * dw_dd, 0.0)
    grad[..., 1] = np.where(axis == 1, sign * dw_dd, 0.0)
    return w, grad


def heatmap_residuals(
    heatmaps: HeatmapStack,
    keyframes: NDArray[np.int_],
    channels: NDArray[np.int_],
    proj: Projection,
    sqrt_weight: float,
    margin: float,
    floor: float = DEFAULT_FLOOR,
) -> tuple[FloatArray, FloatArray | None]:
    """Residuals (N, M) and their Jacobians (N, M, 13) of the heat-map cost.

    Args:
        heatmaps, keyframes: the heat-maps and which keyframe each row of ``proj`` is.
        channels: (M,) heat-map channel of each point.
        proj: the points' projection (with Jacobian if one is wanted).
        sqrt_weight: sqrt(lambda) of this term.
        margin: border fade width [px].
        floor: the heat-map floor eps (see the module docstring).
    """
    ev = _evaluate(heatmaps, keyframes, channels, proj, margin, floor)
    r = sqrt_weight * ev.w * ev.root
    if proj.J is None:
        return r, None
    dr_duv = sqrt_weight * (ev.dw * ev.root[..., None]
                            + (ev.w * ev.drho_dG / (2.0 * ev.root))[..., None] * ev.dG)
    dr_duv = np.where(proj.front[..., None], dr_duv, 0.0)
    return r, np.einsum("nmk,nmkp->nmp", dr_duv, proj.J)


class _Eval:
    __slots__ = ("G", "dG", "drho_dG", "dw", "rho", "root", "w")

    def __init__(self, **kw: FloatArray) -> None:
        for k, v in kw.items():
            setattr(self, k, v)

    G: FloatArray
    dG: FloatArray
    drho_dG: FloatArray
    dw: FloatArray
    rho: FloatArray
    root: FloatArray
    w: FloatArray


def _evaluate(heatmaps: HeatmapStack, keyframes: NDArray[np.int_], channels: NDArray[np.int_],
              proj: Projection, margin: float, floor: float) -> _Eval:
    w, dw = border_weight(proj.uv, heatmaps.width, heatmaps.height, margin)
    w = np.where(proj.front, w, 0.0)
    dw = np.where(proj.front[..., None], dw, 0.0)
    G, dG = interpolate(heatmaps, keyframes, channels, proj.uv, with_gradient=True)
    assert dG is not None
    eps = max(floor, G_MIN)
    Gc = np.minimum(np.maximum(G, 0.0), 1.0)
    rho = np.log1p(eps) - np.log(Gc + eps)
    clamped = (G <= 0.0) | (G >= 1.0)
    drho_dG = np.where(clamped, 0.0, -1.0 / (Gc + eps))
    return _Eval(G=G, dG=dG, drho_dG=drho_dG, dw=dw, rho=rho, root=np.sqrt(RHO_OFFSET + rho), w=w)


def heatmap_model(
    heatmaps: HeatmapStack,
    keyframes: NDArray[np.int_],
    channels: NDArray[np.int_],
    proj: Projection,
    weight: float,
    margin: float,
    curvature: float,
    floor: float = DEFAULT_FLOOR,
    along: float = 0.25,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The heat-map cost with a curvature-aware Gauss-Newton model.

    The cost of a point is ``1/2 s`` with ``s = lambda w^2 (C + rho)`` (exactly the
    residual of :func:`heatmap_residuals` squared). Its plain Gauss-Newton model is poor:
    wherever a heat-map peak is not reached exactly (``rho_min > 0``: noise, blur, a model
    that cannot fit every sample), ``J^T J`` of ``sqrt(C + rho)`` vanishes at the minimum
    although the cost's curvature does not, so LM overshoots and crawls. Instead the model
    uses the exact gradient with the curvature of a Gaussian ridge of width
    ``1 / sqrt(curvature)`` px across the point's line (``along`` of it along the line;
    isotropic for points), plus the Gauss-Newton term of the border fade::

        g_uv = lambda [w grad(w) (C + rho) + 1/2 w^2 grad(rho)]
        H_uv = lambda [(C + rho) grad(w) grad(w)^T + 1/2 w^2 curvature P],
        P = n n^T + along t t^T (lines, tangent t, normal n), I (points)

    (``P`` is scaled by ``G / (G + eps)``: where the heat-map is at the floor there is no
    evidence and no stiffness; on a ridge this is the curvature of ``-log(G + eps)``).
    The model is returned as two rows per point, ``rows = L^-1 g_uv`` and
    ``J_rows = L^T J_uv`` with ``H_uv = L L^T``, so that ``J_rows^T rows`` is the exact
    gradient and ``J_rows^T J_rows`` the model Hessian. Only the step depends on this
    model; the cost, and so the optimum, is the paper's.

    Returns:
        s: (N, M) squared residuals (cost ``1/2 s``); rows: (N, M, 2); J_rows: (N, M, 2, 13).
    """
    assert proj.J is not None
    ev = _evaluate(heatmaps, keyframes, channels, proj, margin, floor)
    c_rho = RHO_OFFSET + ev.rho
    s = weight * ev.w * ev.w * c_rho
    grad_rho = ev.drho_dG[..., None] * ev.dG
    g = weight * (ev.w[..., None] * ev.dw * c_rho[..., None]
                  + 0.5 * (ev.w * ev.w)[..., None] * grad_rho)
    Gc = np.minimum(np.maximum(ev.G, 0.0), 1.0)
    k = 0.5 * weight * ev.w * ev.w * curvature * Gc / (Gc + max(floor, G_MIN))
    if proj.tangent is not None:
        t = proj.tangent
        nrm = np.stack([-t[..., 1], t[..., 0]], axis=-1)
        P = (nrm[..., :, None] * nrm[..., None, :]) + along * (t[..., :, None] * t[..., None, :])
    else:
        P = np.broadcast_to(np.eye(2), (*s.shape, 2, 2))
    H = k[..., None, None] * P + (weight * c_rho)[..., None, None] * (
        ev.dw[..., :, None] * ev.dw[..., None, :])
    tiny = 1e-9 * max(weight * curvature, 1e-12)
    a = H[..., 0, 0] + tiny
    b = H[..., 0, 1]
    c = H[..., 1, 1] + tiny
    l11 = np.sqrt(a)
    l21 = b / l11
    l22 = np.sqrt(np.maximum(c - l21 * l21, tiny))
    rows = np.empty((*s.shape, 2))
    rows[..., 0] = g[..., 0] / l11
    rows[..., 1] = (g[..., 1] - l21 * rows[..., 0]) / l22
    Ju = proj.J[..., 0, :]
    Jv = proj.J[..., 1, :]
    J_rows = np.empty(proj.J.shape)
    J_rows[..., 0, :] = l11[..., None] * Ju + l21[..., None] * Jv
    J_rows[..., 1, :] = l22[..., None] * Jv
    return s, rows, J_rows
