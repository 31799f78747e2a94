"""The hand-made labels of the real-photo benchmark (``benchmarks/bench_real.py``): what
each blade photo shows, and the outlines of the turbine parts its box leaves out."""

from __future__ import annotations

import csv
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
PHOTO_PX = 1024  # the data set's photos are 1024 x 1024
PARTS = {"tower", "nacelle", "blade", "other-turbine"}


def test_parts_outline_only_photos_showing_more_than_the_blade() -> None:
    with open(BENCH / "real_blade_views.csv", newline="") as f:
        views = {r["filename"]: r["view"] for r in csv.DictReader(f)}
    assert set(views.values()) == {"blade", "tower-too"}
    with open(BENCH / "real_blade_parts.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    outlined = {r["filename"] for r in rows}
    # every photo showing the tower or another turbine has its parts outlined, no other
    assert outlined == {n for n, v in views.items() if v == "tower-too"}
    for r in rows:
        assert r["part"] in PARTS, r
        xy = [float(v) for v in r["polygon"].split()]
        assert len(xy) >= 6 and len(xy) % 2 == 0, r
        assert all(0 <= v <= PHOTO_PX for v in xy), r
        xs, ys = xy[0::2], xy[1::2]
        area = 0.5 * abs(sum(xs[i] * ys[i - 1] - xs[i - 1] * ys[i] for i in range(len(xs))))
        assert area > 100, r  # a part, not a degenerate outline
