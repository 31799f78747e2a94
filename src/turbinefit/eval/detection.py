"""How good are heat-maps? Detection metrics of predicted heat-maps against the truth.

Inputs per image: predicted heat-maps (7, H, W) in [0, 1], the target heat-maps (7, H, W),
the projected model points (6, 2) [px of the heat-map grid] and which of them are visible
(in front of the camera and inside the image). Distances (errors, ``match_px``, biases) are
in pixels of an image ``px_scale`` times the heat-map size: 1 (the default) for the
heat-maps' own grid, the model's output scale for the pixels of the photos it takes (a
model that reads 320 x 240 photos and gives 160 x 120 maps: ``px_scale=2``).

* **Points** (base, tower top, hub): the channel's maximum, refined to sub-pixel by a
  log-parabola through its 4-neighbourhood, is the detection if above ``threshold``.
  Error = distance to the projected point, over images where the point is visible and
  detected; ``detected`` = fraction of visible points detected; ``false_peak`` = fraction of
  images where the point is *not* visible but the channel still peaks above ``threshold``.
* **Blade tips** (one channel, up to three tips): local maxima above ``tip_threshold``
  (default ``threshold``) in a ``nms_px`` x ``nms_px`` window (7 px: +-2 sigma of the
  1.5 px targets, so that one tip's blob, flattened or ridged by the net, gives one
  detection), refined to sub-pixel as the points are, are detections; a greedy
  one-to-one match to
  visible tips within ``match_px`` gives recall (matched tips / visible tips) and
  precision (matched detections / detections). Given which points are *in sight* (not
  hidden behind the tower or a nearer blade; :func:`turbinefit.sim.images.points_in_sight`
  for renders), recall is also reported over the tips in sight: a tip hidden behind a
  blade is a guess from the rest of the turbine, not a detection. Recall is also split by
  the blade's apparent length (hub to tip, in the image): under ``short_blade_px`` (far
  turbines, blades foreshortened or seen from above: where tips are hardest to see) and
  over.
* **Lines** (tower, nacelle, blades): intersection over union of the regions above 0.5 in
  prediction and target, pooled over all images (sum of intersections / sum of unions).
* **Biases** (what a fit over many keyframes adds up, where per-image medians hide it):
  the mean signed error of matched blade tips along their blade (sub-pixel, positive =
  outboard of the true tip, measured where the hub is visible), and of the detected tower
  top along the tower (positive = towards the base, where the base is visible; detections
  within ``match_px``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

POINT_NAMES3 = ("base", "tower_top", "hub")
LINE_NAMES3 = ("tower", "nacelle", "blade")
_EPS = 1e-6


def peak(channel: NDArray[np.floating]) -> tuple[float, float, float]:
    """(u, v, value) of a channel's maximum, sub-pixel (log-parabola) where bracketed."""
    i, j = np.unravel_index(int(np.argmax(channel)), channel.shape)
    return refine(channel, int(i), int(j))


def refine(channel: NDArray[np.floating], i: int, j: int) -> tuple[float, float, float]:
    """(u, v, value) of the local maximum at row ``i``, column ``j``, sub-pixel
    (log-parabola through its 4-neighbourhood) where bracketed."""
    val = float(channel[i, j])
    u, v = float(j), float(i)
    h, w = channel.shape
    if 0 < j < w - 1:
        a, b, c = (np.log(max(float(x), _EPS)) for x in channel[i, j - 1:j + 2])
        den = a - 2 * b + c
        if den < 0:
            u += float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
    if 0 < i < h - 1:
        a, b, c = (np.log(max(float(x), _EPS)) for x in channel[i - 1:i + 2, j])
        den = a - 2 * b + c
        if den < 0:
            v += float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
    return u, v, val


def local_maxima(channel: NDArray[np.floating], threshold: float, size: int = 3
                 ) -> NDArray[np.float64]:
    """(n, 2) pixel positions (u, v) of ``size`` x ``size`` local maxima above ``threshold``."""
    mx = ndimage.maximum_filter(channel, size=size, mode="constant", cval=0.0)
    ii, jj = np.nonzero((channel >= mx) & (channel > threshold))
    return np.stack([jj, ii], axis=-1).astype(np.float64)


@dataclass
class DetectionStats:
    """Accumulates metrics over images; :meth:`summary` gives the figures."""

    threshold: float = 0.3
    match_px: float = 5.0
    tip_threshold: float | None = None
    nms_px: int = 7
    px_scale: float = 1.0
    short_blade_px: float = 40.0
    point_errors: list[list[float]] = field(default_factory=lambda: [[], [], []])
    point_visible: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    point_detected: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    point_hidden: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    point_false: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    tips_visible: int = 0
    tips_matched: int = 0
    tips_detections: int = 0
    tips_true_detections: int = 0
    tips_in_sight: int = 0
    tips_in_sight_matched: int = 0
    tips_short: int = 0
    tips_short_matched: int = 0
    inter: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    union: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    tip_along: list[float] = field(default_factory=list)
    top_along: list[float] = field(default_factory=list)
    images: int = 0

    def add(self, pred: NDArray[np.floating], target: NDArray[np.floating],
            points: NDArray[np.floating], visible: NDArray[np.bool_],
            in_sight: NDArray[np.bool_] | None = None) -> None:
        """Add one image (see the module docstring for the arguments; ``in_sight`` (6,),
        a subset of ``visible``, is optional)."""
        self.images += 1
        px = self.px_scale
        for c in range(3):
            u, v, val = peak(pred[c])
            if visible[c]:
                self.point_visible[c] += 1
                if val > self.threshold:
                    self.point_detected[c] += 1
                    err = px * float(np.hypot(u - points[c, 0], v - points[c, 1]))
                    self.point_errors[c].append(err)
                    if c == 1 and visible[0] and err <= self.match_px:
                        self.top_along.append(
                            px * _along(u, v, points[1], points[0] - points[1]))
            else:
                self.point_hidden[c] += 1
                self.point_false[c] += int(val > self.threshold)
        tips = points[3:6][visible[3:6]]
        tip_seen = (np.zeros(len(tips), dtype=bool) if in_sight is None
                    else np.asarray(in_sight[3:6], dtype=bool)[visible[3:6]])
        self.tips_in_sight += int(tip_seen.sum())
        tip_short = px * np.hypot(*(tips - points[2]).T) < self.short_blade_px
        self.tips_short += int(tip_short.sum())
        det = local_maxima(pred[3], self.threshold if self.tip_threshold is None
                           else self.tip_threshold, self.nms_px)
        # sub-pixel, as the points: a blob between two grid pixels is matched where it is
        det = np.array([refine(pred[3], int(v), int(u))[:2] for u, v in det]).reshape(-1, 2)
        self.tips_visible += len(tips)
        self.tips_detections += len(det)
        if len(tips) and len(det):
            d = px * np.hypot(det[:, None, 0] - tips[None, :, 0],
                             det[:, None, 1] - tips[None, :, 1])
            used_det: set[int] = set()
            used_tip: set[int] = set()
            for k in np.argsort(d, axis=None):
                a, b = (int(x) for x in np.unravel_index(int(k), d.shape))
                if d[a, b] > self.match_px:
                    break
                if a in used_det or b in used_tip:
                    continue
                used_det.add(a)
                used_tip.add(b)
                if visible[2]:
                    self.tip_along.append(
                        px * _along(det[a, 0], det[a, 1], tips[b], tips[b] - points[2]))
            self.tips_matched += len(used_tip)
            self.tips_in_sight_matched += int(sum(tip_seen[b] for b in used_tip))
            self.tips_short_matched += int(sum(tip_short[b] for b in used_tip))
            self.tips_true_detections += len(used_det)
        for k, c in enumerate((4, 5, 6)):
            p, t = pred[c] > 0.5, target[c] > 0.5
            self.inter[k] += float(np.count_nonzero(p & t))
            self.union[k] += float(np.count_nonzero(p | t))

    def summary(self) -> dict[str, float]:
        """Figures: ``<point>_median_px``, ``<point>_p90_px``, ``<point>_detected``,
        ``<point>_false_peak``, ``tips_recall``, ``tips_precision``,
        ``tips_recall_in_sight``, ``tips_in_sight`` (share of the visible tips in sight),
        ``tips_recall_short``, ``tips_recall_long`` (blades under / over
        ``short_blade_px``), ``tips_short`` (share of the visible tips on short blades),
        ``iou_<line>``, ``tip_bias_px``, ``tower_top_bias_px`` (NaN where undefined)."""
        out: dict[str, float] = {"images": float(self.images)}
        for c, name in enumerate(POINT_NAMES3):
            e = self.point_errors[c]
            out[f"{name}_median_px"] = float(np.median(e)) if e else float("nan")
            out[f"{name}_p90_px"] = float(np.percentile(e, 90)) if e else float("nan")
            out[f"{name}_detected"] = _ratio(self.point_detected[c], self.point_visible[c])
            out[f"{name}_false_peak"] = _ratio(self.point_false[c], self.point_hidden[c])
        out["tips_recall"] = _ratio(self.tips_matched, self.tips_visible)
        out["tips_precision"] = _ratio(self.tips_true_detections, self.tips_detections)
        out["tips_recall_in_sight"] = _ratio(self.tips_in_sight_matched, self.tips_in_sight)
        out["tips_in_sight"] = (_ratio(self.tips_in_sight, self.tips_visible)
                                if self.tips_in_sight else float("nan"))
        out["tips_recall_short"] = _ratio(self.tips_short_matched, self.tips_short)
        out["tips_recall_long"] = _ratio(self.tips_matched - self.tips_short_matched,
                                         self.tips_visible - self.tips_short)
        out["tips_short"] = _ratio(self.tips_short, self.tips_visible)
        for k, name in enumerate(LINE_NAMES3):
            out[f"iou_{name}"] = _ratio(self.inter[k], self.union[k])
        out["tip_bias_px"] = float(np.mean(self.tip_along)) if self.tip_along else float("nan")
        out["tower_top_bias_px"] = (float(np.mean(self.top_along)) if self.top_along
                                    else float("nan"))
        return out


def _along(u: float, v: float, truth: NDArray[np.floating], axis: NDArray[np.floating]) -> float:
    """Signed error of detection (u, v) from ``truth`` along ``axis`` (any length)."""
    n = float(np.hypot(axis[0], axis[1]))
    if n < 1e-9:
        return 0.0
    return float(((u - truth[0]) * axis[0] + (v - truth[1]) * axis[1]) / n)


def _ratio(a: float, b: float) -> float:
    return float(a) / float(b) if b > 0 else float("nan")


def detection_metrics(preds: Iterable[NDArray[np.floating]], targets: Iterable[NDArray[np.floating]],
                      points: Iterable[NDArray[np.floating]], visible: Iterable[NDArray[np.bool_]],
                      threshold: float = 0.3, match_px: float = 5.0,
                      tip_threshold: float | None = None) -> dict[str, float]:
    """:meth:`DetectionStats.summary` over images given as parallel iterables."""
    stats = DetectionStats(threshold=threshold, match_px=match_px, tip_threshold=tip_threshold)
    for p, t, pt, vis in zip(preds, targets, points, visible, strict=True):
        stats.add(p, t, pt, vis)
    return stats.summary()
