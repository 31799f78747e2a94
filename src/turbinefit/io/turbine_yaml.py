"""Turbine parameter files: the seven :class:`~turbinefit.turbine.model.TurbineParams`.

Format (YAML mapping, exactly these seven keys, any order; comments allowed)::

    # optional comment
    base_x: 12.0          # m, tower base in the world frame (ground plane z = 0)
    base_y: -3.5          # m
    tower_height: 80.0    # m, > 0
    heading: 1.2          # rad, nacelle direction from world x, counter-clockwise about z
    nacelle_length: 4.0   # m, >= 0
    blade_rotation: 0.3   # rad, blade 1 angle about the nacelle axis, 0 = up
    blade_length: 40.0    # m, > 0

A georeferenced fit (:mod:`turbinefit.io.georef`) adds ``latitude`` and ``longitude``
(WGS84 degrees) of the base; they are accepted (and ignored) on reading.

World frame: metres, right-handed, z up (see :mod:`turbinefit.turbine.model`). Angles are
radians and are not wrapped on reading or writing.

A fitted file (``fit``, ``track``) adds the standard deviation of each parameter, a
mapping under ``std`` (same keys and units; ``null`` where unknown)::

    std:
      base_x: 0.12
      ...

:func:`read_turbine_yaml` accepts and checks it (numbers >= 0 or null, known keys) and
returns the parameters only; :func:`read_turbine_std` returns it.

Reading raises :class:`~turbinefit.errors.InputError` naming the file and key for a missing
key, an unknown key, a duplicate key, a non-numeric or non-finite value, or a value out of
range (``tower_height > 0``, ``blade_length > 0``, ``nacelle_length >= 0``) or absurd
(lengths beyond 1 km, base coordinates beyond 1e8 m, angles beyond 1000 rad:
:mod:`turbinefit.io.limits`; checked on reading only). Writing checks
the same ranges (so every written file can be read back; call
:meth:`TurbineParams.canonical` first to turn a negative blade length into a positive one)
and uses ``repr`` precision, so a round trip is exact.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from turbinefit.errors import InputError, plain_number
from turbinefit.io.atomic import StrPath, write_text_atomic
from turbinefit.io.limits import MAX_ANGLE_RAD, MAX_COORDINATE_M, MAX_LENGTH_M
from turbinefit.io.yaml_files import load_yaml_mapping, parse_number, yaml_float
from turbinefit.turbine.model import TurbineParams

#: Keys accepted on reading besides the seven (the base's WGS84 position, not read).
LOCATION_KEYS = ("latitude", "longitude")
_UNITS = dict(zip(TurbineParams.NAMES, ("m", "m", "m", "rad", "m", "rad", "m"), strict=True))


def _check_ranges(values: dict[str, float], path: StrPath | None) -> None:
    for key in ("tower_height", "blade_length"):
        if not values[key] > 0.0:
            raise InputError(f"must be > 0, got {plain_number(values[key])}", path=path,
                             field=key)
    if not values["nacelle_length"] >= 0.0:
        raise InputError(f"must be >= 0, got {plain_number(values['nacelle_length'])}", path=path,
                         field="nacelle_length")


def _check_magnitudes(values: dict[str, float], path: StrPath) -> None:
    """Refuse values no turbine has (:mod:`turbinefit.io.limits`), on reading."""
    limits = {"base_x": MAX_COORDINATE_M, "base_y": MAX_COORDINATE_M,
              "heading": MAX_ANGLE_RAD, "blade_rotation": MAX_ANGLE_RAD,
              "tower_height": MAX_LENGTH_M, "nacelle_length": MAX_LENGTH_M,
              "blade_length": MAX_LENGTH_M}
    for key, limit in limits.items():
        if not abs(values[key]) <= limit:
            raise InputError(f"{plain_number(values[key])} {_UNITS[key]} is beyond the "
                             f"plausible {limit:g} {_UNITS[key]}", path=path, field=key)


#: The optional key of the standard deviations.
STD_KEY = "std"


def _parse_std(value: Any, path: StrPath) -> dict[str, float | None]:
    if not isinstance(value, dict):
        raise InputError("must be a mapping of parameter names to standard deviations",
                         path=path, field=STD_KEY)
    out: dict[str, float | None] = {}
    for key, v in value.items():
        where = f"{STD_KEY}.{key}"
        if key not in TurbineParams.NAMES:
            raise InputError(f"unknown key (expected: {', '.join(TurbineParams.NAMES)})",
                             path=path, field=where)
        if v is None:
            out[key] = None
            continue
        x = parse_number(v, path, where)
        if x < 0:
            raise InputError(f"must be >= 0, got {x:g}", path=path, field=where)
        out[key] = x
    return out


def read_turbine_std(path: StrPath) -> dict[str, float | None] | None:
    """The ``std`` block of a turbine file (None if it has none); checked as
    :func:`read_turbine_yaml` checks it."""
    data = load_yaml_mapping(path)
    return None if STD_KEY not in data else _parse_std(data[STD_KEY], path)


def read_turbine_yaml(path: StrPath) -> TurbineParams:
    """Read turbine parameters (metres, radians) from a YAML file (see module docstring).

    Raises:
        InputError: naming the file and the offending key.
    """
    data = load_yaml_mapping(path)
    for key in data:
        if key in LOCATION_KEYS:
            parse_number(data[key], path, key)
        elif key not in TurbineParams.NAMES and key != STD_KEY:
            raise InputError(f"unknown key (expected: {', '.join(TurbineParams.NAMES)})",
                             path=path, field=key)
    if STD_KEY in data:
        _parse_std(data[STD_KEY], path)
    values: dict[str, float] = {}
    for key in TurbineParams.NAMES:
        if key not in data:
            raise InputError("missing", path=path, field=key)
        values[key] = parse_number(data[key], path, key)
    _check_ranges(values, path)
    _check_magnitudes(values, path)
    return TurbineParams(**values)


def format_turbine_yaml(params: TurbineParams, comment: str | None = None,
                        path: StrPath | None = None,
                        std: Mapping[str, float | None] | None = None) -> str:
    """The text :func:`write_turbine_yaml` writes (``path`` only names errors)."""
    values = params.to_dict()
    _check_ranges(values, path)
    lines = ["# " + c if c else "#" for c in comment.splitlines()] if comment else []
    width = max(len(k) for k in TurbineParams.NAMES) + 2
    for key in TurbineParams.NAMES:
        lines.append(f"{key + ':':<{width}}{yaml_float(values[key])}  # {_UNITS[key]}")
    if std is not None:
        lines.append(f"{STD_KEY}:  # standard deviations (same units)")
        for key in TurbineParams.NAMES:
            v = std.get(key)
            text = "null" if v is None or not math.isfinite(v) else yaml_float(float(v))
            lines.append(f"  {key + ':':<{width}}{text}")
    return "\n".join(lines) + "\n"


def write_turbine_yaml(path: StrPath, params: TurbineParams, comment: str | None = None,
                       std: Mapping[str, float | None] | None = None,
                       extra: str = "") -> None:
    """Write turbine parameters as YAML, atomically.

    Args:
        path: destination file (replaced if it exists).
        params: the parameters (metres, radians), written with ``repr`` precision.
        comment: optional text written as ``#`` lines at the top.
        std: optional standard deviation of each parameter (a ``std`` block; missing or
            non-finite values are written as ``null``).
        extra: YAML lines written after the parameters (e.g. the base's latitude and
            longitude, :func:`turbinefit.io.georef.location_text`).

    Raises:
        InputError: naming ``path`` and the key, for a value out of range.
    """
    write_text_atomic(path, format_turbine_yaml(params, comment, path, std) + extra)
