"""Views added where a plan's stations leave a blade side unseen (:class:`Filler`; the
root near the hub, an edge beyond the gimbal's pitch, and with a position margin the ends
its stations show only from their exact poses): see :mod:`turbinefit.inspection.plan`'s
docstring and ``docs/inspection.md``."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import world_T_cam_from_angles
from turbinefit.inspection.coverage import part_samples, sample_views
from turbinefit.inspection.distances import PlannerDistances
from turbinefit.inspection.surface import FloatArray, IntArray, TurbineSurface
from turbinefit.inspection.waypoint import Waypoint

#: Views added where the stations leave a blade side uncovered (:class:`Filler`): turns
#: about the blade's axis [deg], tilts along it [deg] (positive: the camera further out
#: than the span it looks at), distances tried between the stand-off and the resolution's
#: (evenly), samples aimed at per round, rounds, the most views added per side, and the
#: sample spacing along the blade [m].
FILL_TURNS_DEG = (0.0, 15.0, -15.0, 30.0, -30.0, 40.0, -40.0)
FILL_TILTS_DEG = (0.0, 10.0, -10.0, 20.0, -20.0, 30.0, -30.0, 40.0, 50.0)
FILL_DISTANCES = 4
FILL_TARGETS = 10
FILL_ROUNDS = 2
FILL_MAX = 12
FILL_STEP = 0.25
#: Without a resolution asked for, the added views keep within this factor of the
#: resolution at the stand-off.
FILL_GSD_FACTOR = 1.25


class Filler:
    """Views added where the stations' photos leave a blade side uncovered (see the module
    docstring): the samples of the side along the blade (every :data:`FILL_STEP` metres)
    that no photo shows at the resolution ``goal_mm`` [mm/px] or finer, as
    :func:`~turbinefit.inspection.coverage.sample_views` judges (the coverage's own rules:
    in the photo, the ray meeting the blade first, on that side), are covered greedily by
    views aimed at them from the stand-off out to the distance of that resolution, turned
    about the blade's axis (:data:`FILL_TURNS_DEG`) and tilted along it
    (:data:`FILL_TILTS_DEG`), each view keeping the planner's clearances and the gimbal's
    pitch, its centre showing the side.

    With a position margin ``margin`` [m], a view shows a sample only if it does from
    each of seven positions: its own and ``margin`` metres off it either way along the
    camera's three axes (a drone that flies its waypoints to within the margin). The
    greedy choice then prefers the views that show most that way, and only where none
    does falls back to what the view shows from its own position."""

    def __init__(self, s: TurbineSurface, camera: PinholeCamera, clear: PlannerDistances,
                 dp: float, tp: float, min_alt: float, max_up: float, goal_mm: float,
                 margin: float = 0.0) -> None:
        self.s, self.camera, self.clear = s, camera, clear
        self.dp, self.tp, self.min_alt, self.max_up = dp, tp, min_alt, max_up
        self.goal = goal_mm
        self.margin = margin
        self.depth = goal_mm * math.sqrt(camera.fx * camera.fy) / 1000.0
        self.samples = [part_samples(s, i, FILL_STEP) for i in range(3)]

    def _shown(self, R: FloatArray, position: FloatArray, i: int, pts: FloatArray
               ) -> NDArray[np.bool_]:
        """(k, 4, m) whether each camera (rotations ``R`` (k, 3, 3), positions (k, 3))
        shows each sample ``pts`` (m, 3) of blade ``i`` on each side at the resolution
        asked for."""
        kk, mm, side, _, g = sample_views(self.s, self.camera, R, position, i, pts)
        out = np.zeros((len(position), 4, len(pts)), dtype=bool)
        fine = g <= self.goal
        out[kk[fine], side[fine], mm[fine]] = True
        return out

    def _seen(self, position: FloatArray, yaw: FloatArray, pitch: FloatArray, i: int,
              pts: FloatArray) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """(k, 4, m) twice: whether each view (k) shows each sample ``pts`` (m, 3) of blade
        ``i`` on each side at the resolution asked for from its own position, and from
        every position within the margin (the class docstring; the same array without a
        margin). The shifted positions are tried only for the views that show any of the
        blade from their own."""
        R = world_T_cam_from_angles(position, yaw, pitch, 0.0).rotation_matrix()
        R = R.reshape(-1, 3, 3)
        position = position.reshape(-1, 3)
        seen = self._shown(R, position, i, pts)
        if self.margin <= 0.0:
            return seen, seen
        some = np.flatnonzero(seen.any(axis=(1, 2)))
        sure = np.zeros_like(seen)
        if some.size:
            Rs, k = R[some], len(some)
            shifts = [sign * self.margin * e for e in np.eye(3) for sign in (1.0, -1.0)]
            # every shifted copy of every view at once: copy j of view v is row j * k + v
            moved = self._shown(np.concatenate([Rs] * len(shifts)),
                                np.concatenate([position[some] + np.einsum("kij,j->ki", Rs, d)
                                                for d in shifts]), i, pts)
            sure[some] = seen[some] & moved.reshape(len(shifts), k, 4, len(pts)).all(axis=0)
        return seen, sure

    def covered(self, photos: list[Waypoint], i: int, robust: bool = False
                ) -> NDArray[np.bool_]:
        """(4, m) the samples of blade ``i``'s sides ``photos`` show (``robust``: from
        anywhere within the margin)."""
        pts = self.samples[i][1]
        if not photos:
            return np.zeros((4, len(pts)), dtype=bool)
        seen, sure = self._seen(np.array([w.position for w in photos]),
                                np.array([w.yaw for w in photos]),
                                np.array([w.pitch for w in photos]), i, pts)
        return np.asarray((sure if robust else seen).any(axis=0), dtype=bool)

    def _candidates(self, i: int, side: int, targets: IntArray
                    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """The views aimed at samples ``targets`` that keep the clearances and the gimbal's
        pitch and whose centre shows the side: positions (k, 3), yaws, pitches, spans aimed
        at and distances (k,)."""
        s, bl = self.s, self.s.blades[i]
        spans, pts = self.samples[i][0][targets], self.samples[i][1][targets]
        A, B = s.blade_section(spans)
        tw = s.twist(spans)[:, None]
        chord = np.cos(tw) * bl.chord + np.sin(tw) * bl.normal
        normal = np.cos(tw) * bl.normal - np.sin(tw) * bl.chord
        n = [chord, normal, -chord, -normal][side]  # (t, 3), across the axis
        turn = np.radians(FILL_TURNS_DEG)[None, :, None]
        o = np.cos(turn) * n[:, None] + np.sin(turn) * np.cross(bl.axis, n)[:, None]
        ext = np.hypot(A[:, None] * np.einsum("tuj,tj->tu", o, chord),
                       B[:, None] * np.einsum("tuj,tj->tu", o, normal))
        tilt = np.radians(FILL_TILTS_DEG)[None, None, :, None]
        u = np.cos(tilt) * o[:, :, None] + np.sin(tilt) * bl.axis  # (t, u, v, 3)
        lo = self.dp + ext
        hi = np.maximum(lo, self.depth + ext)
        q = np.linspace(0.0, 1.0, FILL_DISTANCES)
        r = lo[..., None] + (hi - lo)[..., None] * q  # (t, u, d)
        shape = (len(spans), len(FILL_TURNS_DEG), len(FILL_TILTS_DEG), FILL_DISTANCES)
        r4 = np.broadcast_to(r[:, :, None, :], shape)
        c = pts[:, None, None, None] + r4[..., None] * u[:, :, :, None]
        view = -np.broadcast_to(u[:, :, :, None], c.shape)
        c, view, r4 = c.reshape(-1, 3), view.reshape(-1, 3), r4.reshape(-1)
        span = np.broadcast_to(spans[:, None, None, None], shape).reshape(-1)
        pitch = np.arcsin(np.clip(view[:, 2], -1.0, 1.0))
        ok = (pitch <= self.max_up) & (c[:, 2] >= self.min_alt)
        ok[ok] = (self.clear.rotor(c[ok]) >= self.dp) & (self.clear.tower(c[ok]) >= self.tp)
        if np.any(ok):
            hits = s.cast_rays(c[ok], view[ok])
            ok[ok] = (hits.part == i) & (hits.side == side)
        yaw = np.arctan2(view[ok, 1], view[ok, 0])
        return c[ok], yaw, pitch[ok], span[ok], r4[ok]

    def fill(self, i: int, side: int, covered: NDArray[np.bool_]) -> list[Waypoint]:
        """The views added to cover side ``side`` of blade ``i`` where ``covered`` (4, m)
        says no photo does (see the class docstring)."""
        pts = self.samples[i][1]
        todo = ~covered[side]
        tried = np.zeros(len(pts), dtype=bool)
        added: list[Waypoint] = []
        for _ in range(FILL_ROUNDS):
            idx = np.flatnonzero(todo & ~tried)
            if idx.size == 0:
                break
            targets = idx[np.unique(np.round(np.linspace(0, idx.size - 1,
                                                         min(idx.size, FILL_TARGETS))).astype(int))]
            tried[targets] = True
            c, yaw, pitch, span, dist = self._candidates(i, side, targets)
            if not len(c):
                continue
            left = np.flatnonzero(todo)
            seen, held = self._seen(c, yaw, pitch, i, pts[left])
            gain, sure = seen[:, side], held[:, side]  # (k, m)
            while len(added) < FILL_MAX and gain.size:
                count, count_sure = gain.sum(axis=1), sure.sum(axis=1)
                # the view showing the most from anywhere within the margin, then from its
                # own position, of those the nearest
                k = int(np.lexsort((dist, -count, -count_sure))[0])
                if count[k] == 0:
                    break
                added.append(Waypoint(c[k].copy(), float(yaw[k]), float(pitch[k]), i, side,
                                      float(span[k])))
                shown = (sure[k] if count_sure[k] else gain[k]).copy()
                todo[left[shown]] = False
                gain[:, shown] = False
                sure[:, shown] = False
        return added
