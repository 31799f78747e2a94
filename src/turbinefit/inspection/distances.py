"""The planner's own distances of points from the turbine's solid (:class:`PlannerDistances`):
closed-form bounds per shape (the blades' elliptic sections with their pitch and twist,
the spinner, the tower and the nacelle box), fast enough to test every candidate view and
every quarter metre of a leg. The finished path is checked again by the independent
distances of :mod:`turbinefit.inspection.clearance`."""

from __future__ import annotations

import numpy as np

from turbinefit.inspection.surface import FloatArray, TurbineSurface

#: How fast the blades' sections grow along the span at most (metres of half chord per
#: metre of span, :func:`~turbinefit.turbine.solid.blade_profile`: 0.14 at the root's
#: ramp), for the planner's distances from a blade.
SECTION_SLOPE = 0.15


class PlannerDistances:
    """Distances of points from the rotor (blades, spinner) and from the tower and nacelle."""

    def __init__(self, surface: TurbineSurface) -> None:
        self.s = surface

    def blade(self, p: FloatArray, i: int) -> FloatArray:
        """Distance from blade ``i``: from the section's support along the direction
        across the axis, the section the widest within ``SECTION_SLOPE`` times the
        distance along the span (the nearest point of a section that grows along the
        span lies off the point's own span)."""
        s, bl = self.s, self.s.blades[i]
        w = p - bl.root
        along = w @ bl.axis
        t = np.clip(along, 0.0, bl.length)
        perp = w - along[:, None] * bl.axis  # across the axis (beyond the tip too)
        r = np.linalg.norm(perp, axis=1)
        near = np.clip(t[:, None] + SECTION_SLOPE * r[:, None] * np.linspace(-1.0, 1.0, 5),
                       0.0, bl.length)
        A, B = (v.max(axis=1) for v in s.blade_section(near))
        tw = s.twist(t)
        chord = np.cos(tw)[:, None] * bl.chord + np.sin(tw)[:, None] * bl.normal
        normal = np.cos(tw)[:, None] * bl.normal - np.sin(tw)[:, None] * bl.chord
        cth = np.einsum("ij,ij->i", perp, chord) / np.maximum(r, 1e-12)
        sth = np.einsum("ij,ij->i", perp, normal) / np.maximum(r, 1e-12)
        ext = np.sqrt((A * cth) ** 2 + (B * sth) ** 2)
        axial = along - t
        return np.hypot(np.maximum(r - ext, 0.0), axial) - np.maximum(ext - r, 0.0)

    def rotor(self, p: FloatArray, skip: int = -1) -> FloatArray:
        s = self.s
        d = np.full(len(p), np.inf)
        for i in range(3):
            if i != skip:
                d = np.minimum(d, self.blade(p, i))
        spin = np.linalg.norm(p - s.spinner_centre, axis=1) - float(np.max(s.spinner_radii))
        return np.minimum(d, spin)

    def tower(self, p: FloatArray) -> FloatArray:
        s = self.s
        h = float(s.solid.tower_top_z - s.base[2])  # the tower reaches into the nacelle
        z = np.clip(p[:, 2] - s.base[2], 0.0, h)
        r = np.hypot(p[:, 0] - s.base[0], p[:, 1] - s.base[1]) - s.tower_radius(z)
        above = np.maximum(p[:, 2] - s.base[2] - h, 0.0)
        tower = np.hypot(np.maximum(r, 0.0), above) - np.maximum(-r, 0.0) * (above == 0)
        E = np.stack([s.shaft, s.side, s.up])
        q = np.abs((p - s.nacelle_centre) @ E.T) - s.nacelle_half
        box = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
        return np.minimum(tower, box)

