"""What every figure shares: colours, figure creation and atomic PNG saving, small helpers.

Figures draw on a bare :class:`matplotlib.figure.Figure` with the Agg canvas (no pyplot, no
global figure registry, works headless), import matplotlib only when called (so ``import
turbinefit`` stays fast), create missing parent directories and write atomically
(:func:`turbinefit.io.atomic.write_bytes_atomic`: a full disk is one error naming the figure,
and a killed process leaves no partial ``.png``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.geometry.camera import MIN_DEPTH, PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.turbine.model import (
    LINES,
    TurbineGeometry,
    TurbineParams,
    model_points,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]

#: Resolution of every PNG [dots per inch].
DPI = 150
#: zlib level of every PNG: the reprojections figure (photos and heat-maps, 2 MB) encodes
#: in a sixth of the default level 6's time for a fifth more bytes (the line figures: the
#: same time and size within a few per cent); its encoding was half of a fit's plotting.
PNG_COMPRESS_LEVEL = 1
#: Colours of the paper's figures.
GT_COLOUR = "#2ca02c"  # ground truth: green
INITIAL_COLOUR = "#d62728"  # initial estimate: red
OPTIMISED_COLOUR = "#1f77b4"  # optimised estimate: blue (scene figure)
CAUSAL_COLOUR = "#ff7f0e"  # tracker's estimate on arrival: orange
REPROJ_INITIAL_COLOUR = "#ff2a2a"  # initial estimate over heat-maps: bright red
REPROJ_OPTIMISED_COLOUR = "#39ff14"  # optimised estimate over heat-maps: bright green
#: Samples per 3-D line when projecting the skeleton (end points included).
LINE_SAMPLES = 50
#: Image coordinates beyond this many pixels are not drawn (near-singular projections).
MAX_PIXEL = 1e5

# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------
def new_figure(width: float, height: float) -> Figure:
    """A figure not registered with pyplot, on the Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig: Figure, path: str | os.PathLike[str]) -> Path:
    """Write ``fig`` to ``path`` as PNG atomically, then release the figure."""
    import io

    from turbinefit.io.atomic import write_bytes_atomic

    png = io.BytesIO()
    try:
        fig.savefig(png, format="png", dpi=DPI,
                    pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})
    finally:
        fig.clear()
    return write_bytes_atomic(path, png.getvalue(), fsync=False)


def as_batch(poses: SE3 | None) -> SE3:
    """Poses as a flat batch (N, 7) (N may be 0)."""
    if poses is None:
        return SE3(np.zeros((0, 7)))
    return SE3(np.asarray(poses.wxyz_xyz, dtype=np.float64).reshape(-1, 7))


def skeleton_points(turbine: TurbineParams, geometry: TurbineGeometry) -> FloatArray:
    """The six model points (6, 3) [m] of a turbine."""
    pts, _ = model_points(turbine.to_vector(), geometry)
    return pts


def line_polyline(points: FloatArray, n: int = LINE_SAMPLES) -> FloatArray:
    """All model lines sampled densely, as one polyline (5 * (n + 1), 3) with NaN breaks."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    parts = []
    for a, b, _ in LINES:
        parts.append(points[a] * (1.0 - s) + points[b] * s)
        parts.append(np.full((1, 3), np.nan))
    return np.concatenate(parts, axis=0)


def project_skeleton(camera: PinholeCamera, world_T_cam: SE3, points: FloatArray,
                     n: int = LINE_SAMPLES) -> tuple[FloatArray, FloatArray]:
    """Pixels of the model lines of ``points`` (6, 3) sampled ``n`` times each, as one
    polyline (5 (n + 1), 2) with NaN breaks, and of the six model points (6, 2), seen by
    ``camera`` at ``world_T_cam``; NaN where not drawable (behind the camera, beyond the
    trusted distortion range, further than :data:`MAX_PIXEL`). Pixels outside the image
    are kept: the drawing clips them."""
    cam_T_world = world_T_cam.inverse()
    out = []
    for world_p in (line_polyline(points, n), points):
        finite = np.all(np.isfinite(world_p), axis=1)
        cam_p = cam_T_world @ np.where(finite[:, None], world_p, 0.0)
        uv, front, _ = camera.project_unbounded(cam_p)
        ok = finite & front & (cam_p[:, 2] > MIN_DEPTH) & np.all(np.abs(uv) < MAX_PIXEL, axis=1)
        out.append(np.where(ok[:, None], uv, np.nan))
    return out[0], out[1]


def choose_keyframes(n_keyframes: int, count: int = 6) -> list[int]:
    """Up to ``count`` keyframe indices spread evenly over ``0 .. n_keyframes - 1``, first
    and last included (all of them if there are no more than ``count``)."""
    n, c = int(n_keyframes), int(count)
    if n <= 0 or c <= 0:
        return []
    if c >= n:
        return list(range(n))
    if c == 1:
        return [(n - 1) // 2]
    idx = np.round(np.linspace(0.0, n - 1.0, c)).astype(int)
    return sorted({int(i) for i in idx})



def as_series(values: ArrayLike | None) -> FloatArray:
    if values is None:
        return np.zeros(0)
    return np.asarray(values, dtype=np.float64).ravel()


def mean_label(name: str, v: FloatArray, unit: str) -> str:
    finite = v[np.isfinite(v)]
    return f"{name} (mean {np.mean(finite):.3g} {unit})" if finite.size else name
