"""Detection metrics (turbinefit.eval.detection): sub-pixel peaks, counts, biases, tip
shift, recall; per-turbine instance statistics; perfect maps of rendered samples."""

from __future__ import annotations

import numpy as np
import pytest

from turbinefit.eval.detection import DetectionStats, InstanceStats, peak
from turbinefit.heatmaps.targets import render_keypoint_heatmaps


def test_detection_metrics_of_perfect_maps(held_out_samples: list) -> None:
    st = DetectionStats(threshold=0.5)
    for s in held_out_samples:
        st.add(s.target, s.target, s.points, s.visible)
    m = st.summary()
    assert m["hub_median_px"] < 0.3 and m["hub_detected"] == 1.0
    assert m["iou_tower"] == pytest.approx(1.0)
    assert m["tips_precision"] == pytest.approx(1.0) or np.isnan(m["tips_precision"])


def _maps(uv: np.ndarray, lab: np.ndarray) -> np.ndarray:
    return render_keypoint_heatmaps(60, 80, [uv], [lab], sigma_px=1.5)


#: An upright turbine's six projected points (base, tower top, hub, three tips) [px].
_TURBINE_UV = np.array([[40, 55], [40, 15], [44, 15], [44, 3], [34, 21], [54, 21]], float)


def _tips_inboard(uv: np.ndarray, px: float) -> np.ndarray:
    """``uv`` with the three tips moved ``px`` towards the hub."""
    moved = uv.copy()
    for i in (3, 4, 5):
        d = uv[2] - uv[i]
        moved[i] += px * d / np.hypot(*d)
    return moved


def test_peak_is_sub_pixel() -> None:
    uv = np.array([[20.3, 30.6]] * 6)
    m = _maps(uv, np.array([True] + [False] * 5))
    u, v, val = peak(m[0])
    assert abs(u - 20.3) < 0.05 and abs(v - 30.6) < 0.05 and val > 0.8


def test_counts() -> None:
    uv = np.array([[10, 10], [10, 40], [30, 40], [50, 20], [60, 50], [5, 55]], float)
    vis = np.array([True, True, False, True, True, True])
    target = _maps(uv, vis)
    pred = target.copy()
    # the hub (out of view) is "seen" anyway: a false peak; tip 3 is missed, one extra tip
    pred[2] = _maps(np.array([[40.0, 30.0]] * 6), np.array([False, False, True, False, False, False]))[2]
    extra = uv.copy()
    extra[5] = (70, 10)
    pred[3] = _maps(extra, np.array([False, False, False, True, True, True]))[3]
    pred[3][np.abs(np.arange(80) - 5)[None, :] + np.abs(np.arange(60) - 55)[:, None] < 6] = 0
    pred[3] = np.maximum(pred[3], _maps(uv, np.array([False] * 3 + [True, True, False]))[3])
    st = DetectionStats(threshold=0.5)
    st.add(pred, target, uv, vis)
    m = st.summary()
    assert m["base_median_px"] < 0.1 and m["base_detected"] == 1.0
    assert m["hub_false_peak"] == 1.0 and np.isnan(m["hub_median_px"])
    assert m["tips_recall"] == pytest.approx(2 / 3)
    assert m["tips_precision"] == pytest.approx(2 / 3)
    assert m["iou_tower"] == pytest.approx(1.0)


def test_biases_are_signed_along_the_blade_and_the_tower() -> None:
    """Tips drawn 1 px inboard, the tower top 0.5 px towards the base and the base 0.25 px
    below the truth (away from the top) give -1, +0.5 and -0.25."""
    uv = _TURBINE_UV
    vis = np.ones(6, bool)
    target = _maps(uv, vis)
    moved = _tips_inboard(uv, 1.0)
    moved[1, 1] += 0.5
    moved[0, 1] += 0.25
    pred = _maps(moved, vis)
    st = DetectionStats(threshold=0.5)
    st.add(pred, target, uv, vis)
    m = st.summary()
    assert m["tip_bias_px"] == pytest.approx(-1.0, abs=0.05)
    assert m["tower_top_bias_px"] == pytest.approx(0.5, abs=0.05)
    assert m["base_bias_px"] == pytest.approx(-0.25, abs=0.05)
    assert m["tips_recall"] == 1.0


def test_biases_are_nan_without_matches() -> None:
    st = DetectionStats()
    st.add(np.zeros((7, 60, 80)), np.zeros((7, 60, 80)), np.zeros((6, 2)), np.zeros(6, bool))
    m = st.summary()
    assert np.isnan(m["tip_bias_px"]) and np.isnan(m["tower_top_bias_px"])
    assert np.isnan(m["base_bias_px"])


def test_px_scale_reports_distances_in_input_pixels() -> None:
    """Maps 3 px (grid) off: at px_scale 2 errors and biases double, and the 5 px match
    radius is in input pixels, so tips 6 input px away no longer match."""
    uv = _TURBINE_UV
    vis = np.ones(6, bool)
    target = _maps(uv, vis)
    moved = _tips_inboard(uv, 3.0)
    moved[0, 0] += 1.0
    pred = _maps(moved, vis)
    grid, photo = DetectionStats(threshold=0.5), DetectionStats(threshold=0.5, px_scale=2.0)
    for st in (grid, photo):
        st.add(pred, target, uv, vis)
    g, p = grid.summary(), photo.summary()
    assert g["base_median_px"] == pytest.approx(1.0, abs=0.05)
    assert p["base_median_px"] == pytest.approx(2.0, abs=0.1)
    assert g["tips_recall"] == 1.0 and g["tip_bias_px"] == pytest.approx(-3.0, abs=0.1)
    assert p["tips_recall"] == 0.0 and p["tips_precision"] == 0.0


def test_tip_shift_is_the_mean_inboard_offset_of_tips_within_10_px() -> None:
    """Tips 3 grid px inboard at px_scale 2 are 6 input px off: beyond the 5 px match
    (recall 0) but within the 10 px calibration radius, so the shift is +6 px; it is 0
    from fewer than 20 matches and leaves blades under 20 px out (the grid's 12 px)."""
    uv = _TURBINE_UV
    vis = np.ones(6, bool)
    target = _maps(uv, vis)
    pred = _maps(_tips_inboard(uv, 3.0), vis)
    photo, few, grid = (DetectionStats(threshold=0.5, px_scale=2.0),
                        DetectionStats(threshold=0.5, px_scale=2.0), DetectionStats(threshold=0.5))
    for k in range(7):  # 21 tips
        photo.add(pred, target, uv, vis)
        grid.add(pred, target, uv, vis)
        if k < 6:
            few.add(pred, target, uv, vis)
    p = photo.summary()
    assert p["tips_recall"] == 0.0
    assert p["tip_shift_px"] == pytest.approx(6.0, abs=0.2)
    assert few.summary()["tip_shift_px"] == 0.0
    assert grid.summary()["tip_shift_px"] == 0.0
    # outboard tips give a negative shift
    out = DetectionStats(threshold=0.5, px_scale=2.0)
    for _ in range(7):
        out.add(_maps(_tips_inboard(uv, -1.0), vis), target, uv, vis)
    assert out.summary()["tip_shift_px"] == pytest.approx(-2.0, abs=0.1)


def test_recall_in_sight_leaves_hidden_tips_out() -> None:
    """Two of three tips found; the missed one is hidden (behind the tower, say): recall
    2/3 over the tips in the frame, 1 over the tips in sight; without in_sight, NaN."""
    uv = _TURBINE_UV
    vis = np.ones(6, bool)
    target = _maps(uv, vis)
    pred = _maps(uv, np.array([True] * 5 + [False]))
    in_sight = np.array([True] * 5 + [False])
    st, plain = DetectionStats(threshold=0.5), DetectionStats(threshold=0.5)
    st.add(pred, target, uv, vis, in_sight)
    plain.add(pred, target, uv, vis)
    m, p = st.summary(), plain.summary()
    assert m["tips_recall"] == p["tips_recall"] == pytest.approx(2 / 3)
    assert m["tips_recall_in_sight"] == 1.0
    assert m["tips_in_sight"] == pytest.approx(2 / 3)
    assert np.isnan(p["tips_recall_in_sight"]) and np.isnan(p["tips_in_sight"])
    # a found tip that is hidden counts as found over the frame, not in sight
    st2 = DetectionStats(threshold=0.5)
    st2.add(target, target, uv, vis, np.array([True] * 4 + [False, True]))
    assert st2.summary()["tips_recall_in_sight"] == 1.0


def test_tips_are_matched_at_sub_pixel_positions() -> None:
    """Tips drawn half a pixel off the grid match a 0.6 px radius only once refined."""
    uv = _TURBINE_UV + np.array([0.5, 0.0])
    vis = np.ones(6, bool)
    maps = _maps(uv, vis)
    st = DetectionStats(threshold=0.5, match_px=0.2)
    st.add(maps, maps, uv, vis)
    assert st.summary()["tips_recall"] == 1.0


def test_recall_split_by_apparent_blade_length() -> None:
    """Blades 12 px long: short at 40 px (grid), long in pixels of a 4x photo (48 px)."""
    uv = _TURBINE_UV
    vis = np.ones(6, bool)
    target = _maps(uv, vis)
    pred = _maps(uv, np.array([True] * 4 + [False] * 2))  # one tip of three found
    grid, photo = (DetectionStats(threshold=0.5, match_px=20.0, px_scale=k) for k in (1.0, 4.0))
    for st in (grid, photo):
        st.add(pred, target, uv, vis)
    g, p = grid.summary(), photo.summary()
    assert g["tips_short"] == 1.0 and g["tips_recall_short"] == pytest.approx(1 / 3)
    assert np.isnan(g["tips_recall_long"])
    assert p["tips_short"] == 0.0 and p["tips_recall_long"] == pytest.approx(1 / 3)


#: Two upright turbines side by side (base, tower top, hub, three tips) [px].
_A = np.array([[20, 55], [20, 20], [23, 20], [23, 8], [14, 25], [31, 25]], float)

_B = _A + np.array([40.0, 0.0])


def _turbine_maps(uvs: list[np.ndarray], labs: list[np.ndarray]) -> np.ndarray:
    return render_keypoint_heatmaps(60, 80, uvs, labs, sigma_px=1.5)


def test_instance_stats_match_every_turbine() -> None:
    """Turbine A detected, B not: recall 1/2 per point type, precision 1; a negative
    photo with a hub blob: one false detection; lines judged only where labelled."""
    all6 = np.ones(6, bool)
    target = _turbine_maps([_A, _B], [all6, all6])
    pred = _turbine_maps([_A], [all6])
    vis = np.full((2, 6), 2, np.int8)
    vis[1, 3] = 1  # B's first tip labelled as occluded
    st = InstanceStats(threshold=0.5)
    st.add(pred, target, np.stack([_A, _B]), vis)
    m = st.summary()
    for name in ("base", "tower_top", "hub"):
        assert m[f"{name}_recall"] == 0.5 and m[f"{name}_precision"] == 1.0
        assert m[f"{name}_median_px"] < 0.2
    assert m["tips_labelled"] == 6 and m["tips_recall"] == 0.5
    assert m["tips_recall_in_sight"] == pytest.approx(3 / 5)
    assert 0.3 < m["iou_tower"] < 0.7  # half the labelled towers found
    assert m["iou_tower_photos"] == 1
    # a negative photo: the hub blob is a false detection; its lines are all judged
    st.add(_turbine_maps([_A], [np.array([False, False, True, False, False, False])]),
           np.zeros((7, 60, 80)), np.zeros((0, 6, 2)), np.zeros((0, 6), np.int8))
    m = st.summary()
    assert m["hub_precision"] == 0.5 and m["photos"] == 2 and m["turbines"] == 2
    assert m["iou_tower_photos"] == 2
    # a turbine whose base is not labelled (out of frame): no tower target, not judged
    vis_nobase = np.full((1, 6), 2, np.int8)
    vis_nobase[0, 0] = 0
    st2 = InstanceStats(threshold=0.5)
    st2.add(target, _turbine_maps([_A], [vis_nobase[0] > 0]), _A[None], vis_nobase)
    m2 = st2.summary()
    assert np.isnan(m2["iou_tower"]) and m2["iou_tower_photos"] == 0
    assert m2["iou_nacelle"] > 0.3 and np.isnan(m2["base_recall"])
