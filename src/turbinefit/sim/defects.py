"""Known defects drawn on a simulated turbine's blades (erosion patches, cracks and
lightning-receptor burns) and how the photo renderer paints them.

Where a defect is (blade, side, span, chord, size): :mod:`turbinefit.inspection.defects`.
The renderer's own section coordinate
(:meth:`~turbinefit.sim.images.painter.Painter.blade_surface`) runs the other way along
the chord: its chord axis points to the trailing edge of :mod:`turbinefit.inspection.surface`.

**How a defect is painted** (:meth:`~turbinefit.sim.images.painter.Painter.defects`): every
surface point within ``size_m / 2`` of the centre (straight-line distance, so a defect on
an edge wraps round it): an erosion patch is a ragged grey patch of pits (exposed
laminate), a crack a thin dark jagged line (across the blade on a face, along it on an
edge), a burn a black scorch with a brown halo.

:func:`draw_defects` draws defects at random; :func:`painted_defects` turns them into the
renderer's terms.
"""

from __future__ import annotations

import math

import numpy as np

from turbinefit.inspection.defects import BLADE_PARTS, DEFECT_KINDS, Defect
from turbinefit.inspection.surface import blade_names
from turbinefit.turbine.model import TurbineParams
from turbinefit.turbine.solid import blade_profile

#: Sizes :func:`draw_defects` draws [m] (the visible range of real blade damage).
DRAW_SIZE_M = (0.05, 0.5)


def draw_defects(n: int, turbine: TurbineParams, rng: np.random.Generator) -> list[Defect]:
    """``n`` defects at random on the blades of ``turbine``, named ``D01``, ``D02``, ...:
    half erosion (on the outer half, mostly on the leading edge), 30 % cracks (anywhere
    from 15 to 90 % span, on a face or the trailing edge), 20 % receptor burns (on a face
    within 3 m of the tip, near mid-chord); sizes in :data:`DRAW_SIZE_M` (burns up to
    0.3 m)."""
    b = abs(turbine.blade_length)
    out = []
    width = max(2, len(str(n)))
    for k in range(n):
        kind = DEFECT_KINDS[int(rng.choice(3, p=[0.5, 0.3, 0.2]))]
        part = BLADE_PARTS[int(rng.integers(3))]
        face = ("pressure_side", "suction_side")[int(rng.integers(2))]
        if kind == "erosion":
            span = b * rng.uniform(0.5, 0.97)
            side, chord = ("leading_edge", 1.0) if rng.uniform() < 0.7 else \
                (face, float(rng.uniform(0.5, 0.9)))
            size = rng.uniform(0.1, DRAW_SIZE_M[1])
        elif kind == "crack":
            span = b * rng.uniform(0.15, 0.9)
            side, chord = ("trailing_edge", -1.0) if rng.uniform() < 0.3 else \
                (face, float(rng.uniform(-0.8, 0.8)))
            size = rng.uniform(*DRAW_SIZE_M)
        else:
            span = b - rng.uniform(0.3, min(3.0, 0.5 * b))
            side, chord = face, float(rng.uniform(-0.2, 0.2))
            size = rng.uniform(DRAW_SIZE_M[0], 0.3)
        out.append(Defect(f"D{k + 1:0{width}d}", part, side, round(float(span), 3),
                          round(chord, 3), round(float(size), 3), kind))
    return out


def painted_defects(defects: list[Defect], turbine: TurbineParams
                    ) -> tuple[tuple[float, ...], ...]:
    """The defects as the renderer paints them (:attr:`turbinefit.sim.images.Scene.defects`):
    per defect ``(model blade, kind code, span [m], X [m], Y [m], radius [m], phase)``,
    ``(X, Y)`` the centre in the renderer's section frame (its chord axis, its thickness
    axis towards the pressure side) and ``phase`` a number that makes each one's ragged
    outline its own."""
    names = blade_names(turbine)
    b = max(abs(turbine.blade_length), 0.5)
    out = []
    for k, d in enumerate(defects):
        model = names.index(d.part[-1])
        A, B = (float(v[0]) for v in blade_profile(np.array([d.span_m / b], np.float32), b))
        X = -d.chord * A  # the renderer's chord axis points to the trailing edge
        sign = {"pressure_side": 1.0, "suction_side": -1.0}.get(d.side, 0.0)
        Y = sign * B * math.sqrt(max(1.0 - d.chord * d.chord, 0.0))
        out.append((float(model), float(DEFECT_KINDS.index(d.kind)), float(d.span_m), X, Y,
                    0.5 * float(d.size_m), float(k) * 2.399963))
    return tuple(out)
