"""Camera intrinsics files: ROS ``camera_info`` YAML and OpenCV FileStorage YAML.

Units: pixels. Frame: OpenCV camera (x right, y down, z forward); pixel (0, 0) is the
centre of the top-left pixel (see :mod:`turbinefit.geometry.camera`).

**ROS camera_info YAML** (what :func:`write_camera_yaml` writes; ``camera_calibration``
and ``camera_info_manager`` read it)::

    image_width: 640
    image_height: 480
    camera_name: turbinefit                  # optional on reading
    camera_matrix: {rows: 3, cols: 3, data: [fx, s, cx, 0, fy, cy, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
    rectification_matrix: {rows: 3, cols: 3, data: [identity]}     # written, ignored
    projection_matrix: {rows: 3, cols: 4, data: [K | 0]}            # written, ignored

**OpenCV FileStorage YAML** (``cv::FileStorage``, e.g. the calibration sample's output) is
accepted too: a first line ``%YAML:1.0`` and ``!!opencv-matrix`` tags (mappings with
``rows``, ``cols``, ``dt``, ``data``) are stripped before parsing with ``yaml.safe_load``
semantics. Aliases accepted on reading: ``cameraMatrix`` for ``camera_matrix``,
``distCoeffs`` / ``dist_coeffs`` for ``distortion_coefficients``, and
``cameraResolution: [w, h]`` for ``image_width`` / ``image_height``. Other keys are ignored.

Distortion: ``plumb_bob`` (OpenCV's ``k1 k2 p1 p2 k3``; fewer coefficients are padded with
zeros; missing, empty or all-zero coefficients mean no distortion). A missing or null
``distortion_model`` (OpenCV files have none) means plumb_bob; ``""`` or ``none`` means no
distortion and requires zero coefficients. ``rational_polynomial`` (and OpenCV's 8/12/14
coefficient vectors) are accepted only when the coefficients beyond ``k3`` are zero (then
the model *is* plumb_bob); any other model (e.g. ``equidistant``) is an
:class:`~turbinefit.errors.InputError`.

Validation (each failure an InputError naming the file and field): ``rows * cols ==
len(data)``, numbers finite, image size positive integers, ``camera_matrix`` 3x3 with
bottom row ``0 0 1`` and ``K[1, 0] == 0``, focal lengths positive. Numbers written as
strings that PyYAML's YAML 1.1 does not recognise (``1e-5``) are accepted; ``nan``/``inf``
are not. Duplicate keys are errors.

The YAML parsing (duplicate keys, OpenCV's directive and tags, numbers as text) is that of
:mod:`turbinefit.io.yaml_files`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.io.atomic import StrPath, write_text_atomic
from turbinefit.io.yaml_files import load_yaml_mapping, parse_number, yaml_float, yaml_str

_K_KEYS = ("camera_matrix", "cameraMatrix")
_D_KEYS = ("distortion_coefficients", "distCoeffs", "dist_coeffs")
_NO_DISTORTION_MODELS = ("", "none")
_SUPPORTED_MODELS = ("plumb_bob", "rational_polynomial")


def _first_key(data: dict[str, Any], keys: tuple[str, ...]) -> str | None:
    for k in keys:
        if k in data:
            return k
    return None


def _parse_int(value: Any, path: StrPath, field: str) -> int:
    v = parse_number(value, path, field)
    if v != int(v):
        raise InputError(f"must be an integer, got {value!r}", path=path, field=field)
    return int(v)


def _parse_matrix(value: Any, path: StrPath, field: str) -> NDArray[np.float64]:
    """A ``{rows, cols, data}`` mapping (ROS / OpenCV) as a (rows, cols) array."""
    if not isinstance(value, dict):
        raise InputError("expected a mapping with rows, cols and data", path=path, field=field)
    for k in ("rows", "cols", "data"):
        if k not in value:
            raise InputError(f"missing '{k}'", path=path, field=field)
    rows = _parse_int(value["rows"], path, f"{field}.rows")
    cols = _parse_int(value["cols"], path, f"{field}.cols")
    if rows < 0 or cols < 0:
        raise InputError(f"negative size {rows}x{cols}", path=path, field=field)
    data = value["data"]
    if data is None:
        data = []
    if not isinstance(data, list):
        raise InputError(f"'data' must be a list, got {data!r}", path=path, field=field)
    if len(data) != rows * cols:
        raise InputError(f"rows * cols = {rows} * {cols} = {rows * cols} but data has "
                         f"{len(data)} values", path=path, field=field)
    vals = [parse_number(x, path, f"{field}.data[{i}]") for i, x in enumerate(data)]
    return np.array(vals, dtype=np.float64).reshape(rows, cols)


def _parse_distortion(data: dict[str, Any], path: StrPath) -> NDArray[np.float64]:
    dkey = _first_key(data, _D_KEYS)
    raw = data.get(dkey) if dkey is not None else None
    field = dkey or "distortion_coefficients"
    coeffs = np.zeros(0) if raw is None else _parse_matrix(raw, path, field).ravel()
    model_raw = data.get("distortion_model")
    if model_raw is not None and not isinstance(model_raw, str):
        raise InputError(f"must be a string, got {model_raw!r}", path=path,
                         field="distortion_model")
    if model_raw is None:  # OpenCV files have no model: its coefficients are plumb_bob's
        model_raw = "plumb_bob"
    model = model_raw.strip().lower()
    if model in _NO_DISTORTION_MODELS:
        if np.any(coeffs != 0.0):
            raise InputError(f"distortion_model is {model_raw!r} but the coefficients are not "
                             "all zero", path=path, field=field)
        return np.zeros(5)
    if model not in _SUPPORTED_MODELS:
        raise InputError(f"unsupported distortion model {model_raw!r} (supported: plumb_bob, "
                         "or none)", path=path, field="distortion_model")
    if coeffs.size > 5 and np.any(coeffs[5:] != 0.0):
        raise InputError(f"{coeffs.size} distortion coefficients with non-zero entries beyond "
                         "k1 k2 p1 p2 k3; only plumb_bob is supported", path=path, field=field)
    out = np.zeros(5)
    out[: min(5, coeffs.size)] = coeffs[:5]
    return out


def camera_from_mapping(data: dict[str, Any], path: StrPath) -> PinholeCamera:
    """The camera of a parsed camera-info mapping (``path`` names errors)."""
    if "image_width" in data or "image_height" in data or "cameraResolution" not in data:
        for key in ("image_width", "image_height"):
            if key not in data:
                raise InputError("missing", path=path, field=key)
        width = _parse_int(data["image_width"], path, "image_width")
        height = _parse_int(data["image_height"], path, "image_height")
    else:
        res = data["cameraResolution"]
        if not isinstance(res, list) or len(res) != 2:
            raise InputError("expected [width, height]", path=path, field="cameraResolution")
        width = _parse_int(res[0], path, "cameraResolution")
        height = _parse_int(res[1], path, "cameraResolution")
    for key, v in (("image_width", width), ("image_height", height)):
        if v <= 0:
            raise InputError(f"must be positive, got {v}", path=path, field=key)

    kkey = _first_key(data, _K_KEYS)
    if kkey is None:
        raise InputError("missing", path=path, field="camera_matrix")
    K = _parse_matrix(data[kkey], path, kkey)
    if K.shape != (3, 3):
        raise InputError(f"must be 3x3, got {K.shape[0]}x{K.shape[1]}", path=path, field=kkey)
    if K[1, 0] != 0.0 or np.any(np.abs(K[2] - (0.0, 0.0, 1.0)) > 1e-12):
        raise InputError("not a camera matrix: expected [fx s cx; 0 fy cy; 0 0 1], got "
                         f"{K.ravel().tolist()}", path=path, field=kkey)
    for name, v in (("fx", K[0, 0]), ("fy", K[1, 1])):
        if not v > 0.0:
            raise InputError(f"focal length {name} must be positive, got {v!r}", path=path,
                             field=kkey)
    dist = _parse_distortion(data, path)
    try:
        return PinholeCamera.from_matrix(width, height, K, dist)
    except ValueError as e:
        raise InputError(str(e), path=path, field=kkey) from e


def read_camera_yaml(path: StrPath) -> PinholeCamera:
    """Read camera intrinsics from a ROS camera_info or OpenCV FileStorage YAML file.

    See the module docstring for the accepted keys. Raises :class:`InputError` naming the
    file and the offending field.
    """
    return camera_from_mapping(load_yaml_mapping(path), path)


def format_camera_yaml(camera: PinholeCamera, name: str = "turbinefit") -> str:
    """The text :func:`write_camera_yaml` writes."""
    K = camera.K.ravel().tolist()
    P = np.hstack([camera.K, np.zeros((3, 1))]).ravel().tolist()
    R = np.eye(3).ravel().tolist()

    def mat(key: str, rows: int, cols: int, vals: list[float]) -> str:
        data = ", ".join(yaml_float(v) for v in vals)
        return f"{key}:\n  rows: {rows}\n  cols: {cols}\n  data: [{data}]\n"

    return (
        f"image_width: {int(camera.width)}\n"
        f"image_height: {int(camera.height)}\n"
        f"camera_name: {yaml_str(name)}\n"
        + mat("camera_matrix", 3, 3, K)
        + "distortion_model: plumb_bob\n"
        + mat("distortion_coefficients", 1, 5, [float(c) for c in camera.distortion])
        + mat("rectification_matrix", 3, 3, R)
        + mat("projection_matrix", 3, 4, P)
    )


def write_camera_yaml(path: StrPath, camera: PinholeCamera, name: str = "turbinefit") -> None:
    """Write ``camera`` as ROS camera_info YAML, atomically.

    Always writes ``distortion_model: plumb_bob`` with five coefficients (zeros for a camera
    without distortion), an identity ``rectification_matrix`` and ``projection_matrix =
    [K | 0]``. Floats are written with ``repr`` precision, so a read-back is exact.
    """
    write_text_atomic(path, format_camera_yaml(camera, name))
