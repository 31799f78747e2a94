"""How far points and flight paths keep from the turbine's solid: the check every path is
put to before it is flown (``plan`` runs it on its own path before writing it; a path of
poses given to the simulator, or a path replanned in flight, is checked the same way).

**The solid** is :class:`~turbinefit.inspection.surface.TurbineSurface`'s: the tapered
tower from the ground up to where it meets the nacelle, the nacelle box, the spinner
ellipsoid and the three blades of elliptic sections (:func:`TurbineSurface.blade_section`)
with the surface's pitch and twist, each blade closed at its root and its tip by a flat
cap, as :func:`~turbinefit.turbine.solid.solid_mesh` closes them.

**Distances.** Each part's surface is sampled densely (rings across its axis, caps in
concentric rings, the nacelle's faces in grids) so that every point of the surface is
within :attr:`SolidSamples.tolerance` of a sample (0.15 m at the default spacing); the
nearest sample is found with a k-d tree (:class:`scipy.spatial.cKDTree`), and its distance
less the tolerance is a lower bound of the distance to the part. A point inside a part
(exact containment tests of the same shapes) gets a negative distance. Along a straight
leg from ``a`` to ``b`` sampled at points ``p_0 .. p_m`` the distance to a part is at
least ``(d_i + d_(i+1) - |p_i p_(i+1)|) / 2`` between neighbours (a distance to a set
changes by at most the distance moved), so a leg's bound holds for every point of it, not
only the samples, and a leg crossing a part between two samples gets a bound <= 0.

**Why sampling, not closed forms.** The check must not share the planner's arithmetic
(:mod:`turbinefit.inspection.plan` bounds distances to each shape in closed form): a bug
there must show here. Sampling needs only the surface's parametrisation, and its error is
one number, bounded by construction and measured in the tests. Exact distances to the
blades (sections that change size and turn along the span) need a minimisation per point;
the triangle mesh of :func:`~turbinefit.turbine.solid.solid_mesh` is the renderer's solid
(always twisted), inscribed in the surface (its facets lie inside by up to the sagitta of
a 16-gon), and trimesh's closest-point query (a dev-only dependency here) needs rtree.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from turbinefit.inspection.surface import (
    HUB,
    NACELLE,
    PARTS,
    TOWER,
    FloatArray,
    IntArray,
    TurbineSurface,
)

#: The rotor's parts (blades A, B, C and the spinner) and the structure's (tower,
#: nacelle), as indices into :data:`~turbinefit.inspection.surface.PARTS`.
ROTOR = (0, 1, 2, HUB)
STRUCTURE = (TOWER, NACELLE)
#: Default spacing of the samples on the surface [m] (tolerance about the same).
SPACING = 0.15
#: Default spacing of the samples along a leg [m] (the bound holds between them).
LEG_STEP = 0.25
#: Approximation of the k-d tree's quick search: a neighbour at most 1 + this times as
#: far as the nearest.
APPROX_EPS = 1.0
#: Leaf size of the k-d trees (larger than scipy's 16: a third faster on samples lying on
#: thin surfaces).
LEAF_SIZE = 64


@dataclass(frozen=True)
class SolidSamples:
    """A turbine solid's surface sampled for distance queries (:func:`solid_samples`).

    Attributes:
        surface: the surface sampled.
        points: per part (:data:`~turbinefit.inspection.surface.PARTS` order) the samples
            (m_k, 3) [m, world].
        tolerance: every point of the surface lies within this distance [m] of a sample of
            its part.
    """

    surface: TurbineSurface
    points: tuple[FloatArray, ...]
    tolerance: float
    trees: tuple[cKDTree, ...]

    @property
    def size(self) -> int:
        return sum(len(p) for p in self.points)


@dataclass(frozen=True)
class PathClearance:
    """How far a path keeps from the solid (:func:`path_clearance`); all distances are
    lower bounds, at most :attr:`tolerance` below the true ones, negative inside a part.

    Attributes:
        by_part: (N, 6) distance of each path point from each part [m].
        leg_by_part: (N - 1, 6) least distance of each straight leg (point i to i + 1) from
            each part [m].
        tolerance: the samples' tolerance [m].
    """

    by_part: FloatArray
    leg_by_part: FloatArray
    tolerance: float

    @property
    def distance(self) -> FloatArray:
        """(N,) least distance of each point from the solid [m]."""
        return self.by_part.min(axis=1)

    @property
    def part(self) -> IntArray:
        """(N,) the part nearest each point (index into ``PARTS``)."""
        return np.argmin(self.by_part, axis=1).astype(np.int64)

    @property
    def leg_distance(self) -> FloatArray:
        """(N - 1,) least distance of each leg from the solid [m]."""
        return self.leg_by_part.min(axis=1)

    @property
    def leg_part(self) -> IntArray:
        """(N - 1,) the part each leg comes nearest."""
        return np.argmin(self.leg_by_part, axis=1).astype(np.int64)

    def least(self, parts: tuple[int, ...] = tuple(range(len(PARTS))), legs: bool = True
              ) -> tuple[float, int, int, bool]:
        """The least distance from ``parts`` (points and, with ``legs``, legs): (distance
        [m], the part, the index of the point or leg, whether it is a leg). An empty path
        gives (inf, -1, -1, False)."""
        cols = list(parts)
        best = (math.inf, -1, -1, False)
        for a, is_leg in ((self.by_part, False), (self.leg_by_part, True)):
            if is_leg and not legs:
                continue
            if a.size == 0:
                continue
            sub = a[:, cols]
            i, j = np.unravel_index(int(np.argmin(sub)), sub.shape)
            if float(sub[i, j]) < best[0]:
                best = (float(sub[i, j]), cols[int(j)], int(i), is_leg)
        return best

    def first_below(self, clearance: float, parts: tuple[int, ...] = tuple(range(len(PARTS)))
                    ) -> int | None:
        """The first point whose distance from ``parts`` is below ``clearance`` [m], or
        whose leg to the next point is, or None (a path of poses: the first pose at fault)."""
        cols = list(parts)
        bad = self.by_part[:, cols].min(axis=1) < clearance
        if len(self.leg_by_part):
            bad[:-1] |= self.leg_by_part[:, cols].min(axis=1) < clearance
        hits = np.flatnonzero(bad)
        return int(hits[0]) if hits.size else None


# ---- sampling the surface --------------------------------------------------------------------


def _ellipse_rings(centres: FloatArray, ax: FloatArray, ay: FloatArray, rx: FloatArray,
                   ry: FloatArray, spacing: float) -> tuple[FloatArray, float]:
    """Samples on k elliptic rings (centres (k, 3), unit axes ax, ay (k, 3), semi-axes rx,
    ry (k,)): each ring with points at most ``spacing`` apart along it. Returns the points
    and the tolerance of the ring stack: half the longest arc along a ring plus half the
    longest arc between neighbouring rings at the same angle (any point of the surface
    between two rings reaches a sample along those two arcs)."""
    k = len(centres)
    big = np.maximum(np.maximum(rx, ry), 1e-9)
    n = np.maximum(np.ceil(2.0 * math.pi * big / spacing).astype(np.int64), 8)
    out = []
    for i in range(k):
        phi = 2.0 * math.pi * np.arange(n[i]) / n[i]
        out.append(centres[i] + (rx[i] * np.cos(phi))[:, None] * ax[i]
                   + (ry[i] * np.sin(phi))[:, None] * ay[i])
    ring_arc = float(np.max(2.0 * math.pi * big / n))  # the speed along a ring <= max(rx, ry)
    across = 0.0
    if k > 1:  # arcs between rings at fixed angle: chords of 4 sub-steps, 64 angles
        phi = 2.0 * math.pi * np.arange(64) / 64

        def at(t: FloatArray) -> FloatArray:  # (k-1, m, 3) at fraction t between rings
            c = centres[:-1] + t * (centres[1:] - centres[:-1])
            x = ax[:-1] + t * (ax[1:] - ax[:-1])
            y = ay[:-1] + t * (ay[1:] - ay[:-1])
            a = rx[:-1] + t * (rx[1:] - rx[:-1])
            b = ry[:-1] + t * (ry[1:] - ry[:-1])
            return (c[:, None] + (a[:, None] * np.cos(phi))[..., None] * x[:, None]
                    + (b[:, None] * np.sin(phi))[..., None] * y[:, None])

        pts = [at(t) for t in np.linspace(0.0, 1.0, 5)]
        arc = sum(np.linalg.norm(q - p, axis=-1) for p, q in itertools.pairwise(pts))
        across = 1.02 * float(np.max(arc))  # the chords of the sub-steps, with a margin
    return np.concatenate(out), 0.5 * (ring_arc + across)


def _cap(centre: FloatArray, ax: FloatArray, ay: FloatArray, rx: float, ry: float,
         spacing: float) -> tuple[FloatArray, float]:
    """Samples on a flat elliptic disc: concentric rings from the centre out."""
    m = max(1, math.ceil(max(rx, ry) / spacing))
    f = np.linspace(0.0, 1.0, m + 1)
    k = len(f)
    return _ellipse_rings(np.tile(centre, (k, 1)), np.tile(ax, (k, 1)), np.tile(ay, (k, 1)),
                          f * rx, f * ry, spacing)


def _ring_params(lo: float, hi: float, spacing: float) -> FloatArray:
    return np.linspace(lo, hi, max(2, math.ceil((hi - lo) / spacing) + 1))


def _blade_frame(surface: TurbineSurface, i: int, s: FloatArray
                 ) -> tuple[FloatArray, FloatArray]:
    """The chord and thickness directions (k, 3) of blade ``i`` at spans ``s``, turned by
    the surface's twist."""
    bl = surface.blades[i]
    tw = surface.twist(s)[:, None]
    chord = np.cos(tw) * bl.chord + np.sin(tw) * bl.normal
    normal = np.cos(tw) * bl.normal - np.sin(tw) * bl.chord
    return chord, normal


def solid_samples(surface: TurbineSurface, spacing: float = SPACING) -> SolidSamples:
    """The surface of ``surface``'s solid sampled at about ``spacing`` metres (see the
    module docstring); about 0.17 million samples for the demo's 63 m blades and 88 m tower at 0.15 m."""
    parts: list[list[FloatArray]] = [[] for _ in PARTS]
    tol = 0.0

    def add(k: int, sampled: tuple[FloatArray, float]) -> None:
        nonlocal tol
        parts[k].append(sampled[0])
        tol = max(tol, sampled[1])

    for i, bl in enumerate(surface.blades):
        s = _ring_params(0.0, bl.length, spacing)
        A, B = surface.blade_section(s)
        chord, normal = _blade_frame(surface, i, s)
        centres = bl.root + s[:, None] * bl.axis
        add(i, _ellipse_rings(centres, chord, normal, A, B, spacing))
        for j in (0, -1):
            add(i, _cap(centres[j], chord[j], normal[j], float(A[j]), float(B[j]), spacing))
    so = surface.solid
    base = surface.base
    top = float(so.tower_top_z)
    z = _ring_params(float(base[2]), top, spacing)
    r = so.r0 + (so.r1 - so.r0) * (z - base[2]) / max(top - float(base[2]), 1e-9)
    ex, ey = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    k = len(z)
    centres = np.column_stack([np.full(k, base[0]), np.full(k, base[1]), z])
    add(TOWER, _ellipse_rings(centres, np.tile(ex, (k, 1)), np.tile(ey, (k, 1)), r, r, spacing))
    for j in (0, -1):
        add(TOWER, _cap(centres[j], ex, ey, float(r[j]), float(r[j]), spacing))
    # spinner: rings between its poles on the shaft, the poles themselves as rings of radius 0
    a_len, a_r = float(so.spin_len), float(so.spin_r)
    n_lat = max(2, math.ceil(math.pi * max(a_len, a_r) / (0.5 * spacing)) + 1)
    lat = np.linspace(-0.5 * math.pi, 0.5 * math.pi, n_lat)
    k = len(lat)
    centres = so.spin_centre + (a_len * np.sin(lat))[:, None] * so.shaft
    rad = a_r * np.cos(lat)
    add(HUB, _ellipse_rings(centres, np.tile(so.side, (k, 1)), np.tile(so.up, (k, 1)), rad, rad,
                            spacing))
    # nacelle: a grid on each face
    E = np.stack([so.shaft, so.side, so.up])
    half = np.asarray(so.nac_half, dtype=np.float64)
    for ax in range(3):
        u, v = [j for j in range(3) if j != ax]
        nu = max(1, math.ceil(2.0 * half[u] / spacing))
        nv = max(1, math.ceil(2.0 * half[v] / spacing))
        gu, gv = np.meshgrid(np.linspace(-half[u], half[u], nu + 1),
                             np.linspace(-half[v], half[v], nv + 1), indexing="ij")
        for sign in (-1.0, 1.0):
            local = np.zeros((gu.size, 3))
            local[:, ax] = sign * half[ax]
            local[:, u], local[:, v] = gu.ravel(), gv.ravel()
            cell = math.hypot(2.0 * half[u] / nu, 2.0 * half[v] / nv)
            add(NACELLE, (so.nac_centre + local @ E, 0.5 * cell))
    points = tuple(np.concatenate(p) for p in parts)
    return SolidSamples(surface, points, tol, tuple(cKDTree(p, leafsize=LEAF_SIZE) for p in points))


# ---- containment --------------------------------------------------------------------------


def inside(surface: TurbineSurface, world_p: ArrayLike) -> NDArray[np.bool_]:
    """(N, 6) whether each point lies inside each part of the solid (exact tests of the
    shapes of the module docstring, boundaries included)."""
    p = np.asarray(world_p, dtype=np.float64).reshape(-1, 3)
    out = np.zeros((len(p), len(PARTS)), dtype=bool)
    for i, bl in enumerate(surface.blades):
        w = p - bl.root
        s = w @ bl.axis
        on = (s >= 0.0) & (s <= bl.length)
        if not np.any(on):
            continue
        A, B = surface.blade_section(s[on])
        chord, normal = _blade_frame(surface, i, s[on])
        x = np.einsum("ij,ij->i", w[on], chord) / np.maximum(A, 1e-12)
        y = np.einsum("ij,ij->i", w[on], normal) / np.maximum(B, 1e-12)
        out[np.flatnonzero(on), i] = x * x + y * y <= 1.0
    so = surface.solid
    base = surface.base
    top = float(so.tower_top_z)
    h = max(top - float(base[2]), 1e-9)
    zr = np.clip((p[:, 2] - base[2]) / h, 0.0, 1.0)
    rad = so.r0 + (so.r1 - so.r0) * zr
    out[:, TOWER] = ((p[:, 2] >= base[2]) & (p[:, 2] <= top)
                     & (np.hypot(p[:, 0] - base[0], p[:, 1] - base[1]) <= rad))
    E = np.stack([so.shaft, so.side, so.up])
    out[:, NACELLE] = np.all(np.abs((p - so.nac_centre) @ E.T) <= so.nac_half, axis=1)
    semi = np.array([so.spin_len, so.spin_r, so.spin_r])
    out[:, HUB] = np.sum((((p - so.spin_centre) @ E.T) / semi) ** 2, axis=1) <= 1.0
    return out


# ---- distances ----------------------------------------------------------------------------


def point_clearance(world_p: ArrayLike, solid: TurbineSurface | SolidSamples,
                    exact_below: float | ArrayLike = math.inf) -> FloatArray:
    """(N, 6) distance [m] of each point (N, 3) from each part of the solid: a lower bound,
    negative inside the part, at most the samples' tolerance below the true distance where
    it is below ``exact_below`` (a number, or one per part); elsewhere a looser lower bound
    (at least ``exact_below``: half the distance of an approximate neighbour, found ten
    times faster than the nearest).

    Raises:
        ValueError: a point is not finite.
    """
    samples = solid if isinstance(solid, SolidSamples) else solid_samples(solid)
    p = np.asarray(world_p, dtype=np.float64).reshape(-1, 3)
    out = np.empty((len(p), len(PARTS)))
    if not len(p):
        return out
    if not np.all(np.isfinite(p)):
        raise ValueError("points must be finite")
    ins = inside(samples.surface, p)
    tol = samples.tolerance
    below = np.broadcast_to(np.asarray(exact_below, dtype=np.float64), (len(PARTS),))
    for k, tree in enumerate(samples.trees):
        if math.isinf(below[k]):
            d, _ = tree.query(p)
        else:
            approx, _ = tree.query(p, eps=APPROX_EPS)
            d = approx / (1.0 + APPROX_EPS)  # the nearest is at least this far
            near = (d - tol < below[k]) | ins[:, k]
            if np.any(near):
                d[near], _ = tree.query(p[near])
        out[:, k] = np.where(ins[:, k], -d, np.maximum(d - tol, 0.0))
    return out


def path_clearance(world_p_cam: ArrayLike, solid: TurbineSurface | SolidSamples,
                   leg_step: float = LEG_STEP, exact_below: float | ArrayLike = math.inf
                   ) -> PathClearance:
    """How far a path of camera (drone) positions (N, 3) [m, world], flown straight from
    each to the next, keeps from each part of the solid (see the module docstring).

    ``solid``: a surface, or its :func:`solid_samples` to reuse across calls (a path
    replanned in flight against the same turbine estimate). ``leg_step``: spacing [m] of
    the samples along the legs; a finer step makes the legs' bounds tighter, never wrong.
    ``exact_below``: distances [m] (one, or one per part) under which the answer must be
    within the tolerance (the clearance to check, :func:`point_clearance`); the legs are
    then within the tolerance plus ``leg_step`` / 2 of the truth there.

    Raises:
        ValueError: a point is not finite.
    """
    samples = solid if isinstance(solid, SolidSamples) else solid_samples(solid)
    p = np.asarray(world_p_cam, dtype=np.float64).reshape(-1, 3)
    below = np.asarray(exact_below, dtype=np.float64) + leg_step
    if len(p) < 2:
        return PathClearance(point_clearance(p, samples, below), np.empty((0, len(PARTS))),
                             samples.tolerance)
    if not np.all(np.isfinite(p)):
        raise ValueError("points must be finite")
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    n = np.maximum(np.ceil(seg / leg_step).astype(np.int64), 1)
    starts = np.concatenate([[0], np.cumsum(n)])  # leg i: dense points starts[i]..starts[i+1]
    leg = np.repeat(np.arange(len(n)), n)
    t = (np.arange(len(leg)) - starts[leg]) / n[leg]
    dense = np.concatenate([p[leg] + t[:, None] * (p[leg + 1] - p[leg]), p[-1:]])
    d = point_clearance(dense, samples, below)
    step = np.linalg.norm(np.diff(dense, axis=0), axis=1)
    pair = 0.5 * (d[:-1] + d[1:] - step[:, None])  # the least between neighbours
    leg_by_part = np.minimum.reduceat(pair, starts[:-1], axis=0)
    return PathClearance(d[starts], leg_by_part, samples.tolerance)
