"""Line-like clutter round a wind farm, which a net must learn not to take for a turbine:
power lines on lattice pylons, wooden distribution poles and their wires, fences and
buildings (:class:`Clutter`, drawn at random by :func:`sample_clutter`; world metres, z
up). The painter draws rods as thin tubes (sub-pixel wires faint, as a camera sees them)
and buildings as boxes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from turbinefit.sim.images.arrays import RGB
from turbinefit.turbine.model import TurbineParams

#: A rod: ends (x0, y0, z0), (x1, y1, z1) [m], radius [m] and colour (r, g, b).
Rod = tuple[float, float, float, float, float, float, float, float, float, float]
#: A box: centre (x, y, z), half sizes (hx, hy, hz) [m], yaw [rad] and colour (r, g, b).
Box = tuple[float, float, float, float, float, float, float, float, float, float]


@dataclass(frozen=True)
class Clutter:
    """The rods (pylons, wires, poles, fences) and boxes (buildings, platforms) of a scene."""

    rods: tuple[Rod, ...] = ()
    boxes: tuple[Box, ...] = ()


#: A scene without clutter.
NO_CLUTTER = Clutter()


def _rod(a: np.ndarray, b: np.ndarray, r: float, c: RGB) -> Rod:
    return (float(a[0]), float(a[1]), float(a[2]), float(b[0]), float(b[1]), float(b[2]),
            float(r), *c)


def _up(z: float) -> np.ndarray:
    return np.array([0.0, 0.0, z])


def _colour(rng: np.random.Generator, c: RGB, s: float = 0.08) -> RGB:
    v = np.clip(np.asarray(c) * np.exp(rng.normal(0.0, s)), 0.0, 1.0)
    return (float(v[0]), float(v[1]), float(v[2]))


def _wires(rods: list[Rod], a: np.ndarray, b: np.ndarray, sag: float, r: float, c: RGB,
           pieces: int) -> None:
    """A wire from a to b sagging ``sag`` [m] in the middle (a parabola in ``pieces``)."""
    t = np.linspace(0.0, 1.0, pieces + 1)
    pts = a[None] + t[:, None] * (b - a)[None]
    pts[:, 2] -= 4.0 * sag * t * (1.0 - t)
    for k in range(pieces):
        rods.append(_rod(pts[k], pts[k + 1], r, c))


def _power_line(rng: np.random.Generator, centre: np.ndarray, rods: list[Rod]) -> None:
    """A high-voltage line on lattice pylons passing 60-600 m from ``centre``."""
    d, ang, direc = rng.uniform(60.0, 600.0), rng.uniform(0, 2 * math.pi), rng.uniform(0, math.pi)
    u = np.array([math.cos(direc), math.sin(direc), 0.0])
    side = np.array([-u[1], u[0], 0.0])
    p0 = centre + d * np.array([math.cos(ang), math.sin(ang), 0.0])
    p0 = p0 - (p0 - centre) @ u * u  # the route's point nearest the turbine
    span, h = rng.uniform(280.0, 420.0), rng.uniform(24.0, 45.0)
    steel, wire = _colour(rng, (0.52, 0.54, 0.55)), _colour(rng, (0.22, 0.22, 0.23))
    offset = rng.uniform(0.0, span)
    tops: list[list[np.ndarray]] = []
    for k in range(-4, 5):
        base = p0 + (offset + (k - 0.5) * span) * u
        w0, w1 = 0.11 * h, 0.025 * h
        legs = []
        for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
            a = base + w0 * (sx * u + sy * side)
            b = base + w1 * (sx * u + sy * side) + np.array([0.0, 0.0, 0.82 * h])
            legs.append((a, b))
            rods.append(_rod(a, b, 0.18, steel))
        for q in range(4):  # one brace a face, crossing it
            (a0, b0), (a1, b1) = legs[q], legs[(q + 1) % 4]
            rods.append(_rod(a0, 0.5 * (b1 + a1), 0.07, steel))
            rods.append(_rod(a1, 0.5 * (b0 + a0), 0.07, steel))
        ends = []
        for z, half in ((0.68 * h, 0.2 * h), (0.82 * h, 0.15 * h)):
            c = base + np.array([0.0, 0.0, z])
            rods.append(_rod(c - half * side, c + half * side, 0.14, steel))
            ends += [c - half * side, c + half * side]
        peak = base + np.array([0.0, 0.0, h])
        rods.append(_rod(base + np.array([0.0, 0.0, 0.82 * h]), peak, 0.12, steel))
        tops.append([*ends, peak])
    sag = rng.uniform(0.02, 0.04) * span
    for k in range(len(tops) - 1):
        for a, b in zip(tops[k], tops[k + 1], strict=True):
            _wires(rods, a - _up(1.5), b - _up(1.5), sag, 0.025, wire, 4)


def _poles(rng: np.random.Generator, centre: np.ndarray,
           roads: tuple[tuple[float, float, float, float, float], ...], rods: list[Rod]) -> None:
    """A distribution line on wooden poles along a road (or anywhere), 2-3 wires."""
    if roads and rng.uniform() < 0.7:
        x0, y0, x1, y1, w = roads[int(rng.integers(len(roads)))]
        a, b = np.array([x0, y0, 0.0]), np.array([x1, y1, 0.0])
        u = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
        p0 = a + ((centre - a) @ u) * u + (w + rng.uniform(3.0, 8.0)) * np.array([-u[1], u[0], 0])
    else:
        direc = rng.uniform(0, math.pi)
        u = np.array([math.cos(direc), math.sin(direc), 0.0])
        p0 = centre + rng.uniform(30.0, 300.0) * np.array([-u[1], u[0], 0.0])
    h, span = rng.uniform(7.0, 11.0), rng.uniform(50.0, 90.0)
    wood, wire = _colour(rng, (0.35, 0.27, 0.2), 0.15), _colour(rng, (0.2, 0.2, 0.2))
    n_wires = int(rng.integers(2, 4))
    side = np.array([-u[1], u[0], 0.0])
    tops = []
    for k in range(-8, 9):
        base = p0 + (k * span + rng.normal(0.0, 2.0)) * u
        top = base + np.array([0.0, 0.0, h])
        rods.append(_rod(base, top, 0.13, wood))
        rods.append(_rod(top - 0.9 * side - _up(0.4), top + 0.9 * side - _up(0.4), 0.06, wood))
        tops.append([top - _up(0.45) + (q - 0.5 * (n_wires - 1)) * 0.8 * side
                     for q in range(n_wires)])
    for k in range(len(tops) - 1):
        for a, b in zip(tops[k], tops[k + 1], strict=True):
            _wires(rods, a, b, rng.uniform(0.3, 1.0), 0.012, wire, 2)


def _fences(rng: np.random.Generator, centre: np.ndarray, rods: list[Rod]) -> None:
    """1-3 post-and-wire fences 15-250 m from ``centre``."""
    for _ in range(int(rng.integers(1, 4))):
        d, ang, direc = rng.uniform(15.0, 250.0), rng.uniform(0, 2 * math.pi), rng.uniform(0, math.pi)
        u = np.array([math.cos(direc), math.sin(direc), 0.0])
        mid = centre + d * np.array([math.cos(ang), math.sin(ang), 0.0])
        length = rng.uniform(40.0, 300.0)
        a, b = mid - 0.5 * length * u, mid + 0.5 * length * u
        col = _colour(rng, (0.4, 0.33, 0.25) if rng.uniform() < 0.6 else (0.55, 0.56, 0.56), 0.15)
        n = min(30, max(2, int(length / rng.uniform(6.0, 12.0))))
        for k in range(n + 1):
            p = a + (k / n) * (b - a)
            rods.append(_rod(p, p + _up(1.3), 0.06, col))
        for z in (0.6, 1.15):
            rods.append(_rod(a + _up(z), b + _up(z), 0.025, col))


_BUILDING_COLOURS: tuple[RGB, ...] = ((0.82, 0.8, 0.76), (0.52, 0.26, 0.2), (0.5, 0.52, 0.53),
                                      (0.3, 0.38, 0.3), (0.7, 0.66, 0.55))


def _buildings(rng: np.random.Generator, centre: np.ndarray, boxes: list[Box]) -> None:
    """1-4 sheds, barns, houses or substations 40-700 m from ``centre``."""
    for _ in range(int(rng.integers(1, 5))):
        d, ang = rng.uniform(40.0, 700.0), rng.uniform(0, 2 * math.pi)
        hx, hy, hz = rng.uniform(3.0, 16.0), rng.uniform(2.5, 8.0), rng.uniform(1.5, 5.0)
        c = _colour(rng, _BUILDING_COLOURS[int(rng.integers(len(_BUILDING_COLOURS)))], 0.1)
        boxes.append((float(centre[0] + d * math.cos(ang)), float(centre[1] + d * math.sin(ang)),
                      float(hz), float(hx), float(hy), float(hz), float(rng.uniform(0, math.pi)), *c))


def sample_clutter(rng: np.random.Generator, turbine: TurbineParams,
                   roads: tuple[tuple[float, float, float, float, float], ...],
                   sea: str) -> Clutter:
    """Random clutter round ``turbine``'s base: on land a power line on lattice pylons
    (45 %), a line of wooden poles (40 %), fences (50 %) and buildings (55 %); offshore a
    substation platform on legs (30 %)."""
    centre = np.array([turbine.base_x, turbine.base_y, 0.0])
    rods: list[Rod] = []
    boxes: list[Box] = []
    if sea == "all":
        if rng.uniform() < 0.3:
            d, ang = rng.uniform(150.0, 900.0), rng.uniform(0, 2 * math.pi)
            c = centre + d * np.array([math.cos(ang), math.sin(ang), 0.0])
            hz, half = rng.uniform(15.0, 25.0), rng.uniform(8.0, 15.0)
            col = _colour(rng, (0.75, 0.72, 0.6), 0.15)
            boxes.append((float(c[0]), float(c[1]), float(hz + 5.0), float(half), float(half),
                          5.0, float(rng.uniform(0, math.pi)), *col))
            for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
                p = c + 0.8 * half * np.array([sx, sy, 0.0])
                rods.append(_rod(p, p + _up(hz), 0.8, (0.8, 0.65, 0.15)))
        return Clutter(tuple(rods), tuple(boxes))
    if rng.uniform() < 0.45:
        _power_line(rng, centre, rods)
    if rng.uniform() < 0.4:
        _poles(rng, centre, roads, rods)
    if rng.uniform() < 0.5:
        _fences(rng, centre, rods)
    if rng.uniform() < 0.55:
        _buildings(rng, centre, boxes)
    return Clutter(tuple(rods), tuple(boxes))
