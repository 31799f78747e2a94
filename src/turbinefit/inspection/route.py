"""The legs between a plan's consecutive waypoints (:class:`Router`): the shortest clear
route of straight, round the blade, round the tower, or through transit planes parallel to
the rotor, each also from points backed away from the stations (see
:mod:`turbinefit.inspection.plan`'s docstring)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from turbinefit.inspection.distances import PlannerDistances
from turbinefit.inspection.surface import TOWER, FloatArray, TurbineSurface
from turbinefit.inspection.waypoint import Waypoint, path_length, rotate, view_dir

#: The least distance between a transit point and its neighbours [m]: DJI's waypoint
#: missions (Litchi's) take waypoints at least 0.5 m apart.
MIN_LEG = 0.5
#: How far [m] the router steps out of a station (back against its view, along its part
#: or round it) when no route from the station itself clears: a station just at the
#: stand-off from a blade and the clearance from the tower, or from a pitched blade, where
#: any leg straight to a transit plane first comes nearer one of them.
BACK_OFF = (1.0, 3.0)
#: The largest turn [deg] about a blade's axis between the transit points of a route
#: round the blade.
ARC_STEP_DEG = 20.0


def drop_close(p: FloatArray, least: float = MIN_LEG) -> FloatArray:
    """The polyline ``p`` (n, 3) without the inner points closer than ``least`` to the
    point kept before them or to the last point (the ends are kept)."""
    kept = [p[0]]
    for q in p[1:-1]:
        if np.linalg.norm(q - kept[-1]) >= least and np.linalg.norm(q - p[-1]) >= least:
            kept.append(q)
    return np.stack([*kept, p[-1]])



def densify(p: FloatArray, step: float = 0.5) -> FloatArray:
    """Points along the polyline ``p`` (n, 3) at most ``step`` apart."""
    if len(p) < 2:
        return p
    out = [p[:1]]
    for a, b in itertools.pairwise(p):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step))
        t = np.linspace(0.0, 1.0, n + 1)[1:, None]
        out.append(a + t * (b - a))
    return np.concatenate(out)



class Router:
    """Legs between consecutive waypoints: straight if clear, else through the transit
    planes (see the module docstring)."""

    def __init__(self, s: TurbineSurface, clear: PlannerDistances, d: float, t_clear: float,
                 min_alt: float) -> None:
        self.s, self.clear, self.d, self.t, self.min_alt = s, clear, d, t_clear, min_alt
        spin_front = float(0.25 * s.spinner_radii[0] + s.spinner_radii[0])
        self.up_off = d + max(spin_front, s.max_half_chord()) + 1.0
        rear = float(np.linalg.norm(s.nacelle_centre - s.hub)) + float(s.nacelle_half[0])
        self.down_off = -(max(rear + t_clear, d + s.max_half_chord()) + 1.0)
        # crossing: through the gap between blades whose bisector points highest
        bis = []
        for i in range(3):
            a, b = s.blades[i].axis, s.blades[(i + 1) % 3].axis
            m = a + b
            if float(np.linalg.norm(m)) < 1e-9:
                continue
            bis.append(m / np.linalg.norm(m))
        gap = max(bis, key=lambda v: float(v[2])) if bis else s.up
        a_max = s.max_half_chord()
        radius = max((d + a_max) / math.sin(math.radians(60.0)),
                     d + float(np.max(s.spinner_radii))) + 1.0
        self.cross = s.hub + radius * gap

    def _clear(self, pts: FloatArray) -> bool:
        q = densify(pts, 0.25)
        return bool(np.all(self.clear.rotor(q) >= self.d - 1e-6)
                    and np.all(self.clear.tower(q) >= self.t - 1e-6)
                    and np.all(q[:, 2] >= self.min_alt - 1e-6))

    def _offset(self, p: FloatArray) -> float:
        return float((p - self.s.hub) @ self.s.shaft)

    def _to_plane(self, p: FloatArray, off: float) -> FloatArray:
        return p + (off - self._offset(p)) * self.s.shaft

    def connect(self, a: Waypoint, b: Waypoint) -> list[Waypoint] | None:
        """Transit points from ``a`` to ``b`` (none: straight), or None if no route
        clears."""
        pa, pb = a.position, b.position
        if self._clear(np.stack([pa, pb])):
            return []
        both_tower = a.part == TOWER and b.part == TOWER
        blade = a.part if a.part == b.part and 0 <= a.part < 3 else -1
        ea, eb = self._exits(a), self._exits(b)
        # from the stations themselves, else first stepping out of where they are (a
        # station just at the stand-off from one part and the clearance from another)
        for ends in ([(pa, pb)],
                     [(q, pb) for q in ea] + [(pa, q) for q in eb]
                     + list(itertools.product(ea[:2], eb[:2]))):
            tries = []
            for qa, qb in ends:
                for r in self._routes(qa, qb, both_tower, blade):
                    pts = np.stack([pa, qa, *r, qb, pb])
                    pts[:, 2] = np.maximum(pts[:, 2], self.min_alt)
                    tries.append(drop_close(pts))
            for pts in sorted(tries, key=path_length):  # the shortest clear route
                if self._clear(pts):
                    return [self._transit(p, b) for p in pts[1:-1]]
        return None

    def _exits(self, w: Waypoint) -> list[FloatArray]:
        """Points :data:`BACK_OFF` metres from photo station ``w``: back against its view
        (first), either way along its part's axis and round it; those themselves clear."""
        if not w.photo:
            return []
        view = view_dir(w)
        axis = self.s.blades[w.part].axis if w.part < 3 else np.array([0.0, 0.0, 1.0])
        across = np.cross(axis, view)
        n = float(np.linalg.norm(across))
        dirs = [-view, axis, -axis] + ([across / n, -across / n] if n > 1e-6 else [])
        q = np.array([w.position + back * v for v in dirs for back in BACK_OFF])
        ok = ((self.clear.rotor(q) >= self.d - 1e-6) & (self.clear.tower(q) >= self.t - 1e-6)
              & (q[:, 2] >= self.min_alt - 1e-6))
        return list(q[ok])

    @staticmethod
    def _transit(p: FloatArray, b: Waypoint) -> Waypoint:
        """A transit point at ``p`` looking level towards ``b``."""
        v = b.position - p
        yaw = math.atan2(v[1], v[0]) if float(np.linalg.norm(v)) > 1e-9 else b.yaw
        return Waypoint(np.asarray(p, dtype=np.float64), yaw, 0.0)

    def _routes(self, pa: FloatArray, pb: FloatArray, tower: bool, blade: int
                ) -> list[list[FloatArray]]:
        """Transit points between ``pa`` and ``pb`` to try: none (straight),
        round the blade (``blade``: both are stations of that blade, else -1), round the
        tower at the lower height (``tower``: both are tower stations), through the
        upwind or the downwind transit plane, across between them."""
        routes: list[list[FloatArray]] = [[]]
        if blade >= 0:
            routes.append(self._round_blade(pa, pb, blade))
        if tower:
            z = min(pa[2], pb[2])
            c = self.s.base[:2]
            ra, rb = pa[:2] - c, pb[:2] - c
            a0, a1 = math.atan2(ra[1], ra[0]), math.atan2(rb[1], rb[0])
            da = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
            rad = 0.5 * (float(np.linalg.norm(ra)) + float(np.linalg.norm(rb)))
            routes.append([np.array([c[0] + rad * math.cos(a0 + t * da),
                                     c[1] + rad * math.sin(a0 + t * da), z])
                           for t in np.linspace(0.0, 1.0, 7)])
        for plane in (self.up_off, self.down_off):
            routes.append([self._to_plane(pa, plane), self._to_plane(pb, plane)])
        for pa_plane, pb_plane in ((self.up_off, self.down_off), (self.down_off, self.up_off)):
            routes.append([self._to_plane(pa, pa_plane), self._to_plane(self.cross, pa_plane),
                           self._to_plane(self.cross, pb_plane), self._to_plane(pb, pb_plane)])
        return routes

    def _round_blade(self, pa: FloatArray, pb: FloatArray, blade: int) -> list[FloatArray]:
        """Points round blade ``blade``'s axis from ``pa``'s side of it to ``pb``'s, in the
        middle of turns of at most :data:`ARC_STEP_DEG`, far enough out that the legs
        between them keep the larger of the two distances from the axis (the legs from
        ``pa`` and to ``pb`` run along that circle's tangents; the span changes evenly):
        a straight leg between stations looking at the blade from directions a few
        degrees apart cuts inside their distance from it."""
        bl = self.s.blades[blade]
        wa, wb = pa - bl.root, pb - bl.root
        sa, sb = float(wa @ bl.axis), float(wb @ bl.axis)
        ua, ub = wa - sa * bl.axis, wb - sb * bl.axis
        ra, rb = float(np.linalg.norm(ua)), float(np.linalg.norm(ub))
        if min(ra, rb) < 1e-9:
            return []
        angle = math.atan2(float(bl.axis @ np.cross(ua, ub)), float(ua @ ub))
        n = max(1, math.ceil(abs(math.degrees(angle)) / ARC_STEP_DEG))
        radius = max(ra, rb) / math.cos(0.5 * angle / n)
        return [bl.root + (sa + t * (sb - sa)) * bl.axis
                + radius * rotate(ua / ra, bl.axis, t * angle)
                for t in (np.arange(n) + 0.5) / n]

