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

Distortion: ``plumb_bob`` (OpenCV's ``k1 k2 p1 p2 k3``: exactly 5 coefficients, or an
empty list for none). A missing or null ``distortion_model`` (OpenCV files have none)
means plumb_bob with OpenCV's vector lengths (4, 5, 8, 12 or 14; fewer than 5 are padded
with zeros); ``""`` or ``none`` means no distortion and requires zero coefficients (or
none at all). ``rational_polynomial`` (8 coefficients, and OpenCV's 8/12/14 vectors) is
accepted only when the coefficients beyond ``k3`` are zero (then the model *is*
plumb_bob); any other model (e.g. ``equidistant``) is an
:class:`~turbinefit.errors.InputError`. ``distortion_coefficients`` is required unless the
model is ``none``: a file cut off before its distortion block is refused, not read as a
camera without distortion.

Validation (each failure an InputError naming the file and field): ``rows * cols ==
len(data)``, numbers finite, image size integers of at least 32 px a side and at most
200 MP (:func:`turbinefit.io.limits.check_image_size`), ``camera_matrix`` 3x3 with bottom
row ``0 0 1`` and ``K[1, 0] == 0``, focal lengths positive, and intrinsics a camera can
have (:func:`_check_plausible`): fx within 0.01-1000 times the image width, fy / fx within
0.1-10, |skew| at most 0.1 fx, the principal point within one image size of the image,
distortion coefficients within +-1000. Numbers written as
strings that PyYAML's YAML 1.1 does not recognise (``1e-5``) are accepted; ``nan``/``inf``
are not. Duplicate keys are errors.

The YAML parsing (duplicate keys, OpenCV's directive and tags, numbers as text) is that of
:mod:`turbinefit.io.yaml_files`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import InputError, plain_number
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.io.atomic import StrPath, write_text_atomic
from turbinefit.io.limits import check_image_size
from turbinefit.io.yaml_files import load_yaml_mapping, parse_number, yaml_float, yaml_str

_K_KEYS = ("camera_matrix", "cameraMatrix")
_D_KEYS = ("distortion_coefficients", "distCoeffs", "dist_coeffs")
_NO_DISTORTION_MODELS = ("", "none")
_SUPPORTED_MODELS = ("plumb_bob", "rational_polynomial")
#: Distortion coefficients each model has (0 = an empty list, no distortion); "" = an
#: OpenCV FileStorage file without a model (OpenCV's vector lengths).
_COEFFICIENT_COUNTS = {"plumb_bob": (0, 5), "rational_polynomial": (0, 8),
                       "": (0, 4, 5, 8, 12, 14)}

#: Plausible intrinsics: focal lengths within these multiples of the image width (a
#: horizontal field of view between 0.06 and 176 degrees) ...
FOCAL_RANGE = (0.01, 1000.0)
#: ... fy / fx (pixel aspect ratio) within these ...
ASPECT_RANGE = (0.1, 10.0)
#: ... |skew| at most this fraction of fx (axes within about 6 degrees of perpendicular) ...
MAX_SKEW = 0.1
#: ... the principal point within one image size of the image (cx in [-W, 2W]) ...
PRINCIPAL_POINT_MARGIN = 1.0
#: ... and every distortion coefficient within +-1000.
MAX_DISTORTION = 1000.0


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
    model_raw = data.get("distortion_model")
    if model_raw is not None and not isinstance(model_raw, str):
        raise InputError(f"must be a string, got {model_raw!r}", path=path,
                         field="distortion_model")
    no_model = model_raw is None
    model = "plumb_bob" if model_raw is None else model_raw.strip().lower()
    if dkey is None and model not in _NO_DISTORTION_MODELS:
        raise InputError("missing (is the file cut short?): a camera without distortion has "
                         "five zero coefficients, or distortion_model: none", path=path,
                         field=field)
    coeffs = np.zeros(0) if raw is None else _parse_matrix(raw, path, field).ravel()
    counts = _COEFFICIENT_COUNTS.get("" if no_model else model)
    if counts is not None and coeffs.size not in counts:
        which = ("an OpenCV file without distortion_model" if no_model else
                 f"distortion_model {model_raw}")
        raise InputError(f"{coeffs.size} distortion coefficients; {which} has "
                         f"{' or '.join(map(str, counts))} (or none: an empty list)", path=path,
                         field=field)
    big = np.flatnonzero(np.abs(coeffs) > MAX_DISTORTION)
    if big.size:
        i = int(big[0])
        raise InputError(f"coefficient {i} is {plain_number(coeffs[i])}, beyond the plausible "
                         f"+-{MAX_DISTORTION:g}", path=path, field=field)
    if model_raw is None:  # OpenCV files have no model: its coefficients are plumb_bob's
        model_raw = "plumb_bob"
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


def _check_plausible(K: NDArray[np.float64], width: int, height: int, path: StrPath,
                     field: str) -> None:
    """Refuse intrinsics no camera has (the ranges above), naming the value."""
    fx, fy, s, cx, cy = K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2]
    lo, hi = FOCAL_RANGE
    if not lo * width <= fx <= hi * width:
        raise InputError(f"fx = {plain_number(fx)} px is not a focal length of a {width} px wide "
                         f"image (plausible: {lo:g} to {hi:g} times the width)", path=path,
                         field=field)
    lo, hi = ASPECT_RANGE
    if not lo <= fy / fx <= hi:
        raise InputError(f"fy / fx = {plain_number(fy / fx)} (fx {plain_number(fx)}, fy "
                         f"{plain_number(fy)}); plausible: {lo:g} to {hi:g}", path=path,
                         field=field)
    if not abs(s) <= MAX_SKEW * fx:
        raise InputError(f"skew {plain_number(s)} px is implausible (at most {MAX_SKEW:g} fx "
                         f"= {plain_number(MAX_SKEW * fx)} px)", path=path, field=field)
    m = PRINCIPAL_POINT_MARGIN
    for name, c, size in (("cx", cx, width), ("cy", cy, height)):
        if not -m * size <= c <= (1 + m) * size:
            raise InputError(f"principal point {name} = {plain_number(c)} px is far outside "
                             f"the {width}x{height} image (plausible: {plain_number(-m * size)} "
                             f"to {plain_number((1 + m) * size)})", path=path, field=field)


def check_camera(camera: PinholeCamera, path: StrPath, field: str) -> PinholeCamera:
    """Refuse a camera ``camera.yaml`` would refuse - an image size outside the limits,
    intrinsics no camera has, a distortion coefficient beyond +-1000 - naming ``path``
    and ``field`` (e.g. a photo and the metadata its camera came from). The one check
    shared by every reader that makes a camera (``import dji``, ``import rosbag``)."""
    check_image_size(camera.width, camera.height, path, field=field, what="the image size")
    _check_plausible(camera.K, camera.width, camera.height, path, field)
    big = [i for i, c in enumerate(camera.distortion) if not abs(c) <= MAX_DISTORTION]
    if big:
        i = big[0]
        raise InputError(f"coefficient {i} is {plain_number(camera.distortion[i])}, beyond "
                         f"the plausible +-{MAX_DISTORTION:g}", path=path, field=field)
    return camera


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
    check_image_size(width, height, path, field="image_width, image_height",
                     what="the image size")

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
            raise InputError(f"focal length {name} must be positive, got {plain_number(v)}",
                             path=path, field=kkey)
    _check_plausible(K, width, height, path, kkey)
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
