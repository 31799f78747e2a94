"""Figures of one flight: the scene in 3-D, reprojections over the heat-maps, per-keyframe
errors, the cost per iteration and the tracker's latency (what ``fit`` and ``track`` write).

* :func:`plot_scene` -- the paper's Fig. 3 ("synth_output_figure"): turbine skeletons and
  camera trajectories in 3-D (ground truth green, initial red, optimised blue) plus a
  top-down (x-y) panel.
* :func:`plot_reprojections` -- the paper's real-data figures: a grid of keyframes, each
  showing its heat-maps with the turbine model projected from the initial (red) and the
  optimised (green) estimate.
* :func:`plot_errors` -- per-keyframe position / orientation error, initial vs optimised;
  :func:`plot_pose_errors` computes them from the poses.
* :func:`plot_cost_history` -- the LM cost per iteration (log scale).
* :func:`plot_latency` -- the tracker's per-keyframe update time.

Conventions: poses are ``world_T_cam`` (camera-to-world) :class:`~turbinefit.geometry.se3.SE3`
batches, the camera frame is OpenCV (x right, y down, z forward), world units are metres.
Empty inputs or a turbine out of view give a sparse figure, never an exception.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, pose_errors
from turbinefit.heatmaps import HeatmapStack
from turbinefit.turbine.model import (
    PAPER_GEOMETRY,
    TurbineGeometry,
    TurbineParams,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes

from turbinefit.plots.common import (
    CAUSAL_COLOUR,
    GT_COLOUR,
    INITIAL_COLOUR,
    OPTIMISED_COLOUR,
    REPROJ_INITIAL_COLOUR,
    REPROJ_OPTIMISED_COLOUR,
    FloatArray,
    as_batch,
    as_series,
    choose_keyframes,
    line_polyline,
    mean_label,
    new_figure,
    project_skeleton,
    save_png,
    skeleton_points,
)

#: Largest opacity of the heat-maps drawn over a keyframe's photo (:func:`plot_reprojections`).
PHOTO_HEATMAP_ALPHA = 0.45


# ---------------------------------------------------------------------------------------
# scene (paper Fig. 3)
# ---------------------------------------------------------------------------------------
def _frusta(poses: SE3, keyframes: Sequence[int], size: float) -> FloatArray:
    """Wire-frame camera pyramids (apex at the camera centre, image rectangle ``size``
    metres ahead) for the given keyframes, as one polyline (M, 3) with NaN breaks."""
    if not keyframes:
        return np.zeros((0, 3))
    # image corners in the camera frame (OpenCV: x right, y down), ~60 deg horizontal FOV
    corners = np.array([[-0.6, -0.45, 1.0], [0.6, -0.45, 1.0], [0.6, 0.45, 1.0],
                        [-0.6, 0.45, 1.0]]) * size
    nan = np.full((1, 3), np.nan)
    parts = []
    for k in keyframes:
        T = poses[int(k)]
        c = T @ corners
        o = T.translation[None, :]
        parts += [np.concatenate([c, c[:1]]), nan]  # image rectangle
        for i in range(4):
            parts += [np.concatenate([o, c[i : i + 1]]), nan]
        # "up" tick on the top edge so the roll is readable
        top_mid = T @ (np.array([0.0, -0.45 - 0.25, 1.0]) * size)
        parts += [np.stack([c[0], top_mid, c[1]]), nan]
    return np.concatenate(parts, axis=0)


def finite_rows(a: FloatArray) -> FloatArray:
    a = a.reshape(-1, 3)
    return a[np.all(np.isfinite(a), axis=1)]


def plot_scene(
    path: str | os.PathLike[str],
    *,
    initial_poses: SE3,
    optimised_poses: SE3,
    initial_turbine: TurbineParams,
    optimised_turbine: TurbineParams,
    gt_poses: SE3 | None = None,
    gt_turbine: TurbineParams | None = None,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
    title: str | None = None,
) -> Path:
    """The paper's Fig. 3: turbine skeletons and camera trajectories, 3-D and top-down.

    Ground truth is green, the initial estimate red, the optimised estimate blue. Turbines
    are thick lines with the six model points marked, trajectories thin lines (start marked
    with a circle); for a few evenly spread keyframes the 3-D view shows small camera
    frusta (with a tick on the image's top edge) and the top-down view heading ticks along
    the optical axis. Both views use equal scaling in metres.

    Args:
        path: output PNG.
        initial_poses, optimised_poses, gt_poses: ``world_T_cam`` batches (N,) (may be
            empty; ``gt_poses`` optional).
        initial_turbine, optimised_turbine, gt_turbine: turbine parameters (``gt_turbine``
            optional).
        geometry: shape details beyond the paper's model (default: the paper's).
        title: figure title (default: a description of the colours).

    Returns:
        ``Path(path)``.
    """
    from matplotlib.lines import Line2D

    sets: list[tuple[str, str, SE3, TurbineParams | None]] = []
    if gt_poses is not None or gt_turbine is not None:
        sets.append(("ground truth", GT_COLOUR, as_batch(gt_poses), gt_turbine))
    sets.append(("initial", INITIAL_COLOUR, as_batch(initial_poses), initial_turbine))
    sets.append(("optimised", OPTIMISED_COLOUR, as_batch(optimised_poses), optimised_turbine))

    skeletons = {name: skeleton_points(t, geometry) for name, _, _, t in sets if t is not None}
    positions = {name: p.translation.reshape(-1, 3) for name, _, p, _ in sets}

    # scene extent -> frustum size and equal-scaled limits
    everything = np.concatenate(
        [finite_rows(x) for x in (*skeletons.values(), *positions.values())] + [np.zeros((0, 3))]
    )
    if everything.shape[0] == 0:
        everything = np.zeros((1, 3))
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    extent = float(max(np.max(hi - lo), 1.0))
    frustum_size = 0.045 * extent

    fig = new_figure(15.0, 7.5)
    ax3: Any = fig.add_axes((0.0, 0.04, 0.58, 0.86), projection="3d")
    ax2 = fig.add_axes((0.62, 0.15, 0.36, 0.74))

    frusta_pts: list[FloatArray] = []
    for name, colour, poses, turbine in sets:
        n = len(poses)
        pos = positions[name]
        kfs = choose_keyframes(n, 8)
        # trajectory
        ax3.plot(pos[:, 0], pos[:, 1], pos[:, 2], color=colour, lw=1.2, alpha=0.9)
        ax2.plot(pos[:, 0], pos[:, 1], color=colour, lw=1.2, alpha=0.9)
        if n:
            ax3.scatter(*pos[0], color=colour, s=18, marker="o", depthshade=False)
            ax2.plot(pos[0, 0], pos[0, 1], "o", color=colour, ms=5, mfc="white")
            # frusta (3-D) and heading ticks (top-down)
            fr = _frusta(poses, kfs, frustum_size)
            frusta_pts.append(fr)
            ax3.plot(fr[:, 0], fr[:, 1], fr[:, 2], color=colour, lw=0.7, alpha=0.85)
            sel = poses[np.asarray(kfs, dtype=int)]
            axis = sel.rotation_matrix()[:, :, 2]  # optical axis in the world frame
            tip = sel.translation + 1.6 * frustum_size * axis
            ticks = np.stack([sel.translation, tip, np.full_like(tip, np.nan)], axis=1)
            ticks = ticks.reshape(-1, 3)
            ax2.plot(ticks[:, 0], ticks[:, 1], color=colour, lw=1.0)
            ax2.plot(sel.translation[:, 0], sel.translation[:, 1], ".", color=colour, ms=4)
        # turbine
        if turbine is not None:
            sk = skeletons[name]
            poly = line_polyline(sk, 2)
            ax3.plot(poly[:, 0], poly[:, 1], poly[:, 2], color=colour, lw=2.6,
                     solid_capstyle="round")
            ax3.scatter(sk[:, 0], sk[:, 1], sk[:, 2], color=colour, s=14, depthshade=False)
            ax2.plot(poly[:, 0], poly[:, 1], color=colour, lw=2.6, solid_capstyle="round")
            ax2.plot(sk[:, 0], sk[:, 1], "o", color=colour, ms=3.5)
            ax2.plot(sk[0, 0], sk[0, 1], "s", color=colour, ms=7, mfc="none", mew=1.5)

    # equal axis scaling in 3-D: limits padded around the data, box aspect = data ranges
    allp = np.concatenate([everything, *[finite_rows(f) for f in frusta_pts]])
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    lo[2] = min(lo[2], 0.0)  # show the ground
    span = hi - lo
    span = np.maximum(span, 0.4 * float(np.max(span)))  # no needle-thin box: widen the limits
    centre = 0.5 * (lo + hi)
    pad = 0.04 * float(np.max(span))
    lims = np.stack([centre - 0.5 * span - pad, centre + 0.5 * span + pad], axis=1)
    ax3.set_xlim(*lims[0])
    ax3.set_ylim(*lims[1])
    ax3.set_zlim(*lims[2])
    box = lims[:, 1] - lims[:, 0]
    ax3.set_box_aspect(tuple(box), zoom=1.08 if box[2] <= max(box[0], box[1]) else 0.95)
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.view_init(elev=22.0, azim=-58.0)
    ax3.set_title("3-D view", fontsize=11)
    # faint ground plane outline
    gx = [lims[0, 0], lims[0, 1], lims[0, 1], lims[0, 0], lims[0, 0]]
    gy = [lims[1, 0], lims[1, 0], lims[1, 1], lims[1, 1], lims[1, 0]]
    ax3.plot(gx, gy, [0.0] * 5, color="0.75", lw=0.8)

    ax2.set_aspect("equal", adjustable="datalim")
    ax2.grid(True, color="0.9", lw=0.6)
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    ax2.set_title("top-down (x-y)", fontsize=11)

    handles = [Line2D([], [], color=c, lw=2.6, label=name) for name, c, _, _ in sets]
    handles += [
        Line2D([], [], color="0.3", lw=2.6, label="turbine skeleton"),
        Line2D([], [], color="0.3", lw=1.2, marker="o", mfc="white", ms=5,
               label="camera path (o = start)"),
        Line2D([], [], color="0.3", lw=0.7, label="camera frustum / heading"),
    ]
    fig.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.60, 0.0), ncol=3,
               fontsize=9, frameon=False)
    if title is None:
        colours = {GT_COLOUR: "green", INITIAL_COLOUR: "red", OPTIMISED_COLOUR: "blue"}
        title = "Turbine model and drone trajectory: " + ", ".join(
            f"{name} ({colours[c]})" for name, c, _, _ in sets)
    fig.suptitle(title, fontsize=12)
    return save_png(fig, path)


# ---------------------------------------------------------------------------------------
# reprojections (paper's real-data figures)
# ---------------------------------------------------------------------------------------
def _heatmap_composite(maps: NDArray[np.floating]) -> FloatArray:
    """An RGB image (H, W, 3) of one keyframe's heat-maps (7, H, W): the line channels'
    maximum in steel blue, the point channels' maximum in warm white, on black."""
    m = np.nan_to_num(np.asarray(maps, dtype=np.float64), nan=0.0, posinf=1.0, neginf=0.0)
    m = np.clip(m, 0.0, 1.0)
    points = m[:4].max(axis=0)
    lines = m[4:].max(axis=0)
    rgb = lines[..., None] * np.array([0.30, 0.55, 0.95]) + points[..., None] * np.array(
        [1.0, 0.95, 0.75])
    return np.clip(rgb, 0.0, 1.0)


def _grid(n: int) -> tuple[int, int]:
    """(rows, cols) of a panel grid for ``n`` panels."""
    if n <= 1:
        return 1, 1
    if n in (2, 4):
        return (n + 1) // 2, 2
    cols = 3 if n <= 9 else int(np.ceil(np.sqrt(n)))
    return int(np.ceil(n / cols)), cols


def plot_reprojections(
    path: str | os.PathLike[str],
    *,
    camera: PinholeCamera,
    heatmaps: HeatmapStack,
    keyframes: Sequence[int],
    initial_poses: SE3,
    initial_turbine: TurbineParams,
    optimised_poses: SE3,
    optimised_turbine: TurbineParams,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
    timestamps: ArrayLike | None = None,
    photo: Callable[[int], NDArray[np.uint8]] | None = None,
) -> Path:
    """The turbine model projected over the heat-maps (or the photos) of chosen keyframes.

    One panel per keyframe: its heat-maps as a colour composite (line channels steel blue,
    point channels warm white, on black), overlaid with the projected skeleton -- five
    lines sampled at :data:`LINE_SAMPLES` points each and the six model points -- of the
    initial estimate (red) and the optimised one (green), as in the paper's real-data
    figures. Samples behind the camera are not drawn; parts outside the image are clipped.

    Args:
        path: output PNG.
        camera: intrinsics of the images; heat-maps of another resolution are stretched to
            the camera's image.
        heatmaps: the flight's heat-maps (N, 7, H, W).
        keyframes: indices into ``heatmaps`` and both pose batches (see
            :func:`choose_keyframes`); may be empty.
        initial_poses, optimised_poses: ``world_T_cam`` batches (N,).
        initial_turbine, optimised_turbine: turbine parameters.
        geometry: shape details beyond the paper's model.
        timestamps: (N,) keyframe times [s] for the panel titles, or None.
        photo: keyframe index -> its photo (RGB uint8, any size: stretched to the
            camera's image), for a flight fitted from its photos: each panel then shows
            the photo with the heat-maps faint on top (their composite, opaque in
            proportion to the strongest channel at each pixel, at most
            :data:`PHOTO_HEATMAP_ALPHA`), as the paper's real-data figures do.

    Returns:
        ``Path(path)``.

    Raises:
        InputError: a keyframe index outside the heat-maps or the pose batches.
    """
    from matplotlib.lines import Line2D

    init = as_batch(initial_poses)
    opt = as_batch(optimised_poses)
    kfs = [int(k) for k in keyframes]
    n_avail = min(len(heatmaps), len(init), len(opt))
    bad = [k for k in kfs if not 0 <= k < n_avail]
    if bad:
        raise InputError(f"keyframe index {bad[0]} out of range 0..{n_avail - 1} "
                         f"({len(heatmaps)} heat-maps, {len(init)} initial and {len(opt)} "
                         "optimised poses)", field="keyframes")
    times = None if timestamps is None else np.asarray(timestamps, dtype=np.float64).ravel()

    skeletons = (
        ("initial", REPROJ_INITIAL_COLOUR, init, skeleton_points(initial_turbine, geometry)),
        ("optimised", REPROJ_OPTIMISED_COLOUR, opt, skeleton_points(optimised_turbine, geometry)),
    )
    W, H = camera.width, camera.height
    rows, cols = _grid(len(kfs))
    panel_w = 4.2
    panel_h = panel_w * H / W + 0.45
    fig = new_figure(cols * panel_w, rows * panel_h + 0.5)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.5 / (rows * panel_h + 0.5) + 0.01,
                        top=1.0 - 0.3 / (rows * panel_h + 0.5), wspace=0.04, hspace=0.14)
    axes: list[Axes] = [fig.add_subplot(rows, cols, i + 1) for i in range(rows * cols)]

    for ax in axes[len(kfs):]:
        ax.set_axis_off()
    if not kfs:
        axes[0].text(0.5, 0.5, "no keyframes", ha="center", va="center",
                     transform=axes[0].transAxes, color="0.4")

    for ax, k in zip(axes, kfs, strict=False):
        extent = (-0.5, W - 0.5, H - 0.5, -0.5)
        if photo is None:
            ax.imshow(_heatmap_composite(heatmaps[k]), extent=extent, interpolation="bilinear")
        else:
            ax.imshow(photo(k), extent=extent, interpolation="bilinear")
            strength = np.clip(np.nan_to_num(np.asarray(heatmaps[k], dtype=np.float64)).max(axis=0),
                               0.0, 1.0)
            rgba = np.dstack([_heatmap_composite(heatmaps[k]), PHOTO_HEATMAP_ALPHA * strength])
            ax.imshow(rgba, extent=extent, interpolation="bilinear")
        for _, colour, poses, sk in skeletons:
            lines_uv, points_uv = project_skeleton(camera, poses[k], sk)
            ax.plot(lines_uv[:, 0], lines_uv[:, 1], color=colour, lw=1.3, alpha=0.95)
            ax.plot(points_uv[:, 0], points_uv[:, 1], "o", color=colour, ms=4.5, mec="black",
                    mew=0.5)
        ax.set_xlim(-0.5, W - 0.5)
        ax.set_ylim(H - 0.5, -0.5)
        ax.set_xticks([])
        ax.set_yticks([])
        label = f"keyframe {k}"
        if times is not None and k < times.size and np.isfinite(times[k]):
            label += f"   t = {times[k]:.2f} s"
        ax.set_title(label, fontsize=9)

    handles = [Line2D([], [], color=c, lw=1.6, marker="o", ms=4.5, mec="black", mew=0.5,
                      label=f"{name} estimate") for name, c, _, _ in skeletons]
    handles += [
        Line2D([], [], color=(0.30, 0.55, 0.95), lw=5, alpha=0.8, label="heat-map: lines"),
        Line2D([], [], color=(1.0, 0.95, 0.75), lw=0, marker="o", ms=7, mec="0.5",
               label="heat-map: points"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=8.5, frameon=False)
    return save_png(fig, path)


# ---------------------------------------------------------------------------------------
# errors and cost history
# ---------------------------------------------------------------------------------------
def plot_errors(
    path: str | os.PathLike[str],
    *,
    timestamps: ArrayLike | None,
    initial_pos_err: ArrayLike,
    optimised_pos_err: ArrayLike,
    initial_rot_err_deg: ArrayLike,
    optimised_rot_err_deg: ArrayLike,
    causal_pos_err: ArrayLike | None = None,
    causal_rot_err_deg: ArrayLike | None = None,
) -> Path:
    """Per-keyframe position error [m] (top) and orientation error [deg] (bottom), initial
    (red) vs optimised (blue), the means in the legend; with ``causal_*`` (the tracker's
    estimate of each keyframe when it arrived) also those, in orange.

    Args:
        path: output PNG.
        timestamps: (N,) keyframe times [s] (plotted relative to the first), or None to
            plot against the keyframe index.
        initial_pos_err, optimised_pos_err: (N,) position errors [m].
        initial_rot_err_deg, optimised_rot_err_deg: (N,) orientation errors [deg].

    Returns:
        ``Path(path)``.
    """
    series = [as_series(v) for v in (initial_pos_err, optimised_pos_err, initial_rot_err_deg,
                                   optimised_rot_err_deg)]
    causal = [as_series(causal_pos_err), as_series(causal_rot_err_deg)]
    n = max(s.size for s in series)
    t = as_series(timestamps)
    if t.size >= n and n > 0 and np.all(np.isfinite(t[:n])):
        x = t - t[0]
        xlabel = "time since first keyframe [s]"
    else:
        x = np.arange(n, dtype=np.float64)
        xlabel = "keyframe"

    fig = new_figure(9.0, 6.0)
    ax_p = fig.add_subplot(2, 1, 1)
    ax_r = fig.add_subplot(2, 1, 2, sharex=ax_p)
    for ax, (ini, opt), cau, unit, ylabel in (
        (ax_p, series[:2], causal[0], "m", "position error [m]"),
        (ax_r, series[2:], causal[1], "deg", "orientation error [deg]"),
    ):
        lines = [(ini, "initial", INITIAL_COLOUR)]
        if cau.size:
            lines.append((cau, "causal (on arrival)", CAUSAL_COLOUR))
        lines.append((opt, "final" if cau.size else "optimised", OPTIMISED_COLOUR))
        for v, name, colour in lines:
            ax.plot(x[: v.size], v, color=colour, lw=1.4, marker="." if v.size <= 60 else None,
                    label=mean_label(name, v, unit))
        ax.set_ylabel(ylabel)
        ax.set_ylim(bottom=0.0)
        ax.grid(True, color="0.9", lw=0.6)
        ax.legend(loc="upper left", fontsize=8.5)
    ax_p.tick_params(labelbottom=False)
    ax_r.set_xlabel(xlabel)
    ax_p.set_title("Per-keyframe pose error: initial vs " + (
        "tracked" if causal[0].size else "optimised"), fontsize=11)
    fig.tight_layout()
    return save_png(fig, path)


def plot_cost_history(path: str | os.PathLike[str], history_costs: Sequence[float],
                      stages: Sequence[str] | None = None) -> Path:
    """The cost after each LM iteration, log y; with ``stages`` (one name per cost, e.g.
    align / match / refine) each stage in its own colour: the stages minimise different
    costs (the warm-up's correspondences, then the configured cost), so only values within
    one stage compare.

    Non-positive or non-finite costs are left out of the log plot (the y axis falls back to
    linear if nothing positive remains).

    Returns:
        ``Path(path)``.
    """
    c = as_series(list(history_costs))
    it = np.arange(c.size)
    ok = np.isfinite(c) & (c > 0)
    names = list(stages) if stages is not None else [""] * c.size
    if len(names) != c.size:
        raise ValueError(f"{c.size} costs but {len(names)} stage names")

    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    palette = [OPTIMISED_COLOUR, "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b"]
    order = list(dict.fromkeys(names))
    for k, name in enumerate(order):
        sel = ok & (np.asarray(names) == name)
        ax.plot(it[sel], c[sel], color=palette[k % len(palette)], lw=1.5, marker="o", ms=3.5,
                label=name or None)
    if stages is not None and order:
        ax.legend(loc="upper right", fontsize=9, title="stage", title_fontsize=9)
    if np.any(ok):
        ax.set_yscale("log")
        last = c[ok][-1]
        ax.set_title(f"LM cost per iteration: {c.size} iterations, final {last:.4g}"
                     + (" (each stage minimises its own cost)" if len(order) > 1 else ""),
                     fontsize=10)
    else:
        ax.set_title("LM cost (no positive values)", fontsize=11)
    ax.set_xlabel("iteration")
    ax.set_ylabel("cost")
    ax.grid(True, which="both", color="0.9", lw=0.6)
    if c.size:
        ax.set_xlim(-0.7, max(c.size - 1, 1) + 0.3)
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    return save_png(fig, path)


def plot_latency(path: str | os.PathLike[str], latency_ms: ArrayLike,
                 budget_ms: float | None = None) -> Path:
    """The tracker's update time per keyframe [ms] against the keyframe index, with the
    median, the 99th percentile and a least-squares line (its slope in the legend, in ms
    per 1000 keyframes: flat means per-keyframe work does not grow with the flight);
    ``budget_ms`` draws a limit line.

    Returns:
        ``Path(path)``.
    """
    lat = as_series(latency_ms)
    fig = new_figure(8.0, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    idx = np.arange(lat.size, dtype=np.float64)
    ok = np.isfinite(lat)
    ax.plot(idx[ok], lat[ok], ".", ms=2.5, color=OPTIMISED_COLOUR, alpha=0.6,
            label="update time")
    if np.count_nonzero(ok) >= 2:
        med = float(np.median(lat[ok]))
        p99 = float(np.percentile(lat[ok], 99))
        a, b = np.polyfit(idx[ok], lat[ok], 1)
        ax.axhline(med, color="k", lw=1.0, label=f"median {med:.1f} ms")
        ax.axhline(p99, color="0.4", lw=1.0, ls="--", label=f"99th percentile {p99:.1f} ms")
        ax.plot(idx[ok], a * idx[ok] + b, color=CAUSAL_COLOUR, lw=1.5,
                label=f"trend {a * 1000:+.2f} ms / 1000 keyframes")
    if budget_ms is not None:
        ax.axhline(budget_ms, color=INITIAL_COLOUR, lw=1.0, ls=":", label=f"{budget_ms:g} ms")
    ax.set_xlabel("keyframe")
    ax.set_ylabel("update time [ms]")
    ax.set_ylim(bottom=0.0)
    ax.grid(True, color="0.9", lw=0.6)
    ax.legend(loc="upper right", fontsize=8.5)
    ax.set_title(f"Tracker latency per keyframe ({lat.size} keyframes)", fontsize=11)
    fig.tight_layout()
    return save_png(fig, path)


def plot_pose_errors(path: str | os.PathLike[str], timestamps: ArrayLike, gt_world_T_cam: SE3,
                     *, initial: SE3, optimised: SE3, causal: SE3 | None = None) -> Path:
    """:func:`plot_errors` of poses against the ground truth ``gt_world_T_cam``: the
    ``initial`` and ``optimised`` estimates and, if given, the tracker's ``causal`` ones."""
    p0, r0 = pose_errors(initial, gt_world_T_cam)
    p1, r1 = pose_errors(optimised, gt_world_T_cam)
    pc = rc = None
    if causal is not None:
        pc, rc = pose_errors(causal, gt_world_T_cam)
    return plot_errors(path, timestamps=timestamps, initial_pos_err=p0, optimised_pos_err=p1,
                       initial_rot_err_deg=np.degrees(r0), optimised_rot_err_deg=np.degrees(r1),
                       causal_pos_err=pc,
                       causal_rot_err_deg=None if rc is None else np.degrees(rc))
