"""Realistic turbines for simulation: named presets and a random sampler.

World frame: metres, z up, ground plane z = 0; angles in radians. Parameters follow
:class:`turbinefit.turbine.model.TurbineParams` (the paper's theta = (c_x, c_y, h, omega,
r, phi, b)): ``tower_height`` is the top of the tower (the paper's hub height, since the
paper's model puts the hub level with the tower top), ``nacelle_length`` the horizontal
tower-axis -> hub distance (the rotor overhang) and ``blade_length`` hub centre -> tip
(the rotor radius).

Sources of the presets (public data sheets):

* ``nrel5mw`` - NREL 5 MW reference turbine: tower 87.6 m, hub height 90 m, rotor radius
  63 m, overhang 5 m, shaft tilt 5 deg, precone 2.5 deg.
* ``v80`` - Vestas V80-2.0 MW: rotor 80 m (radius 40 m), hub height 78 m (one of the
  offered 60-100 m towers), overhang ~4 m.
* ``swt93`` - Siemens SWT-2.3-93: rotor 93 m (radius 46.5 m), hub height 80 m, overhang
  ~4.5 m.

The presets put the base at the origin with heading 0 and blade 1 pointing up; use
:func:`preset_turbine` to randomise heading, blade rotation and base.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from turbinefit.turbine.model import BLADE_PERIOD, TurbineGeometry, TurbineParams

#: Named real machines (base at the origin, heading 0, blade 1 up).
PRESETS: dict[str, TurbineParams] = {
    "nrel5mw": TurbineParams(0.0, 0.0, 87.6, 0.0, 5.0, 0.0, 63.0),
    "v80": TurbineParams(0.0, 0.0, 78.0, 0.0, 4.0, 0.0, 40.0),
    "swt93": TurbineParams(0.0, 0.0, 80.0, 0.0, 4.5, 0.0, 46.5),
}

#: Shape details of a real machine (NREL 5 MW: 5 deg shaft tilt, 2.5 deg precone, hub
#: ~2.4 m above the tower top). The paper's model (and the default everywhere) is
#: ``TurbineGeometry()``, all zero.
REALISTIC_GEOMETRY = TurbineGeometry(
    shaft_tilt=math.radians(5.0), blade_cone=math.radians(2.5), hub_offset=2.4
)

#: Ranges of :func:`sample_turbine` [m].
TOWER_RANGE = (70.0, 100.0)
BLADE_RANGE = (40.0, 63.0)
NACELLE_RANGE = (4.0, 7.0)
#: Minimum ground clearance of a blade tip [m] (tower height - blade length).
MIN_TIP_CLEARANCE = 20.0


def _random_pose(rng: np.random.Generator, base_radius: float) -> tuple[float, float, float, float]:
    """Random base (uniform in a disc of ``base_radius`` m), heading in [0, 2 pi) and
    blade rotation in [0, 2 pi / 3)."""
    rad = base_radius * math.sqrt(rng.uniform())
    ang = rng.uniform(0.0, 2.0 * math.pi)
    heading = rng.uniform(0.0, 2.0 * math.pi)
    phi = rng.uniform(0.0, BLADE_PERIOD)
    return rad * math.cos(ang), rad * math.sin(ang), heading, phi


def sample_turbine(rng: np.random.Generator, base_radius: float = 3.0) -> TurbineParams:
    """A random realistic three-bladed turbine.

    Tower 70-100 m, blades 40-63 m (at most tower - 20 m, so the tips clear the ground by
    at least 20 m), nacelle 4-7 m, heading uniform in [0, 2 pi), blade rotation uniform in
    [0, 2 pi / 3), base uniform in a disc of ``base_radius`` [m] around the origin.
    The result is canonical (see :meth:`TurbineParams.canonical`).
    """
    h = rng.uniform(*TOWER_RANGE)
    b = rng.uniform(BLADE_RANGE[0], min(BLADE_RANGE[1], h - MIN_TIP_CLEARANCE))
    r = rng.uniform(*NACELLE_RANGE)
    x, y, heading, phi = _random_pose(rng, base_radius)
    return TurbineParams(x, y, h, heading, r, phi, b)


def preset_turbine(
    name: str, rng: np.random.Generator | None = None, base_radius: float = 3.0
) -> TurbineParams:
    """A preset machine (``name`` in :data:`PRESETS`) or, for ``"random"``,
    :func:`sample_turbine`. With ``rng`` the preset's heading, blade rotation and base
    (within ``base_radius`` m) are randomised; without it the preset is returned as is."""
    if name == "random":
        if rng is None:
            raise ValueError("a random turbine needs an rng")
        return sample_turbine(rng, base_radius)
    if name not in PRESETS:
        raise ValueError(f"unknown turbine preset {name!r}; choose from "
                         f"{', '.join([*PRESETS, 'random'])}")
    t = PRESETS[name]
    if rng is None:
        return t
    x, y, heading, phi = _random_pose(rng, base_radius)
    return replace(t, base_x=x, base_y=y, heading=heading, blade_rotation=phi)


def neighbour_turbine(
    primary: TurbineParams,
    rng: np.random.Generator,
    distance: tuple[float, float] = (150.0, 400.0),
) -> TurbineParams:
    """Another turbine of the same wind farm: base ``distance`` [m] (uniform range) from
    ``primary``'s base in a random direction, heading ``primary``'s + N(0, 5 deg) (same
    wind), random blade rotation, sizes within +-5 % of ``primary``'s."""
    d = rng.uniform(*distance)
    ang = rng.uniform(0.0, 2.0 * math.pi)
    scale = rng.uniform(0.95, 1.05, size=3)
    return TurbineParams(
        primary.base_x + d * math.cos(ang),
        primary.base_y + d * math.sin(ang),
        primary.tower_height * float(scale[0]),
        (primary.heading + rng.normal(0.0, math.radians(5.0))) % (2.0 * math.pi),
        primary.nacelle_length * float(scale[1]),
        rng.uniform(0.0, BLADE_PERIOD),
        primary.blade_length * float(scale[2]),
    )
