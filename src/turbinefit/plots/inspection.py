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
    from turbinefit.inspection.surface import FloatArray, TurbineSurface
    from turbinefit.io.georef import Georef

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


def coverage_note(coverage: Coverage, max_gsd_mm: float, focal_px: float | None) -> str | None:
    """The line ``coverage.png`` ends with when no photo reaches ``max_gsd_mm`` anywhere (why
    every "at <= ... mm/px" is 0 %), else None."""
    finite = np.concatenate([g.best_gsd[np.isfinite(g.best_gsd)] for g in coverage.grids]
                            + [np.ones(0)])
    if finite.size == 0:
        return "no photo shows the turbine"
    finest = float(finite.min())
    if finest <= max_gsd_mm:
        return None
    text = f"no photo reaches {max_gsd_mm:g} mm/px anywhere: the finest is {finest:.1f} mm/px"
    if focal_px is not None:
        text += (f"; at {max_gsd_mm:g} mm/px this camera (focal length {focal_px:.0f} px) "
                 f"must be within {max_gsd_mm * focal_px / 1000.0:.2f} m of the surface")
    return text


def plot_coverage(path: str | os.PathLike[str], coverage: Coverage, max_gsd_mm: float,
                  focal_px: float | None = None) -> Path:
    """Span (x) against side (rows, named) of each blade and the tower, coloured by the
    best ground sampling distance reached [mm/px, log scale; ``max_gsd_mm`` marked and
    labelled on the colour bar]; grey where never seen. Right of each row: the share of its
    span seen at all and at ``max_gsd_mm`` or finer; a line at the bottom says so when no
    photo reaches ``max_gsd_mm`` at all (:func:`coverage_note`; ``focal_px``: the photos'
    focal length, to say how close that needs the camera)."""
    import matplotlib
    from matplotlib.colors import LogNorm
    from matplotlib.patches import Patch

    from turbinefit.inspection.coverage import side_names
    from turbinefit.inspection.surface import PARTS

    grids = coverage.grids
    lo, hi = gsd_range([g.best_gsd for g in grids], max_gsd_mm)
    note = coverage_note(coverage, max_gsd_mm, focal_px)
    height = 1.45 * len(grids) + 1.0 + (0.3 if note else 0.0)
    fig = new_figure(10.5, height)
    top, bottom = 1.0 - 0.75 / height, (0.55 if note else 0.3) / height
    row_h = (top - bottom) / len(grids)
    cmap = matplotlib.colormaps[GSD_COLOURMAP].with_extremes(bad=GAP_COLOUR)
    norm = LogNorm(lo, hi)
    image = None
    axes = []
    for i, g in enumerate(grids):
        ax = fig.add_axes((0.12, top - (i + 1) * row_h + 0.33 * row_h, 0.6, 0.55 * row_h))
        axes.append(ax)
        data = np.where(np.isfinite(g.best_gsd), g.best_gsd, np.nan)
        x0 = float(g.spans[0] - 0.5 * g.step) if g.spans.size else 0.0
        x1 = float(g.spans[-1] + 0.5 * g.step) if g.spans.size else 1.0
        image = ax.imshow(np.ma.masked_invalid(data), aspect="auto", cmap=cmap, norm=norm,
                          extent=(x0, x1, 3.5, -0.5), interpolation="nearest")
        names = side_names(g.part)
        ax.set_yticks(range(4), [n.replace("_", " ") for n in names], fontsize=7)
        seen, fine = g.covered(), g.covered(max_gsd_mm)
        for k in range(4):
            for x, share in ((1.07, seen[k]), (1.22, fine[k])):
                ax.text(x, k, f"{100 * share:3.0f} %", transform=ax.get_yaxis_transform(),
                        va="center", ha="right", fontsize=7)
        ax.text(1.07, -0.62, "seen", transform=ax.get_yaxis_transform(), ha="right",
                va="bottom", fontsize=7, fontweight="bold")
        ax.text(1.22, -0.62, f"<= {max_gsd_mm:g} mm/px", transform=ax.get_yaxis_transform(),
                ha="right", va="bottom", fontsize=7, fontweight="bold")
        ax.set_title(PARTS[g.part].replace("_", " "), fontsize=8, loc="left")
        ax.set_xlabel("height above ground [m]" if PARTS[g.part] == "tower"
                      else "span from the hub centre [m]", fontsize=7)
        ax.tick_params(labelsize=7)
    if image is not None:
        cax = fig.add_axes((0.88, bottom + 0.05 * (top - bottom), 0.02, 0.9 * (top - bottom)))
        bar = fig.colorbar(image, cax=cax)
        bar.set_label("best mm per pixel (finer is lower)", fontsize=8)
        bar.ax.tick_params(labelsize=7)
        bar.ax.axhline(max_gsd_mm, color="red", lw=1.5)
        bar.ax.text(-0.3, max_gsd_mm, f"{max_gsd_mm:g} mm/px\n(--gsd)", color="red", fontsize=7,
                    ha="right", va="center", transform=bar.ax.get_yaxis_transform())
    fig.legend(handles=[Patch(facecolor=GAP_COLOUR, label="never seen")], fontsize=7,
               loc="upper right", bbox_to_anchor=(0.98, 1.0))
    fig.suptitle("best resolution along each side; share of the span seen at all and at "
                 f"<= {max_gsd_mm:g} mm/px", fontsize=9, x=0.12, ha="left", y=1.0 - 0.2 / height)
    if note:
        fig.text(0.12, 0.15 / height, note, fontsize=8, color="#b30000", ha="left")
    return save_png(fig, path)


#: Colours of the photos of each part in the path figure (blades A, B, C, tower).
PART_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#7f7f7f")


def plot_path(path: str | os.PathLike[str], plan: Plan, surface: TurbineSurface,
              georef: Georef | None = None) -> Path:
    """The planned path round the turbine in 3-D and from above: photos coloured by the part
    they show, the path coloured by waypoint order (a colour bar; every 25th waypoint
    numbered), its start and end marked. Georeferenced (``georef``), the top view is east
    and north with a north arrow, latitude and longitude on its opposite axes; otherwise it
    is the flight's local x and y, which say nothing of north."""
    import matplotlib
    from matplotlib.collections import LineCollection

    from turbinefit.inspection.surface import PARTS
    from turbinefit.plots.common import line_polyline, skeleton_points

    fig = new_figure(13.5, 6.5)
    ax3: Any = fig.add_axes((0.0, 0.04, 0.47, 0.86), projection="3d")
    ax2 = fig.add_axes((0.53, 0.2, 0.33, 0.66))
    cax = fig.add_axes((0.935, 0.2, 0.011, 0.66))
    skel = line_polyline(skeleton_points(surface.turbine, surface.geometry))
    pts = np.array([w.position for w in plan.waypoints]).reshape(-1, 3)
    n = len(pts)
    cmap = matplotlib.colormaps["plasma"]
    order = np.linspace(0.0, 1.0, max(n - 1, 1))
    def scatter(q: FloatArray, **kw: Any) -> None:
        """``q`` (n, 3) in both views (labelled in the top view's legend)."""
        label = kw.pop("label", None)
        ax3.scatter(q[:, 0], q[:, 1], q[:, 2], **kw)
        ax2.scatter(q[:, 0], q[:, 1], label=label, **kw)

    for ax, dims in ((ax3, (0, 1, 2)), (ax2, (0, 1))):
        ax.plot(*(skel[:, i] for i in dims), color="black", lw=2.0)
    for p in range(4):
        q = np.array([w.position for w in plan.waypoints if w.part == p]).reshape(-1, 3)
        if len(q):
            scatter(q, s=6, color=PART_COLOURS[p], zorder=3, label=PARTS[p].replace("_", " "))
    if n:
        scatter(pts[:1], s=90, marker="^", color="#00a000", edgecolor="black", zorder=5,
                label="start")
        scatter(pts[-1:], s=70, marker="s", color="#d62728", edgecolor="black", zorder=5,
                label="end")
    if n > 1:
        segs = np.stack([pts[:-1], pts[1:]], axis=1)
        ax2.add_collection(LineCollection(list(segs[:, :, :2]), colors=cmap(order), lw=1.0,
                                          zorder=2))
        for a, b, c in zip(pts[:-1], pts[1:], cmap(order), strict=True):
            ax3.plot(*zip(a, b, strict=True), color=c, lw=0.8)
        for i in range(0, n, 25):
            ax2.annotate(str(i), (float(pts[i, 0]), float(pts[i, 1])), fontsize=6, xytext=(3, 3),
                         textcoords="offset points", zorder=6)
    bar = fig.colorbar(matplotlib.cm.ScalarMappable(
        norm=matplotlib.colors.Normalize(0, max(n - 1, 1)), cmap=cmap), cax=cax)
    bar.set_label("waypoint order (waypoints.csv index)", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    lo = np.minimum(pts.min(axis=0), skel[np.isfinite(skel[:, 0])].min(axis=0)) if n \
        else np.zeros(3)
    hi = np.maximum(pts.max(axis=0), np.nanmax(skel, axis=0)) if n else np.ones(3)
    ax3.set_box_aspect(tuple(np.maximum(hi - lo, 1.0)))
    east, north = ("east [m]", "north [m]") if georef is not None else ("x [m]", "y [m]")
    ax3.set_xlabel(east)
    ax3.set_ylabel(north)
    ax3.set_zlabel("height [m]" if georef is not None else "z [m]")
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.set_xlabel(east)
    ax2.set_ylabel(north)
    ax2.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncols=6,
               borderaxespad=0.0, frameon=False)
    if georef is not None:
        _north_and_wgs84(ax2, georef)
        where = (f"origin {georef.latitude:.6f}, {georef.longitude:.6f} (WGS84); "
                 "heights above it")
    else:
        ax2.text(0.02, 0.02, "local frame (not georeferenced): north unknown",
                 transform=ax2.transAxes, fontsize=7, color="0.3")
        where = "local frame"
    fig.suptitle(f"{len(plan.photos)} photos, {n} waypoints, path {plan.length_m:.0f} m, "
                 f"{plan.gsd_mm:.2f} mm/px; clearance: rotor {plan.min_rotor_clearance:.1f} m, "
                 f"tower {plan.min_tower_clearance:.1f} m; {where}", fontsize=9)
    return save_png(fig, path)


def _north_and_wgs84(ax: Any, georef: Georef) -> None:
    """A north arrow in the top view's corner, and longitude and latitude on its top and
    right axes (the east-north frame about ``georef``; degrees per metre taken at the view's
    centre, linear to well below a tick's width across a turbine)."""
    from matplotlib.ticker import FormatStrFormatter, MaxNLocator

    ax.annotate("N", xy=(0.94, 0.97), xytext=(0.94, 0.82), xycoords="axes fraction",
                ha="center", va="center", fontsize=9, fontweight="bold",
                arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 1.5})
    ax.figure.canvas.draw()  # the limits the equal aspect settled on
    xm, ym = np.mean(ax.get_xlim()), np.mean(ax.get_ylim())
    lat, lon, _ = georef.geodetic(np.array([[0.0, ym, 0.0], [1.0, ym, 0.0],
                                            [xm, 0.0, 0.0], [xm, 1.0, 0.0]]))
    lon0, dlon = float(lon[0]), float(lon[1] - lon[0])
    lat0, dlat = float(lat[2]), float(lat[3] - lat[2])
    top = ax.secondary_xaxis("top", functions=(lambda x: lon0 + x * dlon,
                                               lambda v: (v - lon0) / dlon))
    right = ax.secondary_yaxis("right", functions=(lambda y: lat0 + y * dlat,
                                                   lambda v: (v - lat0) / dlat))
    top.set_xlabel("longitude [deg]", fontsize=7)
    right.set_ylabel("latitude [deg]", fontsize=7)
    for axis, n in ((top.xaxis, 4), (right.yaxis, 5)):
        axis.set_major_formatter(FormatStrFormatter("%.4f"))
        axis.set_major_locator(MaxNLocator(n))
    top.tick_params(labelsize=6)
    right.tick_params(labelsize=6)
