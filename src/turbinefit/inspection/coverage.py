"""What each keyframe of an inspection shows: per blade and the tower, the span in view,
the sides seen, the distance and the ground sampling distance; and the best resolution
reached over the flight on each side of each part, span by span.

Each part is sampled along its axis every ``step`` metres (blades from the spinner's edge
to the tip, the tower from the ground to the nacelle's underside). A sample is in view of
a keyframe if it projects inside the photo and the ray from the camera to it meets that
part first (:meth:`~turbinefit.inspection.surface.TurbineSurface.cast_rays`: the tower,
the nacelle, the hub or another blade in front hide it). Its side is the side the ray
sees (:mod:`turbinefit.inspection.surface`), and its ground sampling distance
``GSD = 1000 z / f`` mm per pixel, with ``z`` the depth of the surface point the ray
meets along the optical axis and ``f = sqrt(fx fy)`` the focal length in pixels (the size
of a pixel on a surface facing the camera; a surface seen obliquely is sampled more
coarsely across the slant, which this figure leaves out).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.inspection.surface import (
    BLADE_SIDES,
    PARTS,
    TOWER,
    TOWER_FACES,
    FloatArray,
    TurbineSurface,
)

#: The parts whose coverage is accumulated: the three blades and the tower.
COVERED_PARTS = PARTS[:4]
#: Columns of ``coverage.csv`` (one row per keyframe and part in view).
COVERAGE_COLUMNS = ("timestamp", "keyframe", "part", "span_from_m", "span_to_m", "visible_m",
                    "sides", "distance_m", "gsd_mm_px")


def side_names(part: int) -> tuple[str, ...]:
    """The side names of part ``part`` (index into :data:`PARTS`)."""
    return TOWER_FACES if part == TOWER else BLADE_SIDES


@dataclass(frozen=True)
class PartInView:
    """What one keyframe shows of one part (one row of ``coverage.csv``).

    Attributes:
        keyframe: keyframe index.
        part: index into :data:`~turbinefit.inspection.surface.PARTS`.
        span_from, span_to: the span in view [m] (blade: from the hub centre; tower: above
            the ground), first and last sample widened by half a step.
        visible_m: length of the span in view [m] (gaps left out).
        sides: the sides seen, most samples first.
        distance_m: camera to the nearest surface point in view [m].
        gsd_mm_px: the best ground sampling distance in view [mm per pixel].
    """

    keyframe: int
    part: int
    span_from: float
    span_to: float
    visible_m: float
    sides: tuple[str, ...]
    distance_m: float
    gsd_mm_px: float


@dataclass
class SideGrid:
    """The best resolution reached on each side of one part, span by span.

    Attributes:
        part: index into :data:`~turbinefit.inspection.surface.PARTS`.
        spans: centres of the span bins [m] (n,), ``step`` apart.
        step: bin width [m].
        best_gsd: (4, n) the smallest GSD [mm/px] any keyframe reached on each side (rows in
            the order of :func:`side_names`) and bin; inf: never seen.
        best_keyframe: (4, n) the keyframe that reached it (-1: none).
    """

    part: int
    spans: FloatArray
    step: float
    best_gsd: FloatArray
    best_keyframe: NDArray[np.int64]

    def covered(self, max_gsd_mm: float = math.inf) -> FloatArray:
        """Fraction (4,) of each side's span seen at ``max_gsd_mm`` mm/px or finer."""
        if self.spans.size == 0:
            return np.zeros(4)
        return np.mean(np.isfinite(self.best_gsd) & (self.best_gsd <= max_gsd_mm), axis=1)


@dataclass
class Coverage:
    """What a flight shows (:func:`flight_coverage`): rows per keyframe and part, and the
    per-side grids of :data:`COVERED_PARTS` (in that order)."""

    rows: list[PartInView]
    grids: list[SideGrid]
    step: float

    def summary(self, max_gsd_mm: float) -> dict[str, dict[str, dict[str, float]]]:
        """Per part and side: the fraction of the span seen at all and at ``max_gsd_mm``
        or finer, and the median best GSD where seen."""
        out: dict[str, dict[str, dict[str, float]]] = {}
        for g in self.grids:
            seen, fine = g.covered(), g.covered(max_gsd_mm)
            sides = {}
            for k, name in enumerate(side_names(g.part)):
                row = g.best_gsd[k][np.isfinite(g.best_gsd[k])]
                sides[name] = {"seen": round(float(seen[k]), 4),
                               "covered": round(float(fine[k]), 4),
                               "median_best_gsd_mm_px": round(float(np.median(row)), 3)
                               if row.size else math.nan}
            out[PARTS[g.part]] = sides
        return out


def part_samples(surface: TurbineSurface, part: int, step: float) -> tuple[FloatArray, FloatArray]:
    """Sample spans (n,) and their axis points (n, 3) of part ``part`` (a blade or the
    tower), ``step`` metres apart, centred in their bins (see the module docstring)."""
    if part == TOWER:
        start = float(surface.base[2])
        end = float(surface.nacelle_centre[2] - surface.nacelle_half[2])
        end = max(end, start + step)
        spans = np.arange(start + 0.5 * step, end, step)
        pts = np.stack([np.full(spans.size, surface.base[0]), np.full(spans.size, surface.base[1]),
                        spans], axis=-1)
        return spans, pts
    bl = surface.blades[part]
    start = surface.spinner_radii[1]
    spans = np.arange(start + 0.5 * step, bl.length, step)
    return spans, bl.root + spans[:, None] * bl.axis


def sample_views(surface: TurbineSurface, camera: PinholeCamera, world_R_cam: FloatArray,
                 world_p_cam: FloatArray, part: int, world_p: FloatArray
                 ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], FloatArray,
                            FloatArray]:
    """Which samples ``world_p`` (m, 3) on the axis of part ``part`` each of k cameras
    (rotations ``world_R_cam`` (k, 3, 3), positions ``world_p_cam`` (k, 3)) shows (the
    module docstring's rules: in the photo, the ray meeting that part first): the pairs
    (camera ``kk``, sample ``mm``) in view, with the side seen there (index into
    :func:`side_names`), the distance along the ray [m] and the GSD [mm/px]."""
    f = math.sqrt(camera.fx * camera.fy)
    R, o = world_R_cam, world_p_cam
    # camera-frame samples (k, m, 3): R^T (p - o)
    cam_p = np.einsum("kji,kmj->kmi", R, world_p[None, :, :] - o[:, None, :])
    _, ok, _ = camera.project(cam_p)
    kk, mm = np.nonzero(ok)
    if kk.size == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty, np.zeros(0), np.zeros(0)
    ray = world_p[mm] - o[kk]
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    hits = surface.cast_rays(o[kk], ray)
    seen = hits.part == part
    kk, mm = kk[seen], mm[seen]
    dist, side = hits.distance[seen], hits.side[seen]
    depth = dist * np.einsum("ij,ij->i", ray[seen], R[kk, :, 2])
    return kk, mm, side, dist, 1000.0 * depth / f


def flight_coverage(surface: TurbineSurface, camera: PinholeCamera, world_T_cam: SE3,
                    step: float = 0.5, chunk: int = 256) -> Coverage:
    """What each keyframe ``world_T_cam`` (N,) of a flight with photos of ``camera`` shows
    of the turbine ``surface`` (see the module docstring); parts sampled every ``step`` m,
    ``chunk`` keyframes at a time."""
    if not step > 0:
        raise ValueError(f"step must be positive, got {step}")
    poses = SE3(world_T_cam.wxyz_xyz.reshape(-1, 7))
    n = len(poses)
    rows: list[PartInView] = []
    grids = []
    samples = [part_samples(surface, p, step) for p in range(len(COVERED_PARTS))]
    for p, (spans, _) in enumerate(samples):
        grids.append(SideGrid(p, spans, step, np.full((4, spans.size), np.inf),
                              np.full((4, spans.size), -1, dtype=np.int64)))
    R_all = poses.rotation_matrix()  # world_R_cam (N, 3, 3)
    o_all = poses.translation
    for k0 in range(0, n, chunk):
        ks = np.arange(k0, min(n, k0 + chunk))
        R, o = R_all[ks], o_all[ks]
        found: dict[tuple[int, int], tuple[FloatArray, NDArray[np.int64], FloatArray,
                                           FloatArray]] = {}
        for p, (spans, pts) in enumerate(samples):
            if spans.size == 0:
                continue
            kk, mm, side, dist, gsd = sample_views(surface, camera, R, o, p, pts)
            if kk.size == 0:
                continue
            g = grids[p]
            before = g.best_gsd[side, mm]
            np.minimum.at(g.best_gsd, (side, mm), gsd)
            sel = (gsd < before) & (gsd == g.best_gsd[side, mm])
            g.best_keyframe[side[sel], mm[sel]] = ks[kk[sel]]
            for k in np.unique(kk):
                m = kk == k
                found[(int(k), p)] = (spans[mm[m]], side[m], dist[m], gsd[m])
        for (k, p) in sorted(found):
            s, side, dist, gsd = found[(k, p)]
            names = side_names(p)
            counts = Counter(int(x) for x in side)
            rows.append(PartInView(
                int(ks[k]), p, float(s.min() - 0.5 * step), float(s.max() + 0.5 * step),
                float(s.size * step), tuple(names[i] for i, _ in counts.most_common()),
                float(dist.min()), float(gsd.min())))
    return Coverage(rows, grids, step)
