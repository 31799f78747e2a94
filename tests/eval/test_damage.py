"""Scoring located boxes against known defects: the join by name, per box and per defect,
the squarest box's side, an edge's defect seen from both faces, and summaries over
nothing."""

from __future__ import annotations

from pathlib import Path

import pytest

from turbinefit.eval.damage import EDGE_WRAP_CHORD, defect_side, score_damage
from turbinefit.inspection.defects import Defect
from turbinefit.io.defects import LocatedDamage

TRUTH = [Defect("D1", "blade_A", "leading_edge", 40.0, 1.0, 0.3),
         Defect("D2", "blade_B", "pressure_side", 20.0, 0.2, 0.3, "crack"),
         Defect("D3", "blade_C", "suction_side", 10.0, 0.0, 0.3, "burn")]


def _box(defect: str, part: str | None, side: str | None, span: float | None,
         chord: float | None = None, area: float = 100.0, dist: float = 10.0) -> LocatedDamage:
    return LocatedDamage("p.png", 0, "x", part, side, span, chord, dist, defect, area)


def test_score_per_box_and_per_defect() -> None:
    boxes = [
        # D1: seen head-on from the leading edge (largest area x distance^2), obliquely
        # from the pressure side twice
        _box("D1", "blade_A", "leading_edge", 40.1, 0.95, area=400.0),
        _box("D1", "blade_A", "pressure_side", 40.3, 0.8, area=150.0),
        _box("D1", "blade_A", "pressure_side", 39.9, 0.85, area=160.0),
        # D2: on the wrong blade twice, the right one once
        _box("D2", "blade_C", "pressure_side", 20.0),
        _box("D2", "blade_C", "pressure_side", 20.0),
        _box("D2", "blade_B", "pressure_side", 20.5, 0.1),
        _box("ghost", "blade_A", "pressure_side", 1.0),
        _box("", "blade_A", "pressure_side", 1.0),
    ]
    score = score_damage(boxes, TRUTH)
    d1, d2, d3 = score.defects
    assert (d1.boxes, d1.part, d1.side, d1.right_part, d1.right_side) == (
        3, "blade_A", "leading_edge", True, True)
    assert d1.span_error_m == pytest.approx(0.1) and d1.chord_error == pytest.approx(0.15)
    assert (d2.part, d2.right_part, d2.right_side, d2.span_error_m) == ("blade_C", False,
                                                                         False, None)
    assert d3.boxes == 0 and d3.part is None
    assert score.unknown_boxes == 2 and len(score.boxes) == 6
    s = score.summary()
    assert (s["defects"], s["defects_seen"], s["boxes"]) == (3, 2, 6)
    assert s["right_part"] == 0.5 and s["right_part_and_side"] == 0.5
    assert s["span_error_median_m"] == pytest.approx(0.1)
    assert s["box_right_part"] == pytest.approx(4 / 6)
    assert s["box_right_part_and_side"] == pytest.approx(2 / 6)  # D1 leading, D2's blade_B
    assert s["box_span_error_median_m"] == pytest.approx(0.2)  # 0.1, 0.3, 0.1, 0.5
    rows = score.rows()
    assert rows[0]["defect"] == "D1" and rows[0]["true_side"] == "leading_edge"


def test_a_box_off_the_turbine_and_nothing_to_score() -> None:
    score = score_damage([_box("D3", None, None, None)], TRUTH)
    assert score.defects[2].boxes == 1 and score.defects[2].part is None
    s = score_damage([], TRUTH).summary()
    assert s["defects_seen"] == 0
    assert all(s[k] is None for k in ("right_part", "span_error_median_m", "span_error_p95_m",
                                      "box_right_part"))


def test_score_from_files(tmp_path: Path) -> None:
    from turbinefit.eval.damage import score_damage_files
    from turbinefit.io.defects import format_defects_csv

    (tmp_path / "t.csv").write_text(format_defects_csv(TRUTH))
    (tmp_path / "d.csv").write_text(
        "photo,keyframe,class,xmin,ymin,xmax,ymax,part,side,span_m,distance_m,chord,defect\n"
        "a.png,0,erosion,0,0,10,10,blade_A,leading_edge,40.2,9.0,0.9,D1\n")
    s = score_damage_files(tmp_path / "d.csv", tmp_path / "t.csv").summary()
    assert (s["defects_seen"], s["right_part_and_side"]) == (1, 1.0)
    assert s["span_error_median_m"] == pytest.approx(0.2)


def test_a_defect_seen_from_both_faces_wraps_the_edge_it_is_near() -> None:
    """Both faces show it and its chord is near an edge: that edge, whichever box is the
    squarest; near mid-chord, or one face only: the squarest box's side."""
    both = [_box("D1", "blade_A", "pressure_side", 40.0, area=900.0),
            _box("D1", "blade_A", "suction_side", 40.0, area=100.0)]
    assert defect_side(both, 0.75) == "leading_edge"
    assert defect_side(both, -0.8) == "trailing_edge"
    assert defect_side(both, 0.2) == "pressure_side"  # a big box across the face
    assert defect_side(both, None) == "pressure_side"
    assert defect_side(both[:1], 0.95) == "pressure_side"
    assert defect_side([], 0.9) is None
    assert defect_side(both, EDGE_WRAP_CHORD) == "leading_edge"
    boxes = [_box("D1", "blade_A", "pressure_side", 40.0, 0.8, area=400.0),
             _box("D1", "blade_A", "suction_side", 40.2, 0.7, area=100.0)]
    d1 = score_damage(boxes, TRUTH).defects[0]
    assert (d1.side, d1.right_side) == ("leading_edge", True)
