"""Fit and tracker options as YAML: ``config.yaml`` (what ``fit`` and ``track`` write, and
``--config`` reads).

``fit`` writes the :class:`~turbinefit.solver.config.FitConfig` it used as a flat mapping
(``FitConfig.to_dict``); ``track`` writes ``{tracker: {...}, fit: {...}}``. Both start with
``turbinefit_version``, which reading ignores.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from turbinefit import __version__
from turbinefit.errors import InputError
from turbinefit.io.atomic import StrPath, read_text
from turbinefit.io.limits import MAX_SETTINGS_BYTES
from turbinefit.io.yaml_files import FLOAT_TEXT, plain, safe_load_strict
from turbinefit.solver.config import FitConfig
from turbinefit.turbine.model import TurbineGeometry

if TYPE_CHECKING:
    from turbinefit.solver.tracker import TrackerConfig


def read_fit_config(path: StrPath) -> FitConfig:
    """Read fit options from a YAML mapping (the ``config.yaml`` that ``fit`` writes).

    Every problem is an :class:`InputError` naming the file (and line or option): a file that
    is missing, a directory, unreadable or not UTF-8; malformed YAML or a duplicate key; an
    unknown option; a value of the wrong type (numbers written like ``1e-5``, which YAML 1.1
    reads as strings, are accepted) or out of range.
    """
    p = Path(path)
    text = read_text(p, MAX_SETTINGS_BYTES)
    try:
        data = safe_load_strict(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise InputError(f"malformed YAML: {getattr(exc, 'problem', None) or exc}", p,
                         None if mark is None else mark.line + 1) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError("expected a mapping of fit options", p)
    data.pop("turbinefit_version", None)
    try:
        return FitConfig.from_dict(_typed_options(data, p))
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), p) from None


def _typed_options(data: dict[Any, Any], path: Path) -> dict[str, Any]:
    """``data`` with the types of the numeric options checked (YAML gives any type; the
    dataclass checks ranges and choices): whole numbers for ``int`` options, numbers (or
    numeric text) for ``float`` options, a mapping for ``geometry`` (whose values
    :class:`TurbineGeometry` checks), a list of finite numbers for ``pair_information``.
    Raises InputError naming the option."""
    for key in data:
        if not isinstance(key, str):
            raise InputError(f"option name {key!r} is not a string", path)
    out = dict(data)
    # annotations are strings (postponed evaluation) or, without that, the types themselves
    kinds = {f.name: f.type if isinstance(f.type, str) else getattr(f.type, "__name__", "")
             for f in dataclasses.fields(FitConfig)}

    def number(name: str, v: Any) -> float:
        if isinstance(v, str) and FLOAT_TEXT.fullmatch(v.strip()):
            return float(v)
        if isinstance(v, bool) or not isinstance(v, numbers.Real):
            raise InputError(f"{name}: must be a number (got {v!r})", path)
        return float(v)

    for name, v in data.items():
        kind = kinds.get(name)
        if kind == "int" and (isinstance(v, bool) or not isinstance(v, int)):
            raise InputError(f"{name}: must be a whole number (got {v!r})", path)
        if kind == "float" or (kind == "float | None" and v is not None):
            out[name] = number(name, v)
    if "geometry" in data:
        geo = data["geometry"]
        if not isinstance(geo, dict):
            names = ", ".join(f.name for f in dataclasses.fields(TurbineGeometry))
            raise InputError(f"geometry: must be a mapping with keys {names} (got {geo!r})",
                             path)
        for key in geo:
            if not isinstance(key, str):
                raise InputError(f"geometry: option name {key!r} is not a string", path)
    if "pair_information" in data:
        info = data["pair_information"]
        if info is not None:
            if not isinstance(info, list):
                raise InputError("pair_information: must be a list of 36 numbers (a 6x6 "
                                 f"matrix, row-major) or null (got {info!r})", path)
            out["pair_information"] = [number(f"pair_information[{i}]", x)
                                       for i, x in enumerate(info)]
            if not all(math.isfinite(x) for x in out["pair_information"]):
                raise InputError("pair_information: must be finite", path)
    return out


def tracker_config_dict(cfg: TrackerConfig) -> dict[str, Any]:
    """The tracker options as a plain mapping (``fit`` nested as :meth:`FitConfig.to_dict`)."""
    d = {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg) if f.name != "fit"}
    return {"tracker": plain(d), "fit": cfg.fit.to_dict()}


def format_fit_config(cfg: FitConfig) -> str:
    """The text of the ``config.yaml`` that ``fit`` writes."""
    return yaml.safe_dump({"turbinefit_version": __version__, **cfg.to_dict()},
                          sort_keys=False)


def format_tracker_config(cfg: TrackerConfig) -> str:
    """The text of the ``config.yaml`` that ``track`` writes."""
    return yaml.safe_dump(plain({"turbinefit_version": __version__, **tracker_config_dict(cfg)}),
                          sort_keys=False)
