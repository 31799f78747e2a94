"""The catalogue of common turbine types (``turbinefit init --type NAME``).

``turbinefit/data/turbine_types.yaml`` lists, per type, its rotor diameter, the hub
heights offered and the rotor overhang (metres), with the public source of each number.
:func:`turbine_types` reads and checks it; :meth:`TurbineType.prior` turns a type into a
:class:`~turbinefit.solver.init.TurbinePrior`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

from turbinefit.errors import InputError
from turbinefit.io.yaml_files import load_yaml_mapping, parse_number
from turbinefit.solver.init import TurbinePrior

#: The catalogue file shipped with the package.
CATALOGUE = Path(__file__).resolve().parent.parent / "data" / "turbine_types.yaml"


@dataclass(frozen=True)
class TurbineType:
    """One catalogue entry (metres).

    Attributes:
        key: the ``--type`` name.
        name: the maker's name of the model.
        rotor_diameter: rotor diameter (twice the model's blade length).
        hub_heights: the towers offered, the most common first.
        overhang: tower axis -> hub, horizontally (the model's nacelle length).
        source: where the numbers come from.
    """

    key: str
    name: str
    rotor_diameter: float
    hub_heights: tuple[float, ...]
    overhang: float
    source: str

    def prior(self) -> TurbinePrior:
        """The prior of this type: its rotor radius, overhang and most common hub height."""
        return TurbinePrior(hub_height=self.hub_heights[0], blade_length=self.rotor_diameter / 2,
                            nacelle_length=self.overhang, name=self.name)


def _entry(key: str, data: object, path: Path) -> TurbineType:
    if not isinstance(data, dict):
        raise InputError("must be a mapping", path=path, field=key)
    missing = {"name", "rotor_diameter", "hub_heights", "overhang", "source"} - set(data)
    if missing:
        raise InputError(f"missing {', '.join(sorted(missing))}", path=path, field=key)
    heights = data["hub_heights"]
    if not isinstance(heights, list) or not heights:
        raise InputError("hub_heights must be a non-empty list", path=path, field=key)
    return TurbineType(
        key, str(data["name"]), parse_number(data["rotor_diameter"], path, f"{key}.rotor_diameter"),
        tuple(parse_number(h, path, f"{key}.hub_heights") for h in heights),
        parse_number(data["overhang"], path, f"{key}.overhang"), str(data["source"]))


@cache
def turbine_types(path: Path = CATALOGUE) -> dict[str, TurbineType]:
    """The catalogue, by ``--type`` name."""
    data = load_yaml_mapping(path)
    return {str(k): _entry(str(k), v, path) for k, v in data.items()}


def turbine_type(name: str) -> TurbineType:
    """The catalogue entry ``name`` (case-insensitive).

    Raises:
        InputError: naming the known types, for an unknown name.
    """
    types = turbine_types()
    key = name.strip().lower()
    if key not in types:
        raise InputError(f"unknown turbine type {name!r}; known: {', '.join(types)}",
                         field="--type")
    return types[key]
