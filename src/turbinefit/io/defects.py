"""Known defects and where they were found, as CSV files.

* ``defects_groundtruth.csv`` (:func:`read_defects_csv`, :func:`format_defects_csv`): one
  defect a row, with the header ``defect,part,side,span_m,chord,size_m,kind`` (``kind``
  may be left out: ``erosion``). ``part`` is ``blade_A``, ``blade_B`` or ``blade_C`` (or
  ``A``, ``B``, ``C``), ``side`` one of ``leading_edge``, ``pressure_side``,
  ``trailing_edge``, ``suction_side``, ``span_m`` metres from the hub centre, ``chord``
  -1 (trailing edge) .. 1 (leading edge), ``size_m`` the size across [m]; what they mean
  precisely: :mod:`turbinefit.sim.defects`. ``simulate`` writes it and reads it
  (``--defects-file``).
* ``defect_boxes.csv`` (:func:`format_defect_boxes_csv`): per photo the box of every
  defect in view, in the box CSV format of :mod:`turbinefit.io.regions` with its optional
  ``defect`` column (``class`` is the defect's kind).
* ``damage.csv`` of ``coverage --damage`` (:func:`read_damage_csv`): where each box lies,
  as :class:`LocatedDamage` rows.

Every number passes its :class:`~turbinefit.io.quantities.Quantity`; errors name the file,
line and column.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from turbinefit.errors import InputError
from turbinefit.inspection.defects import Defect, defect_problem
from turbinefit.io.atomic import StrPath, read_text
from turbinefit.io.limits import MAX_LENGTH_M
from turbinefit.io.quantities import Quantity
from turbinefit.io.regions import BOX_COLUMNS, DEFECT_COLUMN

#: Columns of ``defects_groundtruth.csv`` (``kind`` optional on reading).
DEFECT_COLUMNS = ("defect", "part", "side", "span_m", "chord", "size_m", "kind")
#: A defect's span along its blade [m] (the blade's own length is checked by
#: :func:`turbinefit.sim.defects.check_defects`).
SPAN_M = Quantity("span", "m", 0.0, MAX_LENGTH_M)
#: A defect's position along the chord: -1 trailing edge .. 1 leading edge.
CHORD = Quantity("chord", "", -1.0, 1.0)
#: A defect's size across [m]: from 1 cm to 5 m.
DEFECT_SIZE_M = Quantity("defect size", "m", 0.01, 5.0)
#: A box's edge [px] in ``damage.csv`` (photos of at most 200 MP: under 10^6 px a side).
BOX_EDGE = Quantity("box edge", "px", 0.0, 1e6)
#: A distance from the camera [m] in ``damage.csv``.
DISTANCE_M = Quantity("distance", "m", 0.0, MAX_LENGTH_M * 100)


def _rows(path: StrPath, columns: Sequence[str], optional: Sequence[str] = ()
          ) -> list[tuple[int, dict[str, str]]]:
    """The rows of a CSV with a header holding ``columns`` (and any of ``optional``), as
    (line, {column: cell}); refuses other headers and rows of another length."""
    rows = list(csv.reader(io.StringIO(read_text(path))))
    header: list[str] | None = None
    out = []
    for k, row in enumerate(rows, start=1):
        cells = [c.strip() for c in row]
        if not cells or cells == [""]:
            continue
        if header is None:
            header = [c.lower() for c in cells]
            missing = [c for c in columns if c not in header]
            unknown = [c for c in header if c not in (*columns, *optional)]
            if missing or unknown or len(set(header)) != len(header):
                raise InputError(f"header {','.join(cells)}: expected the columns "
                                 f"{','.join(columns)}" + (f" (and {','.join(optional)})"
                                                           if optional else ""),
                                 path=path, line=k)
            continue
        if len(cells) != len(header):
            raise InputError(f"{len(cells)} columns, expected {len(header)} "
                             f"({','.join(header)})", path=path, line=k)
        out.append((k, dict(zip(header, cells, strict=True))))
    if header is None:
        raise InputError("empty file: expected a header line " + ",".join(columns), path=path)
    return out


@dataclass(frozen=True)
class DefectsFile:
    """The defects of a ``defects_groundtruth.csv`` and the line each came from."""

    defects: list[Defect]
    lines: list[int]


def read_defects_csv(path: StrPath) -> DefectsFile:
    """The defects of a ``defects_groundtruth.csv`` (module docstring), each checked but
    for its span against its blade's length (which needs the turbine:
    :func:`turbinefit.sim.defects.check_defects`).

    Raises:
        InputError: naming the file, line and column.
    """
    defects, lines = [], []
    for line, r in _rows(path, DEFECT_COLUMNS[:-1], DEFECT_COLUMNS[-1:]):
        part = r["part"]
        part = f"blade_{part}" if part in ("A", "B", "C") else part
        d = Defect(r["defect"], part, r["side"],
                   SPAN_M.parse(r["span_m"], path, line, "span_m"),
                   CHORD.parse(r["chord"], path, line, "chord"),
                   DEFECT_SIZE_M.parse(r["size_m"], path, line, "size_m"),
                   r.get("kind") or "erosion")
        if not d.defect:
            raise InputError("empty defect name", path=path, line=line, field="defect")
        why = defect_problem(d, None)
        if why is not None:
            raise InputError(f"defect {d.defect}: {why[1]}", path=path, line=line, field=why[0])
        defects.append(d)
        lines.append(line)
    if not defects:
        raise InputError("no defects in the file", path=path)
    return DefectsFile(defects, lines)


def format_defects_csv(defects: Iterable[Defect]) -> str:
    """The text of ``defects_groundtruth.csv``."""
    lines = [",".join(DEFECT_COLUMNS)]
    for d in defects:
        lines.append(f"{d.defect},{d.part},{d.side},{d.span_m:.3f},{d.chord:.3f},"
                     f"{d.size_m:.3f},{d.kind}")
    return "\n".join(lines) + "\n"


def format_defect_boxes_csv(rows: Iterable[tuple[str, int, int, str, tuple[int, int, int, int],
                                                 str]]) -> str:
    """The text of ``defect_boxes.csv`` from rows (photo file name, width, height, class,
    (xmin, ymin, xmax, ymax), defect)."""
    lines = [",".join((*BOX_COLUMNS, DEFECT_COLUMN))]
    for name, w, h, cls, (x0, y0, x1, y1), defect in rows:
        lines.append(f"{name},{w},{h},{cls},{x0},{y0},{x1},{y1},{defect}")
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class LocatedDamage:
    """Where a box drawn on a photo lies on the turbine (a row of ``damage.csv``).

    Attributes:
        photo: the photo's file name; keyframe: its keyframe index.
        label: the box's class.
        part, side: the part and side the box shows (None: not on the turbine).
        span_m: its median span [m] (None off the blades and tower).
        chord: its median chord position (-1 .. 1; None off the blades).
        distance_m: the camera's distance [m] (None: not on the turbine).
        defect: the known defect the box was drawn round (``""``: not known).
        area_px: the box's area [px] (None: not known).
    """

    photo: str
    keyframe: int
    label: str
    part: str | None
    side: str | None
    span_m: float | None
    chord: float | None
    distance_m: float | None
    defect: str = ""
    area_px: float | None = None


#: The columns :func:`read_damage_csv` needs, and those it also accepts.
DAMAGE_NEEDED = ("photo", "keyframe", "class", "part", "side", "span_m", "distance_m")
DAMAGE_OPTIONAL = ("timestamp", "xmin", "ymin", "xmax", "ymax", "span_from_m", "span_to_m",
                   "on_part", "chord", "defect")


def read_damage_csv(path: StrPath) -> list[LocatedDamage]:
    """The rows of a ``damage.csv`` (``coverage --damage``) as :class:`LocatedDamage`
    (``chord`` and ``defect`` are read where the file has them).

    Raises:
        InputError: naming the file, line and column.
    """
    out = []
    keyframe = Quantity("keyframe", "", 0, 1e9, integer=True)
    for line, r in _rows(path, DAMAGE_NEEDED, DAMAGE_OPTIONAL):
        def num(col: str, q: Quantity, r: dict[str, str] = r, line: int = line) -> float | None:
            text = r.get(col, "")
            return None if text == "" else q.parse(text, path, line, col)

        k = num("keyframe", keyframe)
        if k is None:
            raise InputError("empty keyframe", path=path, line=line, field="keyframe")
        corners = [num(c, BOX_EDGE) for c in ("xmin", "ymin", "xmax", "ymax")]
        area = None
        if all(c is not None for c in corners):
            x0, y0, x1, y1 = corners
            area = max(x1 - x0, 0.0) * max(y1 - y0, 0.0)  # type: ignore[operator]
        out.append(LocatedDamage(r["photo"], int(k), r["class"], r["part"] or None,
                                 r["side"] or None, num("span_m", SPAN_M),
                                 num("chord", CHORD), num("distance_m", DISTANCE_M),
                                 r.get("defect", ""), area))
    return out

