"""Figures: the package's only matplotlib user.

Every function writes one PNG and returns its path:

* :func:`plot_scene` -- the paper's Fig. 3 ("synth_output_figure"): turbine skeletons and
  camera trajectories in 3-D (ground truth green, initial red, optimised blue) plus a
  top-down (x-y) panel.
* :func:`plot_reprojections` -- the paper's real-data figures: a grid of keyframes, each
  showing its heat-maps with the turbine model projected from the initial (red) and the
  optimised (green) estimate.
* :func:`plot_errors` -- per-keyframe position / orientation error, initial vs optimised.
* :func:`plot_cost_history` -- the LM cost per iteration (log scale).
* :func:`plot_latency` -- the tracker's per-keyframe update time.

Conventions: poses are ``world_T_cam`` (camera-to-world) :class:`~turbinefit.geometry.se3.SE3`
batches, the camera frame is OpenCV (x right, y down, z forward), world units are metres.

The functions draw on a bare :class:`matplotlib.figure.Figure` with the Agg canvas (no
pyplot, no global figure registry, works headless), import matplotlib only when called (so
``import turbinefit`` stays fast), create missing parent directories, and write atomically
(``<name>.tmp.png`` then :func:`os.replace`). Empty inputs or a turbine out of view give a
sparse figure, never an exception.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.errors import InputError
from turbinefit.eval.metrics import line_fit
from turbinefit.geometry.camera import MIN_DEPTH, PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.turbine.model import (
    LINES,
    PAPER_GEOMETRY,
    TurbineGeometry,
    TurbineParams,
    model_points,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]

#: Resolution of every PNG [dots per inch].
DPI = 150
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
_MAX_PIXEL = 1e5


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------
def _new_figure(width: float, height: float) -> Figure:
    """A figure not registered with pyplot, on the Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path: str | os.PathLike[str]) -> Path:
    """Write ``fig`` to ``path`` as PNG atomically, then release the figure."""
    out = Path(path)
    if not out.parent.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp.png")
    try:
        fig.savefig(tmp, format="png", dpi=DPI)
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
        fig.clear()
    return out


def _as_batch(poses: SE3 | None) -> SE3:
    """Poses as a flat batch (N, 7) (N may be 0)."""
    if poses is None:
        return SE3(np.zeros((0, 7)))
    return SE3(np.asarray(poses.wxyz_xyz, dtype=np.float64).reshape(-1, 7))


def _skeleton(turbine: TurbineParams, geometry: TurbineGeometry) -> FloatArray:
    """The six model points (6, 3) [m] of a turbine."""
    pts, _ = model_points(turbine.to_vector(), geometry)
    return pts


def _line_polyline(points: FloatArray, n: int = LINE_SAMPLES) -> FloatArray:
    """All model lines sampled densely, as one polyline (5 * (n + 1), 3) with NaN breaks."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    parts = []
    for a, b, _ in LINES:
        parts.append(points[a] * (1.0 - s) + points[b] * s)
        parts.append(np.full((1, 3), np.nan))
    return np.concatenate(parts, axis=0)


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


def _finite_rows(a: FloatArray) -> FloatArray:
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
        sets.append(("ground truth", GT_COLOUR, _as_batch(gt_poses), gt_turbine))
    sets.append(("initial", INITIAL_COLOUR, _as_batch(initial_poses), initial_turbine))
    sets.append(("optimised", OPTIMISED_COLOUR, _as_batch(optimised_poses), optimised_turbine))

    skeletons = {name: _skeleton(t, geometry) for name, _, _, t in sets if t is not None}
    positions = {name: p.translation.reshape(-1, 3) for name, _, p, _ in sets}

    # scene extent -> frustum size and equal-scaled limits
    everything = np.concatenate(
        [_finite_rows(x) for x in (*skeletons.values(), *positions.values())] + [np.zeros((0, 3))]
    )
    if everything.shape[0] == 0:
        everything = np.zeros((1, 3))
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    extent = float(max(np.max(hi - lo), 1.0))
    frustum_size = 0.045 * extent

    fig = _new_figure(15.0, 7.5)
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
            poly = _line_polyline(sk, 2)
            ax3.plot(poly[:, 0], poly[:, 1], poly[:, 2], color=colour, lw=2.6,
                     solid_capstyle="round")
            ax3.scatter(sk[:, 0], sk[:, 1], sk[:, 2], color=colour, s=14, depthshade=False)
            ax2.plot(poly[:, 0], poly[:, 1], color=colour, lw=2.6, solid_capstyle="round")
            ax2.plot(sk[:, 0], sk[:, 1], "o", color=colour, ms=3.5)
            ax2.plot(sk[0, 0], sk[0, 1], "s", color=colour, ms=7, mfc="none", mew=1.5)

    # equal axis scaling in 3-D: limits padded around the data, box aspect = data ranges
    allp = np.concatenate([everything, *[_finite_rows(f) for f in frusta_pts]])
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
    return _save(fig, path)


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


def _project_skeleton(
    camera: PinholeCamera, world_T_cam: SE3, points: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Pixels of the densely sampled model lines (M, 2; NaN where not drawable: behind the
    camera, beyond the trusted distortion range) and of the six model points (6, 2; NaN
    likewise). Out-of-image pixels are kept: the axes clip them at the border."""
    cam_T_world = world_T_cam.inverse()
    out = []
    for world_p in (_line_polyline(points), points):
        finite = np.all(np.isfinite(world_p), axis=1)
        cam_p = cam_T_world @ np.where(finite[:, None], world_p, 0.0)
        uv, front, _ = camera.project_unbounded(cam_p)
        ok = finite & front & (cam_p[:, 2] > MIN_DEPTH) & np.all(np.abs(uv) < _MAX_PIXEL, axis=1)
        out.append(np.where(ok[:, None], uv, np.nan))
    return out[0], out[1]


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
) -> Path:
    """The turbine model projected over the heat-maps of chosen keyframes.

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

    Returns:
        ``Path(path)``.

    Raises:
        InputError: a keyframe index outside the heat-maps or the pose batches.
    """
    from matplotlib.lines import Line2D

    init = _as_batch(initial_poses)
    opt = _as_batch(optimised_poses)
    kfs = [int(k) for k in keyframes]
    n_avail = min(len(heatmaps), len(init), len(opt))
    bad = [k for k in kfs if not 0 <= k < n_avail]
    if bad:
        raise InputError(f"keyframe index {bad[0]} out of range 0..{n_avail - 1} "
                         f"({len(heatmaps)} heat-maps, {len(init)} initial and {len(opt)} "
                         "optimised poses)", field="keyframes")
    times = None if timestamps is None else np.asarray(timestamps, dtype=np.float64).ravel()

    skeletons = (
        ("initial", REPROJ_INITIAL_COLOUR, init, _skeleton(initial_turbine, geometry)),
        ("optimised", REPROJ_OPTIMISED_COLOUR, opt, _skeleton(optimised_turbine, geometry)),
    )
    W, H = camera.width, camera.height
    rows, cols = _grid(len(kfs))
    panel_w = 4.2
    panel_h = panel_w * H / W + 0.45
    fig = _new_figure(cols * panel_w, rows * panel_h + 0.5)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.5 / (rows * panel_h + 0.5) + 0.01,
                        top=1.0 - 0.3 / (rows * panel_h + 0.5), wspace=0.04, hspace=0.14)
    axes: list[Axes] = [fig.add_subplot(rows, cols, i + 1) for i in range(rows * cols)]

    for ax in axes[len(kfs):]:
        ax.set_axis_off()
    if not kfs:
        axes[0].text(0.5, 0.5, "no keyframes", ha="center", va="center",
                     transform=axes[0].transAxes, color="0.4")

    for ax, k in zip(axes, kfs, strict=False):
        ax.imshow(_heatmap_composite(heatmaps[k]), extent=(-0.5, W - 0.5, H - 0.5, -0.5),
                  interpolation="bilinear")
        for _, colour, poses, sk in skeletons:
            lines_uv, points_uv = _project_skeleton(camera, poses[k], sk)
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
    return _save(fig, path)


# ---------------------------------------------------------------------------------------
# errors and cost history
# ---------------------------------------------------------------------------------------
def _series(values: ArrayLike | None) -> FloatArray:
    if values is None:
        return np.zeros(0)
    return np.asarray(values, dtype=np.float64).ravel()


def _mean_label(name: str, v: FloatArray, unit: str) -> str:
    finite = v[np.isfinite(v)]
    return f"{name} (mean {np.mean(finite):.3g} {unit})" if finite.size else name


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
    series = [_series(v) for v in (initial_pos_err, optimised_pos_err, initial_rot_err_deg,
                                   optimised_rot_err_deg)]
    causal = [_series(causal_pos_err), _series(causal_rot_err_deg)]
    n = max(s.size for s in series)
    t = _series(timestamps)
    if t.size >= n and n > 0 and np.all(np.isfinite(t[:n])):
        x = t - t[0]
        xlabel = "time since first keyframe [s]"
    else:
        x = np.arange(n, dtype=np.float64)
        xlabel = "keyframe"

    fig = _new_figure(9.0, 6.0)
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
                    label=_mean_label(name, v, unit))
        ax.set_ylabel(ylabel)
        ax.set_ylim(bottom=0.0)
        ax.grid(True, color="0.9", lw=0.6)
        ax.legend(loc="upper left", fontsize=8.5)
    ax_p.tick_params(labelbottom=False)
    ax_r.set_xlabel(xlabel)
    ax_p.set_title("Per-keyframe pose error: initial vs " + (
        "tracked" if causal[0].size else "optimised"), fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


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
    c = _series(list(history_costs))
    it = np.arange(c.size)
    ok = np.isfinite(c) & (c > 0)
    names = list(stages) if stages is not None else [""] * c.size
    if len(names) != c.size:
        raise ValueError(f"{c.size} costs but {len(names)} stage names")

    fig = _new_figure(7.0, 4.2)
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
    return _save(fig, path)


def plot_latency(path: str | os.PathLike[str], latency_ms: ArrayLike,
                 budget_ms: float | None = None) -> Path:
    """The tracker's update time per keyframe [ms] against the keyframe index, with the
    median, the 99th percentile and a least-squares line (its slope in the legend, in ms
    per 1000 keyframes: flat means per-keyframe work does not grow with the flight);
    ``budget_ms`` draws a limit line.

    Returns:
        ``Path(path)``.
    """
    lat = _series(latency_ms)
    fig = _new_figure(8.0, 4.2)
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
    return _save(fig, path)


# ---------------------------------------------------------------------------------------
# experiments
# ---------------------------------------------------------------------------------------
_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")


def _scatter_fit(ax: Axes, data: dict[str, tuple[FloatArray, FloatArray]], unit: str,
                 what: str) -> None:
    top = 0.0
    for k, (name, (x, y)) in enumerate(data.items()):
        x, y = _series(x), _series(y)
        ok = np.isfinite(x) & np.isfinite(y)
        colour = _PALETTE[k % len(_PALETTE)]
        ax.plot(x[ok], y[ok], "o", ms=3.0, alpha=0.45, color=colour, mec="none")
        label = name
        a, b = line_fit(x[ok], y[ok])
        if np.isfinite(a):
            xs = np.array([x[ok].min(), x[ok].max()])
            ax.plot(xs, a * xs + b, color=colour, lw=1.8)
            label = f"{name}: y = {a:.3f} x {'+' if b >= 0 else '-'} {abs(b):.3f}"
        ax.plot([], [], "o-", color=colour, label=label)
        if ok.any():
            top = max(top, float(np.percentile(y[ok], 99)))
    ax.set_xlabel(f"initial mean {what} error [{unit}]")
    ax.set_ylabel(f"final mean {what} error [{unit}]")
    ax.set_xlim(left=0.0)
    ax.set_ylim(0.0, top * 1.1 if top > 0 else 1.0)
    ax.grid(True, color="0.9", lw=0.6)
    ax.legend(loc="upper left", fontsize=7.5)


def plot_error_scatter(path: str | os.PathLike[str],
                       position: dict[str, tuple[ArrayLike, ArrayLike]],
                       orientation: dict[str, tuple[ArrayLike, ArrayLike]],
                       title: str = "") -> Path:
    """The paper's Figs. 4 and 5: per flight, initial against final mean position error
    [m] (left) and orientation error [deg] (right), one colour per configuration, each with
    its least-squares line (in the legend). The y axis stops at the 99th percentile.

    Returns:
        ``Path(path)``.
    """
    fig = _new_figure(12.0, 5.0)
    ax_p = fig.add_subplot(1, 2, 1)
    ax_o = fig.add_subplot(1, 2, 2)
    _scatter_fit(ax_p, {k: (np.asarray(a), np.asarray(b)) for k, (a, b) in position.items()},
                 "m", "position")
    _scatter_fit(ax_o, {k: (np.asarray(a), np.asarray(b)) for k, (a, b) in orientation.items()},
                 "deg", "orientation")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def plot_turbine_recovery(path: str | os.PathLike[str], initial_m: ArrayLike,
                          final_m: ArrayLike,
                          params: dict[str, tuple[ArrayLike, ArrayLike]]) -> Path:
    """The paper's Fig. 6: initial against optimised mean 3-D error of the six model
    points per flight (left, with the least-squares line), and the median absolute error
    of each turbine parameter before and after (right, log scale; metres or degrees as the
    names say).

    Returns:
        ``Path(path)``.
    """
    fig = _new_figure(12.0, 5.0)
    ax = fig.add_subplot(1, 2, 1)
    _scatter_fit(ax, {"joint": (_series(initial_m), _series(final_m))}, "m", "model-point")
    ax2 = fig.add_subplot(1, 2, 2)
    names = list(params)
    before = [float(np.median(_series(params[n][0]))) for n in names]
    after = [float(np.median(_series(params[n][1]))) for n in names]
    x = np.arange(len(names))
    ax2.bar(x - 0.2, before, 0.4, color=INITIAL_COLOUR, label="initial")
    ax2.bar(x + 0.2, after, 0.4, color=OPTIMISED_COLOUR, label="optimised")
    ax2.set_xticks(x, names, rotation=30, ha="right", fontsize=8)
    if all(v > 0 for v in before + after):
        ax2.set_yscale("log")
    ax2.set_ylabel("median absolute error (m or deg)")
    ax2.grid(True, axis="y", color="0.9", lw=0.6)
    ax2.legend(fontsize=8.5)
    fig.tight_layout()
    return _save(fig, path)


def plot_roll(path: str | os.PathLike[str], series: dict[str, ArrayLike]) -> Path:
    """The roll artefact (paper Fig. 7): the mean absolute camera roll error [deg] of each
    flight, one box per estimate (initial, pose-only, joint).

    Returns:
        ``Path(path)``.
    """
    fig = _new_figure(6.5, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    names = list(series)
    data = [_series(series[n]) for n in names]
    ax.boxplot(data, tick_labels=names, showmeans=True)
    ax.set_ylabel("mean |roll error| per flight [deg]")
    ax.set_ylim(bottom=0.0)
    ax.grid(True, axis="y", color="0.9", lw=0.6)
    ax.set_title("Camera roll error with a wrong blade rotation", fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def plot_basin(path: str | os.PathLike[str], edges: ArrayLike, rate: ArrayLike,
               count: ArrayLike) -> Path:
    """Convergence basin: success rate in bins of the initial turbine-error scale (rows)
    and pose-error scale (columns), with each bin's flight count.

    Returns:
        ``Path(path)``.
    """
    e = _series(edges)
    r = np.asarray(rate, dtype=np.float64)
    c = np.asarray(count)
    fig = _new_figure(6.5, 5.2)
    ax = fig.add_subplot(1, 1, 1)
    im = ax.pcolormesh(e, e, np.ma.masked_invalid(r), vmin=0.0, vmax=1.0, cmap="RdYlGn")
    for i in range(r.shape[0]):
        for j in range(r.shape[1]):
            if c[i, j]:
                ax.text(0.5 * (e[j] + e[j + 1]), 0.5 * (e[i] + e[i + 1]),
                        f"{100 * r[i, j]:.0f}%\n(n={c[i, j]})", ha="center", va="center",
                        fontsize=7)
    ax.set_xlabel("initial pose error (x default drift)")
    ax.set_ylabel("initial turbine error (x default sigmas)")
    fig.colorbar(im, ax=ax, label="success rate")
    ax.set_title("Convergence basin", fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def plot_binned(path: str | os.PathLike[str],
                panels: Sequence[tuple[str, Sequence[str], dict[str, Sequence[float | None]]]],
                ylabel: str) -> Path:
    """One panel per factor: a binned statistic (e.g. the median final error) per
    configuration against the factor's bins. ``panels`` are (x label, bin labels,
    {configuration: one value per bin, None where the bin is empty}).

    Returns:
        ``Path(path)``.
    """
    n = max(len(panels), 1)
    fig = _new_figure(4.6 * n, 4.2)
    for k, (label, ticks, series) in enumerate(panels):
        ax = fig.add_subplot(1, n, k + 1)
        x = np.arange(len(ticks))
        for j, (name, values) in enumerate(series.items()):
            v = np.array([np.nan if y is None else y for y in values], dtype=np.float64)
            ax.plot(x, v, "o-", color=_PALETTE[j % len(_PALETTE)], label=name)
        ax.set_xticks(x, list(ticks))
        ax.set_xlabel(label)
        if k == 0:
            ax.set_ylabel(ylabel)
        ax.set_ylim(bottom=0.0)
        ax.grid(True, color="0.9", lw=0.6)
        ax.legend(fontsize=7.5)
    fig.tight_layout()
    return _save(fig, path)
