"""How well boxes drawn on photos are located on the turbine: ``damage.csv`` (``coverage
--damage``) against the known defects (``defects_groundtruth.csv`` of ``simulate``).

Each located box names the defect it was drawn round (``damage.csv``'s ``defect`` column,
from ``simulate``'s ``defect_boxes.csv``); :func:`score_damage` joins it to that defect's
truth and scores

* **per box** (:class:`BoxScore`): the right part (blade), the right side, the span error
  ``|span - truth|`` [m] and the chord error ``|chord - truth|`` (chord positions in
  [-1, 1]: :mod:`turbinefit.inspection.defects`), the errors only where the part is right;
* **per defect** (:class:`DefectScore`), a defect seen in several photos being located
  once: its part is the part most of its boxes name; its span and chord the medians of
  its boxes' on that part (the median, not the mean: one box at a grazing angle does not
  move it); its side (:func:`defect_side`) an edge if boxes from both faces show it and
  its chord lies in the outer half towards that edge (a defect on a face is hidden from
  the other face, unless it wraps the edge it is near), else the side of the box that
  sees it most squarely (the largest area x distance squared: the area it covers across
  the line of sight); then the same errors;
* **summary** (:class:`DamageScore`): of the defects seen (in at least one box), the
  fraction on the right part, on the right part and side, and the median and 95th
  percentile of the span error (defects on the right part), the median chord error; the
  same fractions over boxes; defects never seen and boxes naming no known defect are
  counted. A figure over nothing is None (not NaN).

The side of a box is the side its camera sees (``coverage``'s convention,
:mod:`turbinefit.inspection.surface`): a defect on an edge seen from well off the edge is
on a face for that box, so per-defect sides are the better figure.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from turbinefit.inspection.defects import Defect
from turbinefit.io.defects import LocatedDamage, read_damage_csv, read_defects_csv


@dataclass(frozen=True)
class BoxScore:
    """One located box against its defect's truth (module docstring).

    Attributes:
        photo: the photo; defect: the defect's name.
        part, side: where the box was located (None: not on the turbine).
        right_part, right_side: whether they are the defect's (the side only counts on the
            right part).
        span_error_m, chord_error: the errors (None unless on the right part, or without
            a located chord).
        distance_m: the camera's distance [m].
        chord: the box's located chord position (None off the blades).
        area_px: the box's area [px] (None: not known).
    """

    photo: str
    defect: str
    part: str | None
    side: str | None
    right_part: bool
    right_side: bool
    span_error_m: float | None
    chord_error: float | None
    distance_m: float | None
    chord: float | None = None
    area_px: float | None = None


@dataclass(frozen=True)
class DefectScore:
    """One known defect, located from all its boxes (module docstring).

    Attributes:
        defect: its name; truth: the defect.
        boxes: how many boxes show it (0: never seen; then nothing else is set).
        part, side: where most of its boxes put it.
        span_m, chord: medians of those boxes' spans and chords.
        right_part, right_side: whether part and side are the truth's.
        span_error_m, chord_error: the errors of the medians (None unless on the right
            part).
    """

    defect: str
    truth: Defect
    boxes: int
    part: str | None = None
    side: str | None = None
    span_m: float | None = None
    chord: float | None = None
    right_part: bool = False
    right_side: bool = False
    span_error_m: float | None = None
    chord_error: float | None = None


@dataclass(frozen=True)
class DamageScore:
    """Boxes located on a turbine against the known defects (:func:`score_damage`)."""

    defects: list[DefectScore]
    boxes: list[BoxScore]
    unknown_boxes: int

    @property
    def seen(self) -> list[DefectScore]:
        """The defects shown by at least one box."""
        return [d for d in self.defects if d.boxes > 0]

    def summary(self) -> dict[str, Any]:
        """The summary figures (module docstring) as plain numbers (None over nothing)."""
        seen = self.seen
        span = [d.span_error_m for d in seen if d.span_error_m is not None]
        chord = [d.chord_error for d in seen if d.chord_error is not None]
        box_span = [b.span_error_m for b in self.boxes if b.span_error_m is not None]
        return {
            "defects": len(self.defects), "defects_seen": len(seen),
            "boxes": len(self.boxes), "boxes_of_unknown_defects": self.unknown_boxes,
            "right_part": _fraction([d.right_part for d in seen]),
            "right_part_and_side": _fraction([d.right_side for d in seen]),
            "span_error_median_m": _percentile(span, 50),
            "span_error_p95_m": _percentile(span, 95),
            "chord_error_median": _percentile(chord, 50),
            "chord_error_p95": _percentile(chord, 95),
            "box_right_part": _fraction([b.right_part for b in self.boxes]),
            "box_right_part_and_side": _fraction([b.right_side for b in self.boxes]),
            "box_span_error_median_m": _percentile(box_span, 50),
            "box_span_error_p95_m": _percentile(box_span, 95),
        }

    def rows(self) -> list[dict[str, Any]]:
        """One plain row per defect: its truth and where it was located."""
        out = []
        for d in self.defects:
            row = {k: v for k, v in asdict(d).items() if k != "truth"}
            row.update({f"true_{k}": v for k, v in asdict(d.truth).items() if k != "defect"})
            out.append(row)
        return out


def _fraction(flags: list[bool]) -> float | None:
    return float(np.mean(flags)) if flags else None


def _percentile(values: list[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None


def _squareness(row: LocatedDamage) -> float:
    """How squarely a box sees its defect: its area times the distance squared (the
    defect's area across the line of sight, up to the focal length squared); 0 unknown."""
    if row.area_px is None or row.distance_m is None:
        return 0.0
    return row.area_px * row.distance_m ** 2


#: Of a defect seen from both faces, the least ``|chord|`` that puts it on the edge it is
#: near (:func:`defect_side`).
EDGE_WRAP_CHORD = 0.5
_FACES = frozenset(("pressure_side", "suction_side"))


def defect_side(rows: Sequence[LocatedDamage], chord: float | None) -> str | None:
    """The side of a defect from its boxes ``rows`` on one blade and its median chord
    position (module docstring): an edge if both faces show it and ``|chord| >=``
    :data:`EDGE_WRAP_CHORD` (the leading edge for a positive chord), else the squarest
    box's side. Edge defects 0.2-0.5 m across wrap onto both faces, and the squarest box
    of one, seen from 45 degrees off the edge, names a face: on 20 simulated missions
    this rule put 98 % (RTK: 97 %) of the defects seen on the right side, against 94 %
    for the squarest box alone (``benchmarks/bench_mission.py``)."""
    if not rows:
        return None
    sides = {r.side for r in rows}
    if _FACES <= sides and chord is not None and abs(chord) >= EDGE_WRAP_CHORD:
        return "leading_edge" if chord > 0 else "trailing_edge"
    return max(rows, key=_squareness).side


def _errors(truth: Defect, part: str | None, side: str | None, span: float | None,
            chord: float | None) -> tuple[bool, bool, float | None, float | None]:
    right_part = part == truth.part
    if not right_part:
        return False, False, None, None
    return (True, side == truth.side,
            None if span is None else abs(span - truth.span_m),
            None if chord is None else abs(chord - truth.chord))


def score_damage(located: Sequence[LocatedDamage], truth: Sequence[Defect]) -> DamageScore:
    """Score located boxes (``damage.csv``'s rows) against the known defects (module
    docstring); boxes are joined to defects by name."""
    by_name = {d.defect: d for d in truth}
    boxes: dict[str, list[LocatedDamage]] = {d.defect: [] for d in truth}
    box_scores = []
    unknown = 0
    for row in located:
        t = by_name.get(row.defect)
        if t is None:
            unknown += 1
            continue
        boxes[t.defect].append(row)
        rp, rs, es, ec = _errors(t, row.part, row.side, row.span_m, row.chord)
        box_scores.append(BoxScore(row.photo, t.defect, row.part, row.side, rp, rs, es, ec,
                                   row.distance_m, row.chord, row.area_px))
    defects = []
    for t in truth:
        rows = boxes[t.defect]
        if not rows:
            defects.append(DefectScore(t.defect, t, 0))
            continue
        parts = Counter(r.part for r in rows if r.part is not None)
        if not parts:
            defects.append(DefectScore(t.defect, t, len(rows)))
            continue
        part = parts.most_common(1)[0][0]
        on = [r for r in rows if r.part == part]
        spans = [r.span_m for r in on if r.span_m is not None]
        chords = [r.chord for r in on if r.chord is not None]
        span = float(np.median(spans)) if spans else None
        chord = float(np.median(chords)) if chords else None
        side = defect_side(on, chord)
        rp, rs, es, ec = _errors(t, part, side, span, chord)
        defects.append(DefectScore(t.defect, t, len(rows), part, side, span, chord, rp, rs, es,
                                   ec))
    return DamageScore(defects, box_scores, unknown)


def score_damage_files(damage_csv: str | os.PathLike[str],
                       truth_csv: str | os.PathLike[str]) -> DamageScore:
    """:func:`score_damage` of a ``damage.csv`` and a ``defects_groundtruth.csv``."""
    return score_damage(read_damage_csv(damage_csv), read_defects_csv(truth_csv).defects)
