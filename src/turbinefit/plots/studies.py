"""Figures of the Monte Carlo studies (:mod:`turbinefit.experiments`): error scatter plots,
turbine recovery, false roll, the basin of convergence and binned medians."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from turbinefit.eval.metrics import line_fit

if TYPE_CHECKING:
    from matplotlib.axes import Axes

from turbinefit.plots.common import (
    INITIAL_COLOUR,
    OPTIMISED_COLOUR,
    FloatArray,
    as_series,
    new_figure,
    save_png,
)

# ---------------------------------------------------------------------------------------
# experiments
# ---------------------------------------------------------------------------------------
_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")


def _scatter_fit(ax: Axes, data: dict[str, tuple[FloatArray, FloatArray]], unit: str,
                 what: str) -> None:
    top = 0.0
    for k, (name, (x, y)) in enumerate(data.items()):
        x, y = as_series(x), as_series(y)
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
    fig = new_figure(12.0, 5.0)
    ax_p = fig.add_subplot(1, 2, 1)
    ax_o = fig.add_subplot(1, 2, 2)
    _scatter_fit(ax_p, {k: (np.asarray(a), np.asarray(b)) for k, (a, b) in position.items()},
                 "m", "position")
    _scatter_fit(ax_o, {k: (np.asarray(a), np.asarray(b)) for k, (a, b) in orientation.items()},
                 "deg", "orientation")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return save_png(fig, path)


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
    fig = new_figure(12.0, 5.0)
    ax = fig.add_subplot(1, 2, 1)
    _scatter_fit(ax, {"joint": (as_series(initial_m), as_series(final_m))}, "m", "model-point")
    ax2 = fig.add_subplot(1, 2, 2)
    names = list(params)
    before = [float(np.median(as_series(params[n][0]))) for n in names]
    after = [float(np.median(as_series(params[n][1]))) for n in names]
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
    return save_png(fig, path)


def plot_roll(path: str | os.PathLike[str], series: dict[str, ArrayLike]) -> Path:
    """The roll artefact (paper Fig. 7): the mean absolute camera roll error [deg] of each
    flight, one box per estimate (initial, pose-only, joint).

    Returns:
        ``Path(path)``.
    """
    fig = new_figure(6.5, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    names = list(series)
    data = [as_series(series[n]) for n in names]
    ax.boxplot(data, tick_labels=names, showmeans=True)
    ax.set_ylabel("mean |roll error| per flight [deg]")
    ax.set_ylim(bottom=0.0)
    ax.grid(True, axis="y", color="0.9", lw=0.6)
    ax.set_title("Camera roll error with a wrong blade rotation", fontsize=11)
    fig.tight_layout()
    return save_png(fig, path)


def plot_basin(path: str | os.PathLike[str], edges: ArrayLike, rate: ArrayLike,
               count: ArrayLike) -> Path:
    """Convergence basin: success rate in bins of the initial turbine-error scale (rows)
    and pose-error scale (columns), with each bin's flight count.

    Returns:
        ``Path(path)``.
    """
    e = as_series(edges)
    r = np.asarray(rate, dtype=np.float64)
    c = np.asarray(count)
    fig = new_figure(6.5, 5.2)
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
    return save_png(fig, path)


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
    fig = new_figure(4.6 * n, 4.2)
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
    return save_png(fig, path)
