"""The correspondences read in the photos themselves, per round: where the tower's and the
blades' silhouettes are (the edge term, :mod:`turbinefit.costs.edges`) and how far away
their apparent widths say they are (the width term,
:mod:`turbinefit.costs.silhouette_width`).

Both start from the net's line correspondences (the net gives the basin): each tower and
blade line sample with one is searched for its two silhouette edges along the projected
line's normal, expecting the part's width at the sample's current depth, a blade's
between its thickness and its chord. With the width term and the blades' pitch known
(``FitConfig.blade_pitch_deg``), the separation found, against the one the estimate
predicts for the section's silhouette across the line of sight
(:func:`~turbinefit.turbine.solid.blade_silhouette_half_width`; projecting the sample's
two silhouette points), measures its depth. The search keeps the whole range of widths
even then: searching for the predicted width alone found, on a mission whose tracker was
3 m off along a blade's line of sight, pairs of edges that agreed with the wrong depth,
and the drone came to 0.67x the stand-off (``benchmarks/bench_mission.py --width-term``,
seed 0; 0.92x searching the whole range).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.edges import PhotoStack, find_edge_correspondences
from turbinefit.costs.projection import project_points
from turbinefit.costs.silhouette_width import WidthDepths, measure_depths
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.solver.config import FitConfig
from turbinefit.turbine.model import LINES, LineSampling
from turbinefit.turbine.solid import TurbineSolid, blade_profile, blade_silhouette_half_width

FloatArray = NDArray[np.float64]

#: The lines whose silhouettes the edge term searches: the tower and the three blades.
EDGE_LINES = (0, 2, 3, 4)
#: Photos less than this many times the maps' size are not searched for edges: at the
#: maps' own resolution the net's line correspondences are the more precise (0.19-0.24
#: against 0.42 map px off the true lines, ``benchmarks/bench_precision.py``).
MIN_EDGE_SCALE = 2.0
#: Line samples nearer the camera than this [m] are not searched for edges.
MIN_EDGE_DEPTH = 1.0


def sample_depths(world_T_cam: SE3, points: FloatArray) -> FloatArray:
    """(N, M) depths along each camera's optical axis of world ``points`` (M, 3), shared,
    or (N, M, 3), per camera."""
    R = world_T_cam.rotation_matrix()  # (N, 3, 3)
    d = (points if points.ndim == 3 else points[None]) - world_T_cam.translation[:, None]
    return np.einsum("nk,nmk->nm", R[:, :, 2], d)


def silhouette_correspondences(
    config: FitConfig, camera: PinholeCamera, photos: PhotoStack,
    keyframes: NDArray[np.int_], poses: SE3, theta: FloatArray, S: FloatArray,
    line_dirs: FloatArray, fractions: FloatArray | None, line_index: NDArray[np.int_],
    centre: FloatArray,
    found: NDArray[np.bool_], normal: FloatArray,
) -> tuple[FloatArray, NDArray[np.bool_], WidthDepths | None]:
    """The edge term's correspondences of N keyframes' M line samples (module docstring):
    the silhouettes' midpoints (N, M, 2) [map px] and where found (N, M); and with the
    width term (``lambda_width`` > 0) the depths their separations give, else None.

    Args:
        config: the fit's options.
        camera: the heat-maps' camera; photos: the keyframes' grey photos (indexed by
            ``keyframes``).
        poses: (N,) the current poses; theta: the current turbine.
        S: (M, 3) or (N, M, 3) the line samples' world points; line_dirs: (M, 3) the
            unit direction of each one's line; fractions: (N, 5, n) where each keyframe
            samples each line, or None (uniform).
        line_index: (M,) the line of each sample.
        centre, found, normal: the net's line correspondences (N, M, 2), which were found
            (N, M), and the normals they were searched along (N, M, 2).
    """
    N = len(poses)
    n = config.samples_per_line
    f = (np.broadcast_to(LineSampling(n).fractions(), (N, len(LINES), n))
         if fractions is None else fractions)
    # least and greatest half-widths [m] of each line's cross-section at its samples
    solid = TurbineSolid(theta, config.geometry)
    hw = np.zeros((N, len(LINES), n, 2))
    r = solid.r0 + (solid.r1 - solid.r0) * f[:, 0]
    hw[:, 0, :, 0] = hw[:, 0, :, 1] = r
    A, Bt = blade_profile(f[:, 2:].astype(np.float32), solid.b)
    hw[:, 2:, :, 0] = Bt
    hw[:, 2:, :, 1] = A
    half_width = hw.reshape(N, -1, 2)
    depth = sample_depths(poses, S)
    px_per_m = camera.fx / np.maximum(depth, 1e-3)
    usable = found & np.isin(line_index, EDGE_LINES)[None] & (depth > MIN_EDGE_DEPTH)
    widths = None
    if config.lambda_width > 0:
        # the search keeps the part's whole range of widths (module docstring)
        widths = silhouette_half_widths(config, solid, poses, S, line_dirs,
                                        f.reshape(N, -1), line_index)
    target, edge_found, sep = find_edge_correspondences(
        photos, keyframes, centre, normal, usable, half_width * px_per_m[..., None],
        config.px("edge_reach"))
    if widths is None:
        return target, edge_found, None
    return target, edge_found, width_depths(config, camera, photos, poses, S, normal, depth,
                                            widths, edge_found, sep, line_index)


def silhouette_half_widths(config: FitConfig, solid: TurbineSolid, poses: SE3,
                           S: FloatArray, line_dirs: FloatArray, fractions: FloatArray,
                           line_index: NDArray[np.int_]
                           ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per keyframe and line sample (N, M): the half-width [m] its part shows across the
    line of sight (NaN where not known: the nacelle, and the blades without
    ``blade_pitch_deg``), its relative uncertainty from the pitch's, and the unit world
    direction (N, M, 3) across the line and the line of sight it is measured along.
    ``line_dirs`` (M, 3): each sample's line's unit direction; ``fractions`` (N, M): where
    each sample lies along its line."""
    N = len(poses)
    Sn = np.broadcast_to(S, (N, *S.shape[-2:]))
    across = np.cross(np.broadcast_to(line_dirs, Sn.shape), Sn - poses.translation[:, None])
    across /= np.maximum(np.linalg.norm(across, axis=-1, keepdims=True), 1e-12)
    line = np.broadcast_to(line_index, fractions.shape)
    h = np.full(fractions.shape, np.nan)
    rel = np.zeros(fractions.shape)
    tower = line == 0
    h[tower] = (solid.r0 + (solid.r1 - solid.r0) * fractions)[tower]
    if config.blade_pitch_deg is not None:
        blade = line >= 2
        hb, dh = blade_silhouette_half_width(solid, line[blade] - 2, fractions[blade],
                                             across[blade], math.radians(config.blade_pitch_deg))
        h[blade] = hb
        rel[blade] = (np.abs(dh) * math.radians(config.blade_pitch_sigma_deg)
                      / np.maximum(hb, 1e-9))
    return h, rel, across


def width_depths(config: FitConfig, camera: PinholeCamera, photos: PhotoStack, poses: SE3,
                 S: FloatArray, normal: FloatArray, depth: FloatArray,
                 widths: tuple[FloatArray, FloatArray, FloatArray],
                 found: NDArray[np.bool_], separation: FloatArray,
                 line_index: NDArray[np.int_]) -> WidthDepths:
    """The samples' depths their edges' separations give (width term): the separation
    the current estimate predicts, projecting the sample's two silhouette points, against
    the one found; its noise two edges of ``edge_sigma`` photo px each. The samples of one
    line in one photo together weigh as one: their errors are shared (the section's pitch,
    a shaded side or a field behind the blade taken for an edge along a stretch of it),
    so each one's standard deviation is multiplied by the square root of their number."""
    h, rel, across = widths
    N = len(poses)
    known = np.isfinite(h)
    off = np.where(known, h, 0.0)[..., None] * across
    Sn = np.broadcast_to(S, (N, *S.shape[-2:]))
    plus = project_points(camera, poses, Sn + off, None, with_jacobian=False)
    minus = project_points(camera, poses, Sn - off, None, with_jacobian=False)
    predicted = np.abs(np.sum((plus.uv - minus.uv) * normal, axis=-1))
    sigma = math.sqrt(2.0) * config.edge_sigma / photos.scale
    m = measure_depths(depth, predicted, separation, found & known & plus.front & minus.front,
                       sigma, rel)
    per_line = np.zeros((N, len(LINES)))
    rows = np.broadcast_to(np.arange(N)[:, None], m.found.shape)
    np.add.at(per_line, (rows[m.found], np.broadcast_to(line_index, m.found.shape)[m.found]), 1)
    shared = np.sqrt(np.maximum(per_line[:, line_index], 1.0))
    return WidthDepths(m.depth, np.where(m.found, m.sigma * shared, m.sigma), m.found)
