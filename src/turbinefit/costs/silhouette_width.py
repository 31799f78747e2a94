"""The width term: how far the camera is from a part, from how wide the part looks.

A line correspondence, from the heat-maps or from the silhouette's midpoint
(:mod:`turbinefit.costs.edges`), says where a part's axis is in the photo but not how far
away it is: sliding the camera along its line of sight to a blade leaves the projected
line where it was. Close up, where a photo shows part of one blade and no model point,
that distance is then held only by the GNSS fixes and the pose graph, metres off with
standard GNSS. The part's apparent width holds it: the tower is round, and a blade's
section is an ellipse whose axes the blade type and its parked pitch give
(:func:`turbinefit.turbine.solid.blade_silhouette_half_width`), so the separation ``w``
of the two silhouette edges the edge search found, against the separation ``w_0`` the
current estimate predicts at depth ``z_0``, measures the sample's depth::

    z_meas = z_0 w_0 / w,     sigma_z = z_meas sqrt((sigma_w / w)^2 + (sigma_h / h)^2)

with ``sigma_w`` the separation's noise (two edges of ``edge_sigma`` photo px each) and
``sigma_h / h`` what the pitch's uncertainty makes of the section's half-width ``h``.
The measured depth is held fixed while the solver iterates (like every correspondence,
re-measured each round), and the residual ``sqrt(lambda) (z - z_meas) / sigma_z`` of the
sample's depth ``z`` along the optical axis is linear in the camera-frame point, so its
Jacobians are exact (:mod:`turbinefit.costs.projection`'s conventions)::

    d z / d dt = -R[:, 2],   d z / d dphi = ([cam_p]x)[2] = (-y, x, 0),
    d z / d theta = R[:, 2] . d world_p / d theta

under a Cauchy loss of scale :data:`WIDTH_ROBUST_SCALE` (a field or a road behind a
blade can give a wrong pair of edges).

Written here: a model-based tracker's depth from a CAD model's silhouette width is a few
lines on top of the edge search, which no library offers for a parametric turbine.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.robust import RobustLoss
from turbinefit.geometry.se3 import SE3

FloatArray = NDArray[np.float64]

#: Scale of the Cauchy loss on the whitened depth residual.
WIDTH_ROBUST_SCALE = 2.0
#: Separations narrower than this [map px] measure nothing (a thin edge-on blade).
MIN_SEPARATION = 3.0


@dataclass(frozen=True)
class WidthDepths:
    """Depths of line samples measured from their apparent widths (module docstring).

    Attributes:
        depth: (N, M) measured depths along the optical axis [m] (0 where not found).
        sigma: (N, M) their standard deviations [m] (1 where not found).
        found: (N, M) which samples were measured.
    """

    depth: FloatArray
    sigma: FloatArray
    found: NDArray[np.bool_]


def measure_depths(depth: FloatArray, predicted: FloatArray, measured: FloatArray,
                   found: NDArray[np.bool_], separation_sigma: float,
                   shape_rel_sigma: FloatArray | float = 0.0) -> WidthDepths:
    """The depths the measured separations give (module docstring).

    Args:
        depth: (N, M) the samples' current depths [m].
        predicted: (N, M) the separations the current estimate predicts [px].
        measured: (N, M) the separations found [px].
        found: (N, M) where an edge pair was found.
        separation_sigma: the separation's noise [px].
        shape_rel_sigma: the part's half-width's relative uncertainty (broadcast).
    """
    ok = (found & np.isfinite(depth) & (depth > 0) & np.isfinite(predicted)
          & (predicted > 0) & np.isfinite(measured) & (measured >= MIN_SEPARATION))
    w = np.where(ok, measured, 1.0)
    z = np.where(ok, depth * np.where(ok, predicted, 1.0) / w, 0.0)
    rel = np.sqrt((separation_sigma / w) ** 2 + np.asarray(shape_rel_sigma) ** 2)
    sigma = np.where(ok, np.maximum(z * rel, 1e-6), 1.0)
    return WidthDepths(z, sigma, ok)


def width_terms(world_T_cam: SE3, points: FloatArray,
                J_theta: tuple[FloatArray, FloatArray, FloatArray | None] | None,
                meas: WidthDepths, lam: float, with_jacobian: bool,
                loss: RobustLoss | None = None
                ) -> tuple[float, int, FloatArray | None, FloatArray | None]:
    """The width term of N keyframes' M line samples.

    Args:
        world_T_cam: (N,) camera poses.
        points: (N, M, 3) the samples' world points [m].
        J_theta: ``(JA, JB, f)``: the samples' Jacobians w.r.t. theta as ``(1 - f) JA +
            f JB`` (JA, JB (M, 3, 7), f (N, M) or None: JA alone), or None (theta held).
        meas: the measured depths.
        lam: the term's weight.
        with_jacobian: also return the normal equations' blocks.
        loss: the robust loss (default Cauchy of :data:`WIDTH_ROBUST_SCALE`).

    Returns:
        ``(cost, count, JtHJ, g)``: ``1/2 sum rho(r^2)``, the samples used, and per
        keyframe (N, 13, 13) and (N, 13) over (dt, dphi, theta), or None.
    """
    loss = loss or RobustLoss("cauchy", WIDTH_ROBUST_SCALE)
    N = points.shape[0]
    R = world_T_cam.rotation_matrix()  # (N, 3, 3)
    t = world_T_cam.translation  # (N, 3)
    cam_p = np.einsum("nki,nmk->nmi", R, points - t[:, None])  # R^T (p - t)
    z = cam_p[..., 2]
    used = meas.found & (z > 0)
    r = np.where(used, np.sqrt(lam) * (z - meas.depth) / meas.sigma, 0.0)
    rho, drho = loss.evaluate(r * r)
    cost = 0.5 * float(np.sum(np.where(used, rho, 0.0)))
    count = int(used.sum())
    if not with_jacobian:
        return cost, count, None, None
    scale = np.where(used, np.sqrt(lam) / meas.sigma, 0.0)  # d r / d z
    J = np.zeros((*points.shape[:2], 13))
    J[..., 0:3] = -R[:, None, :, 2]
    J[..., 3] = -cam_p[..., 1]
    J[..., 4] = cam_p[..., 0]
    if J_theta is not None:
        JA, JB, f = J_theta
        a = np.einsum("nk,mkj->nmj", R[:, :, 2], JA)
        if f is None:
            J[..., 6:] = a
        else:
            b = np.einsum("nk,mkj->nmj", R[:, :, 2], JB)
            J[..., 6:] = a + f[..., None] * (b - a)
    J *= scale[..., None]
    w = np.where(used, drho, 0.0)
    JtHJ = np.einsum("nmi,nm,nmj->nij", J, w, J)
    g = np.einsum("nmi,nm->ni", J, w * r)
    assert JtHJ.shape == (N, 13, 13)
    return cost, count, JtHJ, g
