"""The paper's skeletal turbine model: parameters, point model, line model, Jacobians.

World frame: metres, right-handed, z up, ground plane z = 0 (the turbine base lies on it).

Parameters ``theta = (base_x, base_y, tower_height, heading, nacelle_length,
blade_rotation, blade_length)`` = the paper's ``(c_x, c_y, h, omega, r, phi, b)``, metres and
radians. The paper's functions Psi applied to its default model reduce to::

    base      g   = (c, 0)
    tower top t   = (c, h)
    hub       p_r = (c, 0) + R_z(omega) (r, 0, h)
    tip i     p_i = (c, 0) + R_z(omega) (r, -b sin phi_i, h + b cos phi_i),  phi_i = phi + 2 pi i / 3

so the nacelle is horizontal along the heading and the blades turn in the plane through the
hub perpendicular to it. :class:`TurbineGeometry` adds optional real-turbine details that
the paper ignores (shaft tilt, blade cone, hub above the tower top); with its defaults
(all zero) the model is the paper's exactly. These are fixed shape constants, not
optimised.

Heading is defined modulo 2 pi and blade rotation modulo 2 pi / 3 (three identical blades):
:meth:`TurbineParams.canonical` maps to ``[0, 2 pi)`` and ``[0, 2 pi / 3)``, and
:func:`param_errors` measures angle errors modulo those periods.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

HEADING_PERIOD = 2.0 * math.pi
BLADE_PERIOD = 2.0 * math.pi / 3.0

#: Names of the six model points, in order (the paper's g, t, r, b1, b2, b3).
POINT_NAMES = ("base", "tower_top", "hub", "tip_1", "tip_2", "tip_3")
#: Heat-map channel of each model point (see :mod:`turbinefit.heatmaps`).
POINT_CHANNELS = np.array([0, 1, 2, 3, 3, 3])
#: Line model: (start point index, end point index, heat-map channel).
LINES = (
    (0, 1, 4),  # tower: base -> tower top      (line_tower)
    (1, 2, 5),  # nacelle: tower top -> hub     (line_nacelle)
    (2, 3, 6),  # blade 1: hub -> tip 1         (line_blade)
    (2, 4, 6),  # blade 2
    (2, 5, 6),  # blade 3
)
LINE_NAMES = ("tower", "nacelle", "blade_1", "blade_2", "blade_3")


def wrap(angle: ArrayLike, period: float) -> FloatArray:
    """Wrap angles into ``[-period / 2, period / 2)``."""
    a = np.asarray(angle, dtype=np.float64)
    return (a + 0.5 * period) % period - 0.5 * period


@dataclass(frozen=True)
class TurbineParams:
    """The seven turbine parameters theta (metres, radians).

    Attributes:
        base_x, base_y: tower base on the ground plane, world frame [m].
        tower_height: tower top above the ground [m].
        heading: direction of the nacelle (tower top -> hub) from the world x axis,
            counter-clockwise about z [rad], period 2 pi.
        nacelle_length: horizontal distance tower top -> hub [m].
        blade_rotation: rotor angle phi of blade 1 about the nacelle axis, 0 = pointing up
            [rad], period 2 pi / 3.
        blade_length: hub -> tip [m].
    """

    base_x: float
    base_y: float
    tower_height: float
    heading: float
    nacelle_length: float
    blade_rotation: float
    blade_length: float

    NAMES: ClassVar[tuple[str, ...]] = (
        "base_x", "base_y", "tower_height", "heading", "nacelle_length",
        "blade_rotation", "blade_length",
    )
    #: Which entries are angles [rad] (the rest are metres).
    ANGULAR: ClassVar[tuple[bool, ...]] = (False, False, False, True, False, True, False)

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not math.isfinite(v):
                raise ValueError(f"turbine parameter {f.name} must be finite, got {v}")

    def to_vector(self) -> FloatArray:
        return np.array([getattr(self, n) for n in self.NAMES], dtype=np.float64)

    @staticmethod
    def from_vector(v: ArrayLike) -> TurbineParams:
        a = np.asarray(v, dtype=np.float64).ravel()
        if a.size != 7:
            raise ValueError(f"theta needs 7 values, got {a.size}")
        return TurbineParams(*(float(x) for x in a))

    def to_dict(self) -> dict[str, float]:
        return {n: float(getattr(self, n)) for n in self.NAMES}

    def canonical(self) -> TurbineParams:
        """The same turbine with heading in [0, 2 pi) and blade rotation in [0, 2 pi / 3);
        a negative blade length is turned into a positive one (phi + pi)."""
        v = self.to_vector()
        if v[6] < 0:
            v[6] = -v[6]
            v[5] += math.pi
        v[3] = v[3] % HEADING_PERIOD
        v[5] = v[5] % BLADE_PERIOD
        # `%` can return the period itself for tiny negative inputs
        if v[3] >= HEADING_PERIOD:
            v[3] = 0.0
        if v[5] >= BLADE_PERIOD:
            v[5] = 0.0
        return TurbineParams.from_vector(v)


#: Period of each parameter (0 = not periodic).
PERIODS = np.array([0.0, 0.0, 0.0, HEADING_PERIOD, 0.0, BLADE_PERIOD, 0.0])

#: Plausible range of each length of a real turbine [m]: tower (hub height) 10-250 m,
#: nacelle overhang 0-25 m, blade 5-150 m. The largest machines built reach a hub height
#: of about 180 m, an overhang of about 15 m and a rotor radius of about 130 m; the
#: smallest grid machines have towers of about 20 m and blades of about 10 m. The solver
#: keeps theta inside (:func:`turbinefit.solver.linalg.bounded_step`) and a fit that ends
#: on a bound is not trusted (:mod:`turbinefit.solver.verdict`). Base, heading and blade
#: rotation are unbounded (-inf, inf).
THETA_LOWER = np.array([-np.inf, -np.inf, 10.0, -np.inf, 0.0, -np.inf, 5.0])
THETA_UPPER = np.array([np.inf, np.inf, 250.0, np.inf, 25.0, np.inf, 150.0])


def param_errors(estimate: TurbineParams, reference: TurbineParams) -> FloatArray:
    """Signed per-parameter errors ``estimate - reference`` (7,), angles wrapped modulo
    their periods into ``[-period/2, period/2)``."""
    d = estimate.to_vector() - reference.to_vector()
    for i in (3, 5):
        d[i] = float(wrap(d[i], PERIODS[i]))
    return d


@dataclass(frozen=True)
class TurbineGeometry:
    """Fixed shape details beyond the paper's model; all zero = the paper's model.

    Attributes:
        shaft_tilt: rotor shaft tilted nose-up by this angle [rad] (real turbines ~5 deg).
        blade_cone: blades leaning forward (away from the tower) by this angle [rad]
            (real turbines ~2.5 deg).
        hub_offset: hub axis above the tower top [m].

    Each must be a finite real number (int, float or NumPy scalar, not bool); anything else
    is a ValueError naming the field. Values are stored as plain floats.
    """

    shaft_tilt: float = 0.0
    blade_cone: float = 0.0
    hub_offset: float = 0.0

    def __post_init__(self) -> None:
        # Checked here, where every user of the geometry (fit configs read from YAML,
        # simulation settings) passes, instead of failing deep in the model's trigonometry.
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise ValueError(f"geometry.{f.name}: must be a finite real number (got {v!r})")
            object.__setattr__(self, f.name, float(v))  # plain floats: YAML/JSON-safe


PAPER_GEOMETRY = TurbineGeometry()


def model_points(
    theta: ArrayLike, geometry: TurbineGeometry = PAPER_GEOMETRY, with_jacobian: bool = False
) -> tuple[FloatArray, FloatArray | None]:
    """The six model points (world frame, metres) of ``theta`` (7,).

    Returns:
        world_p: (6, 3) points in the order of :data:`POINT_NAMES`.
        J: (6, 3, 7) d world_p / d theta, or None.
    """
    cx, cy, h, w, r, phi, b = (float(x) for x in np.asarray(theta, dtype=np.float64).ravel())
    tau, kappa, z0 = geometry.shaft_tilt, geometry.blade_cone, geometry.hub_offset
    ct, st = math.cos(tau), math.sin(tau)
    ck, sk = math.cos(kappa), math.sin(kappa)
    phis = phi + np.arange(3) * BLADE_PERIOD
    sp, cp = np.sin(phis), np.cos(phis)

    # Points in the turbine's local frame (x along the heading, z up, origin at the base).
    local = np.zeros((6, 3))
    local[1] = (0.0, 0.0, h)
    hub = np.array([r * ct, 0.0, h + z0 + r * st])
    local[2] = hub
    # Blade direction before tilt: (sin k, -cos k sin phi_i, cos k cos phi_i); tilt = R_y(-tau).
    d0 = np.stack([np.full(3, sk), -ck * sp, ck * cp], axis=-1)  # (3, 3)
    dirs = np.stack([ct * d0[:, 0] - st * d0[:, 2], d0[:, 1], st * d0[:, 0] + ct * d0[:, 2]], -1)
    local[3:] = hub + b * dirs

    cw, sw = math.cos(w), math.sin(w)
    Rz = np.array([[cw, -sw, 0.0], [sw, cw, 0.0], [0.0, 0.0, 1.0]])
    world_p = local @ Rz.T + np.array([cx, cy, 0.0])
    if not with_jacobian:
        return world_p, None

    J = np.zeros((6, 3, 7))
    J[:, 0, 0] = 1.0
    J[:, 1, 1] = 1.0
    # tower height moves every point but the base straight up
    J[1:, 2, 2] = 1.0
    # heading: d(Rz l)/dw = dRz l
    dRz = np.array([[-sw, -cw, 0.0], [cw, -sw, 0.0], [0.0, 0.0, 0.0]])
    J[:, :, 3] = local @ dRz.T
    # nacelle length moves hub and tips along the (tilted) shaft
    dhub_dr = Rz @ np.array([ct, 0.0, st])
    J[2:, :, 4] = dhub_dr
    # blade rotation: d dirs / d phi
    dd0 = np.stack([np.zeros(3), -ck * cp, -ck * sp], axis=-1)
    ddirs = np.stack([ct * dd0[:, 0] - st * dd0[:, 2], dd0[:, 1], st * dd0[:, 0] + ct * dd0[:, 2]], -1)
    J[3:, :, 5] = b * (ddirs @ Rz.T)
    J[3:, :, 6] = dirs @ Rz.T
    return world_p, J


def skeleton_segments(theta: TurbineParams, geometry: TurbineGeometry = PAPER_GEOMETRY
                      ) -> FloatArray:
    """The five model lines of :data:`LINES` as segments (5, 2, 3) [m, world]."""
    p, _ = model_points(theta.to_vector(), geometry)
    return np.stack([np.stack([p[a], p[b]]) for a, b, _ in LINES])


@dataclass(frozen=True)
class LineSampling:
    """Where the line model is sampled: ``n`` points per line at interior fractions
    ``s_k = (k + 0.5) / n`` (the end points belong to the point model)."""

    samples_per_line: int = 10

    def fractions(self) -> FloatArray:
        n = self.samples_per_line
        return (np.arange(n) + 0.5) / n


def line_samples(
    world_p: FloatArray, J_points: FloatArray | None, samples_per_line: int
) -> tuple[FloatArray, FloatArray | None, NDArray[np.int_]]:
    """Sample the five model lines into points.

    Args:
        world_p: (6, 3) model points.
        J_points: (6, 3, 7) their Jacobians w.r.t. theta, or None.
        samples_per_line: samples per line (interior, see :class:`LineSampling`).

    Returns:
        world_s: (5 * n, 3) samples, line by line in the order of :data:`LINES`.
        J: (5 * n, 3, 7) or None.
        channel: (5 * n,) heat-map channel of each sample.
    """
    s = LineSampling(samples_per_line).fractions()
    a_idx = np.array([ln[0] for ln in LINES])
    b_idx = np.array([ln[1] for ln in LINES])
    ch = np.repeat(np.array([ln[2] for ln in LINES]), s.size)
    wa = (1.0 - s)[None, :, None]
    wb = s[None, :, None]
    world_s = (world_p[a_idx][:, None, :] * wa + world_p[b_idx][:, None, :] * wb).reshape(-1, 3)
    J = None
    if J_points is not None:
        J = (
            J_points[a_idx][:, None] * wa[..., None] + J_points[b_idx][:, None] * wb[..., None]
        ).reshape(-1, 3, 7)
    return world_s, J, ch


def model_point_error(estimate: TurbineParams, reference: TurbineParams,
                      geometry: TurbineGeometry = PAPER_GEOMETRY) -> float:
    """Mean 3-D distance [m] between the six model points of two turbines.

    The three tips are matched by the cyclic shift that fits best, since blade rotation is
    only defined modulo 2 pi / 3 (the tips of ``phi`` and ``phi + 2 pi / 3`` are the same set).
    """
    pa, _ = model_points(estimate.to_vector(), geometry)
    pb, _ = model_points(reference.to_vector(), geometry)
    best = math.inf
    for shift in range(3):
        perm = np.r_[0, 1, 2, 3 + (np.arange(3) + shift) % 3]
        best = min(best, float(np.mean(np.linalg.norm(pa[perm] - pb, axis=-1))))
    return best
