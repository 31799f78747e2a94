"""YAML files: strict parsing, numbers as text, and scalars that read back exactly.

Shared by the YAML formats of :mod:`turbinefit.io` (camera intrinsics, turbine
parameters), the fit settings and the sweep files:

* :func:`safe_load_strict` - ``yaml.safe_load`` that refuses duplicate mapping keys;
* :func:`load_yaml_mapping` - a file whose top level is a mapping (ROS or OpenCV
  FileStorage flavour), each failure an :class:`~turbinefit.errors.InputError` naming the
  file and line;
* :func:`parse_number` - a finite float from a YAML scalar, also from numbers written as
  text that PyYAML's YAML 1.1 does not recognise (``1e-5``, :data:`FLOAT_TEXT`);
  ``nan`` / ``inf`` are refused;
* :func:`yaml_float`, :func:`yaml_str` - scalars written so that they read back as the
  same value;
* :func:`plain` - data with tuples turned into lists, as ``yaml.safe_dump`` needs.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

import yaml

from turbinefit.errors import InputError
from turbinefit.io.atomic import StrPath, read_text
from turbinefit.io.limits import MAX_SETTINGS_BYTES

_OPENCV_TAG = re.compile(r"!!opencv-(?:nd-)?matrix\b")
#: A decimal number as text, e.g. ``1e-5``, which YAML 1.1 (PyYAML) reads as a string.
FLOAT_TEXT = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


class _StrictLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses duplicate mapping keys."""


def _construct_mapping(loader: _StrictLoader, node: yaml.MappingNode) -> dict[Any, Any]:
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            duplicate = key in seen
        except TypeError:  # unhashable key: let PyYAML report it
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep=True)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def safe_load_strict(text: str) -> Any:
    """``yaml.safe_load`` that also refuses duplicate mapping keys (a
    ``yaml.constructor.ConstructorError`` marked at the second key)."""
    return yaml.load(text, Loader=_StrictLoader)  # a SafeLoader subclass


def load_yaml_mapping(path: StrPath) -> dict[str, Any]:
    """Parse a YAML file (ROS or OpenCV FileStorage flavour) whose top level is a mapping.

    The file must be a regular file of at most
    :data:`~turbinefit.io.limits.MAX_SETTINGS_BYTES`. The OpenCV ``%YAML:1.0`` directive
    and ``!!opencv-matrix`` tags are blanked out first (line numbers are kept). Raises
    :class:`InputError` naming the file (and line).
    """
    text = read_text(path, MAX_SETTINGS_BYTES)
    if text.startswith("%YAML:"):
        text = text[text.find("\n"):] if "\n" in text else ""
    text = _OPENCV_TAG.sub("", text)
    try:
        data = safe_load_strict(text)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        line = mark.line + 1 if mark is not None else None
        raise InputError(f"invalid YAML: {e.problem or e.context}", path=path, line=line) from e
    except yaml.YAMLError as e:
        raise InputError(f"invalid YAML: {e}", path=path) from e
    if data is None:
        raise InputError("file is empty", path=path)
    if not isinstance(data, dict):
        raise InputError(f"expected a YAML mapping (key: value lines), got {type(data).__name__}",
                         path=path)
    for key in data:
        if not isinstance(key, str):
            raise InputError(f"key {key!r} is not a string", path=path)
    return data


def parse_number(value: Any, path: StrPath, field: str) -> float:
    """A finite float from a YAML scalar (int, float or numeric string), else InputError."""
    if isinstance(value, bool) or value is None:
        raise InputError(f"not a number: {value!r}", path=path, field=field)
    if isinstance(value, int | float):
        v = float(value)
    elif isinstance(value, str) and FLOAT_TEXT.fullmatch(value.strip()):
        v = float(value)
    elif isinstance(value, str) and value.strip().lower().lstrip("+-.") in ("nan", "inf",
                                                                         "infinity"):
        v = math.nan
    else:
        raise InputError(f"not a number: {value!r}", path=path, field=field)
    if not math.isfinite(v):
        raise InputError(f"must be finite, got {value!r}", path=path, field=field)
    return v


def yaml_float(x: float) -> str:
    """A float as a YAML scalar that PyYAML reads back as the same float (repr, with a
    ``.0`` before a bare exponent, e.g. ``1.0e-05``)."""
    s = repr(float(x))
    if "e" in s and "." not in s:
        s = s.replace("e", ".0e", 1)
    return s


def yaml_str(s: str) -> str:
    """A string as a YAML scalar: plain if that reads back as the same string, else quoted."""
    try:
        if s and yaml.safe_load(s) == s and "\n" not in s and s.strip() == s:
            return s
    except yaml.YAMLError:
        pass
    return json.dumps(s)


def plain(obj: Any) -> Any:
    """Tuples to lists, recursively (``yaml.safe_dump`` refuses tuples)."""
    if isinstance(obj, dict):
        return {k: plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [plain(v) for v in obj]
    return obj
