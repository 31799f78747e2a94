"""Known defects on a turbine's blades: where a defect is, in the terms ``coverage`` and
``damage.csv`` use, and the check that it lies on the blade.

A :class:`Defect` names its blade as ``coverage`` and ``damage.csv`` do (``blade_A``,
``blade_B``, ``blade_C``: :func:`~turbinefit.inspection.surface.blade_names` of the
turbine), its side as one of :data:`~turbinefit.inspection.surface.BLADE_SIDES`, its span
(metres from the hub centre along the blade, as ``coverage`` measures it) and its
``chord``: the position of its centre along the section's chord line, ``-1`` at the
trailing edge, ``0`` mid-chord, ``1`` at the leading edge (the leading edge of
:mod:`turbinefit.inspection.surface`: a rotor turning clockwise seen from upwind;
:meth:`TurbineSurface.chord_position <turbinefit.inspection.surface.TurbineSurface.chord_position>`
measures it on a fitted turbine). On the ``pressure_side`` (the face towards upwind) or
the ``suction_side`` the centre is the point of that face above that chord position; on
the ``leading_edge`` or ``trailing_edge`` it is the edge itself, so its chord is ``1`` or
``-1``. The section is the blade's as built, pitch and twist included (the chord line
turns with them). ``size_m`` is the defect's size across (a patch's or burn's diameter,
a crack's length).

:func:`defect_point` places a defect on a :class:`~turbinefit.inspection.surface.TurbineSurface`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import InputError
from turbinefit.inspection.surface import BLADE_SIDES, PARTS, TurbineSurface
from turbinefit.turbine.model import TurbineParams

FloatArray = NDArray[np.float64]

#: Kinds of defects, in the order of their codes in a painted defect.
DEFECT_KINDS = ("erosion", "crack", "burn")
#: The part names of the blades (``damage.csv``'s ``part``).
BLADE_PARTS = PARTS[:3]
#: The chord an edge's defect has: the edge itself.
EDGE_CHORD = {"leading_edge": 1.0, "trailing_edge": -1.0}
#: Defects start this far out along the blade (a fraction of its length): inside it the
#: blade is hidden in the spinner.
MIN_SPAN_FRACTION = 0.05


@dataclass(frozen=True)
class Defect:
    """One defect on a blade (module docstring).

    Attributes:
        defect: its name (``D01``), unique in a flight.
        part: ``blade_A``, ``blade_B`` or ``blade_C``.
        side: one of :data:`~turbinefit.inspection.surface.BLADE_SIDES`.
        span_m: metres from the hub centre along the blade.
        chord: -1 (trailing edge) .. 1 (leading edge); 1 or -1 on an edge.
        size_m: size across [m].
        kind: one of :data:`DEFECT_KINDS`.
    """

    defect: str
    part: str
    side: str
    span_m: float
    chord: float
    size_m: float
    kind: str = "erosion"


def defect_problem(d: Defect, blade_length: float | None) -> tuple[str, str] | None:
    """Why ``d`` cannot lie on a blade of ``blade_length`` [m] (field, reason), or None;
    ``blade_length`` None: its span is not checked."""
    if d.part not in BLADE_PARTS:
        return "part", f"unknown blade {d.part!r}; choose from {', '.join(BLADE_PARTS)}"
    if d.side not in BLADE_SIDES:
        return "side", f"unknown side {d.side!r}; choose from {', '.join(BLADE_SIDES)}"
    if d.kind not in DEFECT_KINDS:
        return "kind", f"unknown kind {d.kind!r}; choose from {', '.join(DEFECT_KINDS)}"
    if blade_length is not None:
        lo = MIN_SPAN_FRACTION * blade_length
        if not (lo <= d.span_m <= blade_length):
            return "span_m", (f"span {d.span_m:g} m is not on the blade: it must be between "
                              f"{lo:.2f} and {blade_length:.2f} m (the blade's length)")
    if not -1.0 <= d.chord <= 1.0:
        return "chord", f"chord {d.chord:g} is outside the blade: it must be in [-1, 1]"
    if d.side in EDGE_CHORD and d.chord != EDGE_CHORD[d.side]:
        return "chord", (f"a {d.side} defect lies on the edge: chord {EDGE_CHORD[d.side]:g}, "
                         f"not {d.chord:g}")
    return None


def check_defects(defects: list[Defect], turbine: TurbineParams, path: object | None = None,
                  lines: list[int] | None = None) -> None:
    """Refuse defects that are not on the blades of ``turbine`` (:func:`defect_problem`)
    or whose names repeat, naming the first (``path``, its ``lines[i]``).

    Raises:
        InputError: naming the file, line and field.
    """
    seen: dict[str, int] = {}
    length = abs(turbine.blade_length)
    for i, d in enumerate(defects):
        line = lines[i] if lines is not None else None
        why = defect_problem(d, length)
        if why is not None:
            raise InputError(f"defect {d.defect}: {why[1]}", path=path, line=line, field=why[0])
        if d.defect in seen:
            raise InputError(f"defect {d.defect} is named twice (also defect {seen[d.defect] + 1})",
                             path=path, line=line, field="defect")
        seen[d.defect] = i




def defect_point(surface: TurbineSurface, d: Defect) -> tuple[FloatArray, FloatArray]:
    """The centre of defect ``d`` on ``surface`` (its blades' pitch and twist those the
    defect's blade was built with) and the unit direction out of the surface there: the
    point on the section's outline at chord position ``d.chord`` on ``d.side``'s face
    (on an edge, the edge), and the outline's normal (on an edge, along the chord)."""
    k = BLADE_PARTS.index(d.part)
    bl = surface.blades[k]
    tw = float(surface.twist(d.span_m))
    chord = math.cos(tw) * bl.chord + math.sin(tw) * bl.normal
    normal = math.cos(tw) * bl.normal - math.sin(tw) * bl.chord
    A, B = (float(v[0]) for v in surface.blade_section(np.array([d.span_m])))
    face = {"pressure_side": 1.0, "suction_side": -1.0}.get(d.side, 0.0)
    x, y = d.chord * A, face * B * math.sqrt(max(1.0 - d.chord * d.chord, 0.0))
    point = bl.root + d.span_m * bl.axis + x * chord + y * normal
    out = x / (A * A) * chord + y / (B * B) * normal  # the ellipse's normal
    return point, out / np.linalg.norm(out)
