"""How good are heat-maps on photos labelled only with boxes or masks?

Real photos rarely come with keypoints; the labels users have are boxes (one per turbine
or blade) and masks. This module scores a photo's heat-maps (7, h, w) against such a
region, a boolean (h, w) on the maps' own grid (:func:`box_region`, :func:`mask_region`):

* **line mass inside** (``line_mass_inside``): the share of the three line channels' summed
  values that falls inside the region. 1 for maps that answer only on the turbine, 0 for
  maps that answer only on the background; undefined (NaN) for maps with no mass at all.
* **skeleton covered** (``skeleton_covered``, masks only): the share of the mask's
  skeleton (:func:`skeleton`, one pixel wide, on the maps' grid) that lies within one map
  pixel of a line response above the threshold: whether the lines follow the whole part,
  not only a piece of it.
* **found** (``found``): whether any channel's maximum is above the model's threshold.
* **peaks outside** (``peaks_outside`` of ``peaks``): local maxima of the four point
  channels above their thresholds (the tips' own for the tip channel) that fall outside
  the region.
* **bottom rows** (:func:`bottom_rows`): the mean of the line channels' per-pixel maximum
  over the maps' bottom rows against that over the whole map: an artefact at the border
  shows as a bottom mean several times the whole map's.

:class:`RegionStats` gathers the per-photo figures and summarises them per class and
overall (means over the photos where each figure is defined) and names the worst photos.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from matplotlib.path import Path as Outline  # imported here, not in the detector threads
from numpy.typing import NDArray
from scipy import ndimage

from turbinefit.heatmaps import CHANNEL_NAMES
from turbinefit.heatmaps.peaks import local_maxima

LINE_CHANNELS = tuple(i for i, n in enumerate(CHANNEL_NAMES) if n.startswith("line_"))
POINT_CHANNELS = tuple(i for i, n in enumerate(CHANNEL_NAMES) if n.startswith("point_"))
TIP_CHANNEL = CHANNEL_NAMES.index("point_blade_tip")
#: Boxes are grown by this share of their width (left and right) and height (top and
#: bottom) on each side before scoring: a box drawn tightly round a blade leaves out the
#: edges of the net's ridge, which is a few pixels wide.
DEFAULT_GROW = 0.05

Box = tuple[float, float, float, float]  # left, top, right, bottom [px, pixel edges]
BoolMap = NDArray[np.bool_]


def grow_box(box: Box, grow: float, width: int, height: int) -> Box:
    """``box`` (left, top, right, bottom; pixel edges: 0 is the left edge of the first
    pixel) with each side moved out by ``grow`` times the box's width (left, right) or
    height (top, bottom), clipped to a ``width`` x ``height`` photo."""
    x0, y0, x1, y1 = box
    gx, gy = grow * (x1 - x0), grow * (y1 - y0)
    return max(x0 - gx, 0.0), max(y0 - gy, 0.0), min(x1 + gx, width), min(y1 + gy, height)


def box_region(boxes: list[Box], photo_size: tuple[int, int], map_size: tuple[int, int]
               ) -> BoolMap:
    """(h, w) boolean map of the map pixels whose centres lie inside any of ``boxes``
    (photo px, pixel edges) of a photo of ``photo_size`` (W, H); ``map_size`` = (w, h)."""
    (pw, ph), (w, h) = photo_size, map_size
    u = (np.arange(w) + 0.5) * (pw / w)  # map pixel centres in photo px, pixel edges
    v = (np.arange(h) + 0.5) * (ph / h)
    out = np.zeros((h, w), dtype=bool)
    for x0, y0, x1, y1 in boxes:
        out |= ((v >= y0) & (v <= y1))[:, None] & ((u >= x0) & (u <= x1))[None, :]
    return out


def mask_region(mask: NDArray[np.bool_], map_size: tuple[int, int]) -> BoolMap:
    """(h, w) boolean map of the map pixels at least half covered by ``mask`` (a
    photo-sized boolean (H, W)); ``map_size`` = (w, h)."""
    from PIL import Image

    w, h = map_size
    if mask.shape == (h, w):
        return mask.astype(bool)
    im = Image.fromarray(mask.astype(np.float32), mode="F")
    return np.asarray(im.resize((w, h), Image.Resampling.BOX)) >= 0.5


def polygon_region(polygons: list[tuple[float, ...]], photo_size: tuple[int, int],
                   map_size: tuple[int, int], samples: int = 4) -> BoolMap:
    """(h, w) boolean map of the map pixels at least half covered by any of ``polygons``
    ((x1, y1, x2, y2, ...) in photo px, pixel edges) of a photo of ``photo_size`` (W, H),
    as :func:`mask_region` treats a mask; coverage is counted on ``samples`` x ``samples``
    points a map pixel (matplotlib's point-in-polygon test)."""
    (pw, ph), (w, h) = photo_size, map_size
    u = (np.arange(w * samples) + 0.5) * (pw / (w * samples))
    v = (np.arange(h * samples) + 0.5) * (ph / (h * samples))
    points = np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)
    inside = np.zeros(len(points), dtype=bool)
    for xy in polygons:
        inside |= Outline(np.reshape(np.asarray(xy, dtype=np.float64), (-1, 2))).contains_points(points)
    cover = inside.reshape(h, samples, w, samples).mean(axis=(1, 3))
    return cover >= 0.5


def skeleton(region: BoolMap) -> BoolMap:
    """One-pixel-wide skeleton of a boolean region (Zhang and Suen's thinning, 1984:
    boundary pixels are peeled in two alternating sub-iterations, each removing those
    with 2-6 set 8-neighbours, one 0-to-1 transition round them and the sub-iteration's
    pair of neighbour conditions, until nothing changes). scikit-image's
    ``skeletonize`` does the same; it is not a dependency of turbinefit."""
    img = np.pad(region.astype(np.uint8), 1)
    while True:
        changed = False
        for step in (0, 1):
            p = img
            # neighbours P2..P9 clockwise from north
            n = [p[:-2, 1:-1], p[:-2, 2:], p[1:-1, 2:], p[2:, 2:],
                 p[2:, 1:-1], p[2:, :-2], p[1:-1, :-2], p[:-2, :-2]]
            b = sum(x.astype(np.int32) for x in n)
            a = sum(((n[k] == 0) & (n[(k + 1) % 8] == 1)).astype(np.int32) for k in range(8))
            if step == 0:
                c1, c2 = n[0] * n[2] * n[4], n[2] * n[4] * n[6]
            else:
                c1, c2 = n[0] * n[2] * n[6], n[0] * n[4] * n[6]
            kill = (p[1:-1, 1:-1] == 1) & (b >= 2) & (b <= 6) & (a == 1) & (c1 == 0) & (c2 == 0)
            if kill.any():
                img = img.copy()
                img[1:-1, 1:-1][kill] = 0
                changed = True
        if not changed:
            return img[1:-1, 1:-1].astype(bool)


def line_mass_inside(maps: NDArray[np.floating], region: BoolMap) -> float:
    """Share of the line channels' summed values inside ``region`` (NaN if none)."""
    lines = maps[list(LINE_CHANNELS)].astype(np.float64).sum(axis=0)
    total = float(lines.sum())
    return float(lines[region].sum()) / total if total > 0 else math.nan


def skeleton_covered(maps: NDArray[np.floating], region: BoolMap, threshold: float) -> float:
    """Share of ``region``'s :func:`skeleton` within one map pixel of a line response
    above ``threshold`` (NaN for an empty region)."""
    skel = skeleton(region)
    if not skel.any():
        return math.nan
    on = maps[list(LINE_CHANNELS)].max(axis=0) > threshold
    near = ndimage.binary_dilation(on, structure=np.ones((3, 3), dtype=bool))
    return float(near[skel].mean())


def point_peaks(maps: NDArray[np.floating], threshold: float, tip_threshold: float
                ) -> NDArray[np.float64]:
    """(n, 2) integer positions (u, v) of the point channels' 7x7 local maxima above
    ``threshold`` (``tip_threshold`` for the blade tips)."""
    found = [local_maxima(maps[c], tip_threshold if c == TIP_CHANNEL else threshold, 7)
             for c in POINT_CHANNELS]
    return np.concatenate(found).reshape(-1, 2)


def could_be_evidence(maps: NDArray[np.floating], threshold: float) -> bool:
    """Whether a fit could count these maps (7, h, w) as a keyframe with heat-map
    evidence (:mod:`turbinefit.solver.verdict`): some channel reaches ``threshold`` (the
    fit's ``corr_threshold``: a correspondence can be found there) and no channel is at or
    above it over more than :data:`~turbinefit.solver.verdict.MAX_EVIDENCE_AREA` of the
    map. Whether it does also depends on where the model projects: the share of a
    flight's photos whose maps could is an upper bound of its evidence share."""
    from turbinefit.solver.verdict import MAX_EVIDENCE_AREA

    high = maps >= threshold
    return bool(high.any()) and float(high.mean(axis=(1, 2)).max()) <= MAX_EVIDENCE_AREA


def bottom_rows(maps: NDArray[np.floating], rows: int) -> tuple[float, float]:
    """(mean over the bottom ``rows`` rows, mean over the whole map) of the line
    channels' per-pixel maximum."""
    lines = maps[list(LINE_CHANNELS)].max(axis=0)
    return float(lines[-max(rows, 1):].mean()), float(lines.mean())


@dataclass
class PhotoScore:
    """One photo's figures (see the module docstring); NaN where undefined."""

    name: str
    classes: tuple[str, ...]
    line_mass_inside: float
    skeleton_covered: float
    found: bool
    peaks: int
    peaks_outside: int


@dataclass
class RegionStats:
    """Per-photo figures of heat-maps against boxes or masks, summarised per class.

    ``threshold`` and ``tip_threshold``: the model's (a line response, a detection)."""

    threshold: float
    tip_threshold: float
    photos: list[PhotoScore] = field(default_factory=list)

    def add(self, name: str, classes: tuple[str, ...], maps: NDArray[np.floating],
            region: BoolMap, mask: bool = False) -> PhotoScore:
        """Score one photo's maps (7, h, w) against its ``region`` (h, w) (boxes, or a
        mask with ``mask``: then the skeleton is scored too) and keep the figures. A photo
        with an empty region is a negative: only ``found`` and its peaks count."""
        pk = point_peaks(maps, self.threshold, self.tip_threshold)
        inside = region[pk[:, 1].astype(int), pk[:, 0].astype(int)] if len(pk) else pk[:, 0] > 0
        has = bool(region.any())
        score = PhotoScore(
            name, classes,
            line_mass_inside(maps, region) if has else math.nan,
            skeleton_covered(maps, region, self.threshold) if has and mask else math.nan,
            bool(maps.max() > self.threshold), len(pk), int((~inside).sum()))
        self.photos.append(score)
        return score

    @staticmethod
    def _figures(photos: list[PhotoScore]) -> dict[str, float]:
        def mean(vals: list[float]) -> float:
            ok = [v for v in vals if not math.isnan(v)]
            return float(np.mean(ok)) if ok else math.nan

        peaks = sum(p.peaks for p in photos)
        return {
            "photos": float(len(photos)),
            "line_mass_inside": mean([p.line_mass_inside for p in photos]),
            "skeleton_covered": mean([p.skeleton_covered for p in photos]),
            "found": mean([float(p.found) for p in photos]),
            "peaks": float(peaks),
            "peaks_outside": float(sum(p.peaks_outside for p in photos)),
            "peaks_outside_share": (sum(p.peaks_outside for p in photos) / peaks
                                    if peaks else math.nan),
        }

    def summary(self) -> dict[str, dict[str, float]]:
        """``{"overall": figures, "<class>": figures, ...}``: per class over the photos
        with a region of that class (a photo of several classes counts in each), means of
        the per-photo figures where defined; ``found`` is the share of photos."""
        out = {"overall": self._figures(self.photos)}
        for c in sorted({c for p in self.photos for c in p.classes}):
            out[c] = self._figures([p for p in self.photos if c in p.classes])
        return out

    def worst(self, n: int) -> list[int]:
        """Indices of the ``n`` photos with the least line mass inside their regions
        (photos where nothing was found first, negatives last)."""
        def key(k: int) -> tuple[int, float]:
            p = self.photos[k]
            if math.isnan(p.line_mass_inside):
                return (0 if p.classes else 2, 0.0)
            return (0 if not p.found else 1, p.line_mass_inside)
        return sorted(range(len(self.photos)), key=key)[:n]
