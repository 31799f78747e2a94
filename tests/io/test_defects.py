"""defects_groundtruth.csv, defect_boxes.csv and damage.csv: round trips and refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support import raises_input_error

from turbinefit.inspection.defects import Defect
from turbinefit.io.defects import (
    format_defect_boxes_csv,
    format_defects_csv,
    read_damage_csv,
    read_defects_csv,
)
from turbinefit.io.regions import read_box_csv
from turbinefit.sim.defects import draw_defects
from turbinefit.turbine.model import TurbineParams


def test_defects_round_trip(tmp_path: Path) -> None:
    drawn = draw_defects(20, TurbineParams(0, 0, 90, 0, 5, 0, 60), np.random.default_rng(1))
    p = tmp_path / "d.csv"
    p.write_text(format_defects_csv(drawn))
    back = read_defects_csv(p)
    assert back.defects == drawn and back.lines == list(range(2, 22))


def test_defects_kind_is_optional_and_blades_may_be_letters(tmp_path: Path) -> None:
    p = tmp_path / "d.csv"
    p.write_text("defect,part,side,span_m,chord,size_m\nX,B,trailing_edge,12.5,-1,0.1\n")
    assert read_defects_csv(p).defects == [
        Defect("X", "blade_B", "trailing_edge", 12.5, -1.0, 0.1, "erosion")]


@pytest.mark.parametrize(("text", "line", "field"), [
    ("defect,part,side\n", 1, None),
    ("defect,part,side,span_m,chord,size_m,kind,extra\n", 1, None),
    ("defect,part,side,span_m,chord,size_m\nD,blade_A,leading_edge,1,1\n", 2, None),
    ("defect,part,side,span_m,chord,size_m\nD,blade_A,leading_edge,x,1,0.1\n", 2, "span_m"),
    ("defect,part,side,span_m,chord,size_m\nD,blade_A,leading_edge,3,1,0\n", 2, "size_m"),
    ("defect,part,side,span_m,chord,size_m\nD,blade_A,pressure_side,3,-1.2,0.1\n", 2, "chord"),
    ("defect,part,side,span_m,chord,size_m\nD,tower,pressure_side,3,0,0.1\n", 2, "part"),
    ("defect,part,side,span_m,chord,size_m\nD,A,pressure_side,3,0,0.1,x\n", 2, None),
    ("defect,part,side,span_m,chord,size_m,kind\nD,A,pressure_side,3,0,0.1,dent\n", 2, "kind"),
    ("defect,part,side,span_m,chord,size_m\n,A,pressure_side,3,0,0.1\n", 2, "defect"),
    ("defect,part,side,span_m,chord,size_m\n", None, None),
])
def test_bad_defects_name_file_line_and_column(tmp_path: Path, text: str, line: int | None,
                                               field: str | None) -> None:
    p = tmp_path / "d.csv"
    p.write_text(text)
    with raises_input_error(p, line, field):
        read_defects_csv(p)


def test_defect_boxes_are_a_box_csv_with_defect_names(tmp_path: Path) -> None:
    (tmp_path / "1.000000.png").write_bytes(b"")
    (tmp_path / "b.csv").write_text(format_defect_boxes_csv([
        ("1.000000.png", 64, 48, "crack", (1, 2, 10, 20), "D1"),
        ("1.000000.png", 64, 48, "burn", (30, 2, 40, 9), "D2")]))
    (lab,) = read_box_csv(tmp_path / "b.csv", tmp_path)
    assert lab.boxes == (("crack", (1.0, 2.0, 10.0, 20.0)), ("burn", (30.0, 2.0, 40.0, 9.0)))
    assert lab.defects == ("D1", "D2")


def test_damage_csv_rows(tmp_path: Path) -> None:
    p = tmp_path / "damage.csv"
    p.write_text("photo,timestamp,keyframe,class,xmin,ymin,xmax,ymax,part,side,span_m,"
                 "span_from_m,span_to_m,distance_m,on_part,chord,defect\n"
                 "a.png,1.0,0,crack,0,0,4,5,blade_A,pressure_side,3.5,3,4,8.2,1.00,0.25,D1\n"
                 "b.png,2.0,1,crack,0,0,4,5,,,,,,,0.00,,\n")
    a, b = read_damage_csv(p)
    assert (a.part, a.side, a.span_m, a.chord, a.distance_m, a.defect, a.area_px) == (
        "blade_A", "pressure_side", 3.5, 0.25, 8.2, "D1", 20.0)
    assert (b.part, b.side, b.span_m, b.chord, b.defect) == (None, None, None, None, "")
    p.write_text("photo,keyframe,class,part,side,span_m,distance_m\nx,0,c,blade_A,s,1,-3\n")
    with raises_input_error(p, 2, "distance_m"):
        read_damage_csv(p)
