"""Figures of an inspection: the coverage of each blade's and the tower's sides
(``coverage``) and a planned path round the turbine (``plan``); the coverage's colour scale
(:func:`gsd_range`, :func:`gsd_colours`), which the interactive page
(:mod:`turbinefit.view.scene`) paints on the turbine."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.plots.common import new_figure, save_png

if TYPE_CHECKING:
    from turbinefit.inspection.coverage import Coverage
    from turbinefit.inspection.plan import Plan
    from turbinefit.inspection.surface import TurbineSurface

#: Colour of span never seen.
GAP_COLOUR = "#d9d9d9"
#: The colour map of the best ground sampling distance (log scale; fine is yellow).
GSD_COLOURMAP = "viridis_r"


def gsd_range(best_gsd: Sequence[NDArray[np.float64]], max_gsd_mm: float) -> tuple[float, float]:
    """The ends [mm/px] of the colour scale of best ground sampling distances ``best_gsd``
    (arrays; inf: never seen) with the threshold ``max_gsd_mm`` inside it."""
    finite = np.concatenate([np.asarray(g)[np.isfinite(g)].ravel() for g in best_gsd]
                            + [np.ones(0)])
    lo = max(min(float(finite.min()) if finite.size else 1.0, max_gsd_mm) * 0.9, 1e-3)
    hi = max(float(finite.max()) if finite.size else 10.0, max_gsd_mm * 1.5, lo * 10)
    return lo, hi


def gsd_colours(gsd: ArrayLike, lo: float, hi: float) -> NDArray[np.uint8]:
    """sRGB colours (..., 3) of ground sampling distances ``gsd`` [mm/px] on the scale
    ``lo`` .. ``hi`` of :func:`plot_coverage` (:data:`GSD_COLOURMAP`, log scale; values
    outside it take its ends); :data:`GAP_COLOUR` where not finite (never seen)."""
    import matplotlib
    from matplotlib.colors import to_rgb

    g = np.asarray(gsd, dtype=np.float64)
    finite = np.isfinite(g) & (g > 0)
    t = np.zeros(g.shape)
    t[finite] = np.clip(np.log(g[finite] / lo) / math.log(hi / lo), 0.0, 1.0)
    rgb = np.asarray(matplotlib.colormaps[GSD_COLOURMAP](t))[..., :3]
    rgb[~finite] = to_rgb(GAP_COLOUR)
    return np.round(255.0 * rgb).astype(np.uint8)


def plot_coverage(path: str | os.PathLike[str], coverage: Coverage, max_gsd_mm: float) -> Path:
    """Span (x) against side (rows) of each blade and the tower, coloured by the best
    ground sampling distance reached [mm/px, log scale; ``max_gsd_mm`` marked red on the
    colour bar]; grey where never seen."""
    import matplotlib
    from matplotlib.colors import LogNorm
    from matplotlib.patches import Patch

    from turbinefit.inspection.coverage import side_names
    from turbinefit.inspection.surface import PARTS

    grids = coverage.grids
    lo, hi = gsd_range([g.best_gsd for g in grids], max_gsd_mm)
    fig = new_figure(9.0, 1.45 * len(grids) + 1.0)
    axes = fig.subplots(len(grids), 1, squeeze=False)[:, 0]
    cmap = matplotlib.colormaps[GSD_COLOURMAP].with_extremes(bad=GAP_COLOUR)
    norm = LogNorm(lo, hi)
    image = None
    for ax, g in zip(axes, grids, strict=True):
        data = np.where(np.isfinite(g.best_gsd), g.best_gsd, np.nan)
        x0 = float(g.spans[0] - 0.5 * g.step) if g.spans.size else 0.0
        x1 = float(g.spans[-1] + 0.5 * g.step) if g.spans.size else 1.0
        image = ax.imshow(np.ma.masked_invalid(data), aspect="auto", cmap=cmap, norm=norm,
                          extent=(x0, x1, 3.5, -0.5), interpolation="nearest")
        names = side_names(g.part)
        ax.set_yticks(range(4), [n.replace("_", " ") for n in names], fontsize=7)
        seen = g.covered()
        fine = g.covered(max_gsd_mm)
        ax.set_title(f"{PARTS[g.part].replace('_', ' ')}: seen "
                     + ", ".join(f"{100 * s:.0f}" for s in seen)
                     + f" %; at <= {max_gsd_mm:g} mm/px "
                     + ", ".join(f"{100 * s:.0f}" for s in fine) + " %", fontsize=8)
        ax.set_xlabel("height above ground [m]" if PARTS[g.part] == "tower"
                      else "span from the hub centre [m]", fontsize=7)
        ax.tick_params(labelsize=7)
    if image is not None:
        bar = fig.colorbar(image, ax=list(axes), fraction=0.03, pad=0.02)
        bar.set_label("best mm per pixel", fontsize=8)
        bar.ax.axhline(max_gsd_mm, color="red", lw=1.0)
    axes[0].legend(handles=[Patch(facecolor=GAP_COLOUR, label="never seen")], fontsize=7,
                   loc="lower right", bbox_to_anchor=(1.0, 1.2))
    fig.subplots_adjust(left=0.13, right=0.86, top=1.0 - 0.7 / fig.get_figheight(),
                        bottom=0.06, hspace=0.75)
    return save_png(fig, path)


#: Colours of the photos of each part in the path figure (blades A, B, C, tower).
PART_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#7f7f7f")


def plot_path(path: str | os.PathLike[str], plan: Plan, surface: TurbineSurface) -> Path:
    """The planned path round the turbine in 3-D (photos coloured by the part they show,
    transit legs dashed) and from above."""
    from turbinefit.inspection.surface import PARTS
    from turbinefit.plots.common import line_polyline, skeleton_points

    fig = new_figure(11.0, 5.5)
    ax3: Any = fig.add_axes((0.0, 0.04, 0.58, 0.86), projection="3d")
    ax2 = fig.add_axes((0.64, 0.12, 0.34, 0.76))
    skel = line_polyline(skeleton_points(surface.turbine, surface.geometry))
    pts = np.array([w.position for w in plan.waypoints]).reshape(-1, 3)
    for ax, dims in ((ax3, (0, 1, 2)), (ax2, (0, 1))):
        ax.plot(*(skel[:, i] for i in dims), color="black", lw=2.0)
        ax.plot(*(pts[:, i] for i in dims), color="0.55", lw=0.7, ls="--")
        for p in range(4):
            q = np.array([w.position for w in plan.waypoints if w.part == p]).reshape(-1, 3)
            if len(q) and len(dims) == 3:
                ax3.scatter(q[:, 0], q[:, 1], q[:, 2], s=4, color=PART_COLOURS[p])
            elif len(q):
                ax2.scatter(q[:, 0], q[:, 1], s=4, color=PART_COLOURS[p],
                            label=PARTS[p].replace("_", " "))
    lo = np.minimum(pts.min(axis=0), skel[np.isfinite(skel[:, 0])].min(axis=0)) if len(pts) \
        else np.zeros(3)
    hi = np.maximum(pts.max(axis=0), np.nanmax(skel, axis=0)) if len(pts) else np.ones(3)
    box = np.maximum(hi - lo, 1.0)
    ax3.set_box_aspect(tuple(box))
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax2.set_aspect("equal")
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    ax2.legend(fontsize=7, loc="best")
    fig.suptitle(f"{len(plan.photos)} photos, path {plan.length_m:.0f} m, "
                 f"{plan.gsd_mm:.2f} mm/px; clearance: rotor {plan.min_rotor_clearance:.1f} m, "
                 f"tower {plan.min_tower_clearance:.1f} m", fontsize=9)
    return save_png(fig, path)
