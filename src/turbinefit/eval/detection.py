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
  outboard of the true tip, measured where the hub is visible), of the detected tower
  top along the tower (positive = towards the base, where the base is visible) and of the
  detected base along the tower (positive = towards the tower top, where the tower top is
  visible); detections within ``match_px``. A negative base bias (the base detected
  below the truth) or a negative tower-top bias lengthens the tower a fit finds.
* **Tip shift** (``tip_shift_px``, a calibration, not a score): minus the mean signed
  offset along the blade of the tip peaks matched within ``shift_match_px`` (10 px, twice
  ``match_px``, so that the tips a net finds a few pixels inboard count too) on blades at
  least ``shift_min_blade_px`` (20 px) long whose hub is visible: how far the tip channel
  must move outward from the hub for its peaks to sit on the tips on average
  (:attr:`turbinefit.heatmaps.model_info.ModelInfo.tip_shift_px`). 0 from fewer than
  ``shift_min_count`` (20) matches.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from turbinefit.heatmaps.peaks import local_maxima as local_maxima
from turbinefit.heatmaps.peaks import peak as peak
from turbinefit.heatmaps.peaks import peaks as peaks
from turbinefit.heatmaps.peaks import refine as refine

POINT_NAMES3 = ("base", "tower_top", "hub")
LINE_NAMES3 = ("tower", "nacelle", "blade")


def match_points(det: NDArray[np.floating], truth: NDArray[np.floating], max_d: float
                 ) -> list[tuple[int, int, float]]:
    """Greedy one-to-one matching, nearest pairs first, of detections (n, 2) to true
    points (m, 2) within ``max_d``: (detection index, point index, distance) per pair."""
    if len(det) == 0 or len(truth) == 0:
        return []
    d = np.hypot(det[:, None, 0] - truth[None, :, 0], det[:, None, 1] - truth[None, :, 1])
    used_det: set[int] = set()
    used_truth: set[int] = set()
    pairs: list[tuple[int, int, float]] = []
    for k in np.argsort(d, axis=None, kind="stable"):
        a, b = (int(x) for x in np.unravel_index(int(k), d.shape))
        if d[a, b] > max_d:
            break
        if a in used_det or b in used_truth:
            continue
        used_det.add(a)
        used_truth.add(b)
        pairs.append((a, b, float(d[a, b])))
    return pairs


@dataclass
class DetectionStats:
    """Accumulates metrics over images; :meth:`summary` gives the figures."""

    threshold: float = 0.3
    match_px: float = 5.0
    tip_threshold: float | None = None
    nms_px: int = 7
    px_scale: float = 1.0
    short_blade_px: float = 40.0
    shift_match_px: float = 10.0
    shift_min_blade_px: float = 20.0
    shift_min_count: int = 20
    point_errors: list[list[float]] = field(default_factory=lambda: [[], [], []])
    point_visible: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    point_detected: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    point_hidden: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    point_false: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    tips_visible: int = 0
    tips_matched: int = 0
    tips_detections: int = 0
    tips_in_sight: int = 0
    tips_in_sight_matched: int = 0
    tips_short: int = 0
    tips_short_matched: int = 0
    inter: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    union: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    tip_along: list[float] = field(default_factory=list)
    tip_along_wide: list[float] = field(default_factory=list)
    top_along: list[float] = field(default_factory=list)
    base_along: list[float] = field(default_factory=list)
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
                    if c < 2 and visible[1 - c] and err <= self.match_px:  # base, top
                        (self.base_along, self.top_along)[c].append(
                            px * _along(u, v, points[c], points[1 - c] - points[c]))
            else:
                self.point_hidden[c] += 1
                self.point_false[c] += int(val > self.threshold)
        tips = points[3:6][visible[3:6]]
        tip_seen = (np.zeros(len(tips), dtype=bool) if in_sight is None
                    else np.asarray(in_sight[3:6], dtype=bool)[visible[3:6]])
        self.tips_in_sight += int(tip_seen.sum())
        tip_short = px * np.hypot(*(tips - points[2]).T) < self.short_blade_px
        self.tips_short += int(tip_short.sum())
        # sub-pixel, as the points: a blob between two grid pixels is matched where it is
        det = peaks(pred[3], self.threshold if self.tip_threshold is None
                    else self.tip_threshold, self.nms_px)
        self.tips_visible += len(tips)
        self.tips_detections += len(det)
        pairs = match_points(det, tips, self.match_px / px)
        for a, b, _ in pairs:
            if visible[2]:
                self.tip_along.append(
                    px * _along(det[a, 0], det[a, 1], tips[b], tips[b] - points[2]))
        self.tips_matched += len(pairs)
        self.tips_in_sight_matched += int(sum(tip_seen[b] for _, b, _ in pairs))
        self.tips_short_matched += int(sum(tip_short[b] for _, b, _ in pairs))
        if visible[2]:  # the tip shift: matches within the wider radius, blades long enough
            for a, b, _ in match_points(det, tips, self.shift_match_px / px):
                axis = tips[b] - points[2]
                if px * float(np.hypot(*axis)) >= self.shift_min_blade_px:
                    self.tip_along_wide.append(
                        px * _along(det[a, 0], det[a, 1], tips[b], axis))
        for k, c in enumerate((4, 5, 6)):
            _add_overlap(self.inter, self.union, k, pred[c], target[c])

    def summary(self) -> dict[str, float]:
        """Figures: ``<point>_median_px``, ``<point>_p90_px``, ``<point>_detected``,
        ``<point>_false_peak``, ``tips_recall``, ``tips_precision``,
        ``tips_recall_in_sight``, ``tips_in_sight`` (share of the visible tips in sight),
        ``tips_recall_short``, ``tips_recall_long`` (blades under / over
        ``short_blade_px``), ``tips_short`` (share of the visible tips on short blades),
        ``iou_<line>``, ``tip_bias_px``, ``tower_top_bias_px``, ``base_bias_px`` (NaN where
        undefined), ``tip_shift_px`` (0 where undefined)."""
        out: dict[str, float] = {"images": float(self.images)}
        for c, name in enumerate(POINT_NAMES3):
            e = self.point_errors[c]
            out[f"{name}_median_px"] = float(np.median(e)) if e else float("nan")
            out[f"{name}_p90_px"] = float(np.percentile(e, 90)) if e else float("nan")
            out[f"{name}_detected"] = _ratio(self.point_detected[c], self.point_visible[c])
            out[f"{name}_false_peak"] = _ratio(self.point_false[c], self.point_hidden[c])
        out["tips_recall"] = _ratio(self.tips_matched, self.tips_visible)
        out["tips_precision"] = _ratio(self.tips_matched, self.tips_detections)  # one-to-one
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
        out["base_bias_px"] = (float(np.mean(self.base_along)) if self.base_along
                               else float("nan"))
        wide = self.tip_along_wide
        out["tip_shift_px"] = (-float(np.mean(wide)) if len(wide) >= self.shift_min_count
                               else 0.0)
        return out


def _along(u: float, v: float, truth: NDArray[np.floating], axis: NDArray[np.floating]) -> float:
    """Signed error of detection (u, v) from ``truth`` along ``axis`` (any length)."""
    n = float(np.hypot(axis[0], axis[1]))
    if n < 1e-9:
        return 0.0
    return float(((u - truth[0]) * axis[0] + (v - truth[1]) * axis[1]) / n)


def _add_overlap(inter: NDArray[np.float64], union: NDArray[np.float64], k: int,
                 pred: NDArray[np.floating], target: NDArray[np.floating]) -> None:
    """Add the pixels above 0.5 in both / either of ``pred`` and ``target`` to entry k."""
    p, t = pred > 0.5, target > 0.5
    inter[k] += float(np.count_nonzero(p & t))
    union[k] += float(np.count_nonzero(p | t))


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


#: Line channels of :class:`InstanceStats` and the keypoint rows their lines join.
_LINE_ENDS = ((4, ((0, 1),)), (5, ((1, 2),)), (6, ((2, 3), (2, 4), (2, 5))))
#: The point types of :class:`InstanceStats`: name, heat-map channel, keypoint rows.
INSTANCE_POINTS = (("base", 0, (0,)), ("tower_top", 1, (1,)), ("hub", 2, (2,)),
                   ("tips", 3, (3, 4, 5)))


@dataclass
class InstanceStats:
    """Metrics of photos with any number of labelled turbines (real photos labelled as
    in :mod:`turbinefit.io.coco`), where a channel's single maximum is not the answer.

    Per point type (base, tower top, hub, tips): local maxima above the threshold, refined
    to sub-pixel, are detections; a greedy one-to-one match to the labelled points
    (visibility 1 or 2) within ``match_px`` gives recall, precision and the median error
    of the matches; ``<name>_recall_in_sight`` counts only the points labelled visible (2).
    Lines: IoU (> 0.5) against the targets drawn from the labels (a ridge between two
    labelled ends), pooled over the photos where every turbine has both ends of every
    line of that channel labelled: a line with an end out of frame has no target, so
    its pixels would count as false. Distances are in pixels of an image ``px_scale``
    times the heat-maps (see :class:`DetectionStats`).
    """

    threshold: float = 0.3
    tip_threshold: float | None = None
    match_px: float = 5.0
    nms_px: int = 7
    px_scale: float = 1.0
    labelled: NDArray[np.int64] = field(default_factory=lambda: np.zeros(4, np.int64))
    in_sight: NDArray[np.int64] = field(default_factory=lambda: np.zeros(4, np.int64))
    matched: NDArray[np.int64] = field(default_factory=lambda: np.zeros(4, np.int64))
    matched_in_sight: NDArray[np.int64] = field(default_factory=lambda: np.zeros(4, np.int64))
    detections: NDArray[np.int64] = field(default_factory=lambda: np.zeros(4, np.int64))
    errors: list[list[float]] = field(default_factory=lambda: [[], [], [], []])
    inter: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    union: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    line_photos: NDArray[np.int64] = field(default_factory=lambda: np.zeros(3, np.int64))
    photos: int = 0
    turbines: int = 0

    def add(self, pred: NDArray[np.floating], target: NDArray[np.floating],
            uv: NDArray[np.floating], visibility: NDArray[np.integer]) -> None:
        """One photo: predicted and target heat-maps (7, H, W), the labelled points
        ``uv`` (K, 6, 2) [px of the heat-map grid] of its K turbines (K may be 0) and
        their COCO ``visibility`` (K, 6) (0 not labelled, 1 occluded, 2 visible)."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 6, 2)
        vis = np.asarray(visibility).reshape(-1, 6)
        self.photos += 1
        self.turbines += len(uv)
        px = self.px_scale
        for k, (_, ch, rows) in enumerate(INSTANCE_POINTS):
            pts = uv[:, list(rows)].reshape(-1, 2)
            v = vis[:, list(rows)].reshape(-1)
            truth, seen = pts[v > 0], v[v > 0] == 2
            thr = self.threshold if ch != 3 or self.tip_threshold is None else self.tip_threshold
            det = peaks(pred[ch], thr, self.nms_px)
            pairs = match_points(det, truth, self.match_px / px)
            self.labelled[k] += len(truth)
            self.in_sight[k] += int(seen.sum())
            self.detections[k] += len(det)
            self.matched[k] += len(pairs)
            self.matched_in_sight[k] += int(sum(seen[b] for _, b, _ in pairs))
            self.errors[k].extend(px * d for _, _, d in pairs)
        for k, (c, ends) in enumerate(_LINE_ENDS):
            if not all(bool(((vis[:, a] > 0) & (vis[:, b] > 0)).all()) for a, b in ends):
                continue  # a line of this channel has no target: its pixels are unjudged
            _add_overlap(self.inter, self.union, k, pred[c], target[c])
            self.line_photos[k] += 1

    def summary(self) -> dict[str, float]:
        """``photos``, ``turbines``; per point type ``<name>_labelled``, ``<name>_recall``,
        ``<name>_recall_in_sight``, ``<name>_precision``, ``<name>_median_px``; and
        ``iou_<line>`` with ``iou_<line>_photos``, the photos it is over (NaN where
        undefined)."""
        out: dict[str, float] = {"photos": float(self.photos), "turbines": float(self.turbines)}
        for k, (name, _, _) in enumerate(INSTANCE_POINTS):
            e = self.errors[k]
            out[f"{name}_labelled"] = float(self.labelled[k])
            out[f"{name}_recall"] = _ratio(self.matched[k], self.labelled[k])
            out[f"{name}_recall_in_sight"] = _ratio(self.matched_in_sight[k], self.in_sight[k])
            out[f"{name}_precision"] = _ratio(self.matched[k], self.detections[k])
            out[f"{name}_median_px"] = float(np.median(e)) if e else float("nan")
        for k, name in enumerate(LINE_NAMES3):
            out[f"iou_{name}"] = _ratio(self.inter[k], self.union[k])
            out[f"iou_{name}_photos"] = float(self.line_photos[k])
        return out
