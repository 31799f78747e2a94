"""The table of DJI cameras (``turbinefit/data/dji_cameras.yaml``): what a photo's EXIF does
not say about its camera - the sensor's width behind the photo, the lens, which camera of a
payload it is, the gimbal's pitch range.

:func:`dji_cameras` reads and checks the table (every number through
:mod:`turbinefit.io.quantities`); :func:`find_camera` finds a photo's entry by its EXIF
model, width and focal length (the table file's header says how). The focal length in
pixels of a photo ``W`` px wide is then ``focal_length_mm * W / sensor_width_mm``, the
lens's millimetres being the photo's EXIF ``FocalLength`` (a zoom lens) or the table's (a
fixed lens, also when the EXIF has none). The gimbal's pitch range is kept machine-readable
for planners (:attr:`DjiCamera.gimbal_pitch_deg`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

from turbinefit.errors import InputError
from turbinefit.io.quantities import Quantity
from turbinefit.io.yaml_files import load_yaml_mapping

#: The table shipped with the package.
TABLE = Path(__file__).resolve().parent.parent / "data" / "dji_cameras.yaml"
#: Kinds of camera (``import dji --camera``).
KINDS = ("wide", "zoom", "thermal")
#: How far a photo's EXIF focal length may lie outside an entry's range and still match.
FOCAL_TOLERANCE = 0.03

_FOCAL = Quantity("focal length", "mm", 0.0, 2000.0, lo_open=True)
_SENSOR = Quantity("sensor width", "mm", 0.0, 100.0, lo_open=True)
_WIDTH = Quantity("photo width", "px", 1.0, 100000.0, integer=True)
_PITCH = Quantity("gimbal pitch", "deg", -180.0, 180.0)


@dataclass(frozen=True)
class DjiCamera:
    """One camera of the table.

    Attributes:
        name: the payload and camera (``Zenmuse H20T thermal``).
        kind: ``wide``, ``zoom`` or ``thermal``.
        models: EXIF ``Model`` values (upper case).
        widths: photo widths it writes [px].
        focal_range_mm: (min, max) focal length [mm]; min == max for a fixed lens.
        sensor_width_mm: width of the sensor area a photo's width spans [mm].
        gimbal_pitch_deg: (min, max) controllable gimbal pitch [deg].
        source: the published specification.
    """

    name: str
    kind: str
    models: tuple[str, ...]
    widths: tuple[int, ...]
    focal_range_mm: tuple[float, float]
    sensor_width_mm: float
    gimbal_pitch_deg: tuple[float, float]
    source: str

    @property
    def fixed_focal(self) -> bool:
        return self.focal_range_mm[0] == self.focal_range_mm[1]

    def matches_focal(self, focal_mm: float | None) -> bool:
        """Whether an EXIF focal length (None: unknown) fits this camera's lens."""
        if focal_mm is None:
            return True
        lo, hi = self.focal_range_mm
        return lo * (1 - FOCAL_TOLERANCE) <= focal_mm <= hi * (1 + FOCAL_TOLERANCE)

    def focal_px(self, width: int, focal_mm: float | None) -> float | None:
        """Focal length [px] of a photo ``width`` px wide whose EXIF says ``focal_mm``
        (None: unknown; then only a fixed lens answers)."""
        if focal_mm is None:
            if not self.fixed_focal:
                return None
            focal_mm = self.focal_range_mm[0]
        return focal_mm * width / self.sensor_width_mm


def _pair(value: object, path: Path, field: str, q: Quantity) -> tuple[float, float]:
    if isinstance(value, list) and len(value) == 2:
        lo, hi = (q.check(v, path, field=field) for v in value)
    else:
        lo = hi = q.check(value, path, field=field)
    if lo > hi:
        raise InputError(f"[min, max] with min > max: {value!r}", path=path, field=field)
    return lo, hi


def _entry(i: int, data: object, path: Path) -> DjiCamera:
    where = f"cameras[{i}]"
    if not isinstance(data, dict):
        raise InputError("must be a mapping", path=path, field=where)
    keys = {"name", "kind", "models", "widths", "focal_length_mm", "sensor_width_mm",
            "gimbal_pitch_deg", "source"}
    missing, unknown = keys - set(data), set(data) - keys
    if missing or unknown:
        what = f"missing {', '.join(sorted(missing))}" if missing else \
            f"unknown key {', '.join(sorted(unknown))}"
        raise InputError(what, path=path, field=where)
    if data["kind"] not in KINDS:
        raise InputError(f"kind must be one of {', '.join(KINDS)}", path=path,
                         field=f"{where}.kind")
    models, widths = data["models"], data["widths"]
    if not isinstance(models, list) or not models or not isinstance(widths, list) or not widths:
        raise InputError("models and widths must be non-empty lists", path=path, field=where)
    return DjiCamera(
        name=str(data["name"]), kind=str(data["kind"]),
        models=tuple(str(m).upper() for m in models),
        widths=tuple(int(_WIDTH.check(w, path, field=f"{where}.widths")) for w in widths),
        focal_range_mm=_pair(data["focal_length_mm"], path, f"{where}.focal_length_mm", _FOCAL),
        sensor_width_mm=_SENSOR.check(data["sensor_width_mm"], path,
                                      field=f"{where}.sensor_width_mm"),
        gimbal_pitch_deg=_pair(data["gimbal_pitch_deg"], path, f"{where}.gimbal_pitch_deg",
                               _PITCH),
        source=str(data["source"]))


@cache
def dji_cameras(path: Path = TABLE) -> tuple[DjiCamera, ...]:
    """The table's cameras, checked.

    Raises:
        InputError: naming the file and entry of a malformed one.
    """
    data = load_yaml_mapping(path)
    entries = data.get("cameras")
    if not isinstance(entries, list) or not entries:
        raise InputError("must list cameras", path=path, field="cameras")
    return tuple(_entry(i, e, path) for i, e in enumerate(entries))


def find_camera(make: str, model: str, width: int, focal_mm: float | None,
                table: tuple[DjiCamera, ...] | None = None) -> DjiCamera | None:
    """The table's camera of a photo by its EXIF make and model, its width [px] and EXIF
    focal length [mm] (None: not in the EXIF), or None if it is not in the table."""
    if make.strip().upper() != "DJI":
        return None
    key = model.strip().upper()
    for cam in table if table is not None else dji_cameras():
        if key in cam.models and width in cam.widths and cam.matches_focal(focal_mm):
            return cam
    return None
