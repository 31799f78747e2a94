"""COCO keypoint annotation files (as CVAT and Label Studio export them) for turbine photos.

Users label the six model points of the turbines in their own photos, export the labels
as COCO keypoints and fine-tune the heat-map CNN on them. This module reads and writes
such files; it checks that every image file exists but never decodes an image.

**Keypoints.** One turbine has the six points of
:data:`turbinefit.turbine.model.POINT_NAMES`, in this order (:data:`KEYPOINT_NAMES`)::

    base, tower_top, hub, tip_1, tip_2, tip_3

A category's ``keypoints`` list may name them in any order and is mapped by name; a name
that is not one of ours is an error, a name missing from the list means that point is not
labelled in any annotation of that category. The three tips are interchangeable for the
CNN (one heat-map channel holds all three) but are kept as labelled, in the file's order.

**Visibility** (COCO): 0 = not labelled, 1 = labelled but not visible (occluded),
2 = labelled and visible. 1 and 2 both count as labelled and the value is kept. The
coordinates of a point with visibility 0 are meaningless in COCO; they are read (and
stored) as 0.

**Coordinates**: keypoint ``x, y`` are pixels, ``x`` to the right and ``y`` down, with
pixel (0, 0) the centre of the top-left pixel - the same convention as the rest of
turbinefit (``u = x``, ``v = y``), so no half-pixel shift is applied on reading or writing.
Coordinates are not checked against the image size (a point may lie slightly outside).

**Which categories are used.** Only categories with a non-empty ``keypoints`` list are
keypoint categories. If the name of one or more of them contains ``turbine``
(case-insensitive), exactly those are used; otherwise all keypoint categories are used.
Annotations of any other category (bounding boxes, people, ...) are ignored, as are the
keypoint names of unused categories. ``num_keypoints``, ``bbox``, ``area``, ``iscrowd`` and
``segmentation`` of an annotation are ignored on reading (they are derived data).

**Images.** Every entry of ``images`` is kept, in file order; one with no (used)
annotation is a labelled negative: a photo with no turbine. An image may hold several
turbines (one annotation each, in file order). ``file_name`` is relative to
``images_dir`` or absolute; if no file exists there, ``images_dir / basename(file_name)``
is tried (the basename is taken after the last ``/`` or ``\\``), so that Label Studio's
``images/abc.jpg`` or ``/data/upload/1/abc.jpg`` resolve to ``images_dir/abc.jpg``.
``width`` and ``height`` are taken from the image entry.

**Errors.** Reading checks the whole file before returning anything and raises
:class:`~turbinefit.errors.InputError` with one line naming the file and the JSON field,
e.g. ``labels.json [annotations[3].keypoints]: expected 18 numbers (6 keypoints x 3), got
15``, for: a missing, unreadable or non-JSON file (with the line of the JSON error); a top
level that is not an object; a missing or non-list ``images`` / ``annotations`` /
``categories``; no category with keypoints; an unknown or duplicate keypoint name; a
keypoints list of the wrong length; a non-numeric or non-finite coordinate; a visibility
not in {0, 1, 2}; an ``image_id`` or ``category_id`` that matches no image or category;
duplicate image or category ids; a missing image file (naming the image id and the paths
tried); a ``width`` or ``height`` that is not a positive integer; and an ``images_dir``
that is not a directory.

**Writing** produces one category ``{"id": 1, "name": "wind_turbine", "keypoints":
KEYPOINT_NAMES, "skeleton": [[1, 2], [2, 3], [3, 4], [3, 5], [3, 6]]}`` (COCO skeletons
are 1-based: tower, nacelle, three blades), image ids 1..N and annotation ids 1..M in
order, ``file_name`` relative to ``images_dir`` with ``/`` separators, and per annotation
``keypoints`` (``x, y, v`` x 6), ``num_keypoints`` (labelled points), ``bbox`` ``[x, y, w,
h]`` of the labelled points (``[0, 0, 0, 0]`` if none), ``area = w * h`` and ``iscrowd``
0. Floats are written with ``repr`` precision, so a write-read round trip is exact. The
file is written atomically (:func:`turbinefit.io.atomic.write_text_atomic`).
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.errors import InputError
from turbinefit.io.atomic import StrPath, read_text, write_text_atomic
from turbinefit.io.quantities import pixel
from turbinefit.turbine.model import POINT_NAMES

__all__ = [
    "CATEGORY_NAME",
    "KEYPOINT_NAMES",
    "SKELETON",
    "LabelledImage",
    "TurbineKeypoints",
    "format_coco_keypoints",
    "read_coco_keypoints",
    "write_coco_keypoints",
]

#: How far [px] a labelled keypoint may lie beyond its image's edge pixels' centres (half
#: a pixel is the edge itself; labelling tools clamp points to it).
KEYPOINT_MARGIN_PX = 1.0

#: Names of the six keypoints of a turbine, in order (= the model's ``POINT_NAMES``).
KEYPOINT_NAMES: tuple[str, ...] = tuple(POINT_NAMES)
#: Name of the one category written.
CATEGORY_NAME = "wind_turbine"
#: COCO skeleton written (1-based keypoint indices): tower, nacelle, blades 1-3.
SKELETON: tuple[tuple[int, int], ...] = ((1, 2), (2, 3), (3, 4), (3, 5), (3, 6))

_N = len(KEYPOINT_NAMES)
_VISIBILITIES = (0, 1, 2)


# ============================================================================ data types

@dataclass(frozen=True, eq=False)
class TurbineKeypoints:
    """The labelled keypoints of one turbine in one image.

    Attributes:
        uv: (6, 2) float64, pixel coordinates ``(u, v)`` = COCO ``(x, y)`` (u right, v
            down, pixel (0, 0) = centre of the top-left pixel), rows in the order of
            :data:`KEYPOINT_NAMES`. Must be finite: an unlabelled point has visibility 0,
            and its coordinates are stored as 0 whatever was given.
        visibility: (6,) int8, COCO visibility per point: 0 = not labelled, 1 = labelled
            but occluded, 2 = labelled and visible.

    Both arrays are copied and made read-only. A bad shape or value is a ValueError.
    Instances compare equal when both arrays are equal.
    """

    uv: NDArray[np.float64]
    visibility: NDArray[np.int8]

    def __init__(self, uv: ArrayLike, visibility: ArrayLike) -> None:
        u = np.array(uv, dtype=np.float64)
        if u.shape != (_N, 2):
            raise ValueError(f"uv must have shape ({_N}, 2), got {u.shape}")
        if not np.all(np.isfinite(u)):
            raise ValueError("uv must be finite (mark an unlabelled point with visibility 0)")
        vis_in = np.asarray(visibility)
        if vis_in.shape != (_N,):
            raise ValueError(f"visibility must have shape ({_N},), got {vis_in.shape}")
        if not np.all(np.isin(vis_in, _VISIBILITIES)):
            raise ValueError(f"visibility must be 0, 1 or 2, got {vis_in.tolist()}")
        vis = vis_in.astype(np.int8)
        u[vis == 0] = 0.0
        u += 0.0  # -0.0 -> 0.0, so that equal labels hash equally
        u.setflags(write=False)
        vis.setflags(write=False)
        object.__setattr__(self, "uv", u)
        object.__setattr__(self, "visibility", vis)

    @property
    def labelled(self) -> NDArray[np.bool_]:
        """(6,) bool: which points are labelled (visibility 1 or 2)."""
        return self.visibility > 0

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TurbineKeypoints):
            return NotImplemented
        return bool(np.array_equal(self.uv, other.uv)
                    and np.array_equal(self.visibility, other.visibility))

    def __hash__(self) -> int:
        return hash((self.uv.tobytes(), self.visibility.tobytes()))

    def __repr__(self) -> str:
        return f"TurbineKeypoints(uv={self.uv.tolist()}, visibility={self.visibility.tolist()})"


@dataclass(frozen=True)
class LabelledImage:
    """One labelled photo.

    Attributes:
        path: the image file. As read: ``images_dir / file_name`` (or ``images_dir /
            basename(file_name)``, or ``file_name`` itself if absolute), the file that was
            found; it is not made absolute.
        width, height: image size in pixels, from the COCO image entry (not from the file).
        turbines: the turbines labelled in it; empty for a labelled negative (no turbine).
    """

    path: Path
    width: int
    height: int
    turbines: tuple[TurbineKeypoints, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", Path(self.path))
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v <= 0:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
            object.__setattr__(self, name, int(v))
        turbines = tuple(self.turbines)
        for t in turbines:
            if not isinstance(t, TurbineKeypoints):
                raise ValueError(f"turbines must be TurbineKeypoints, got {type(t).__name__}")
            for axis, n in enumerate((self.width, self.height)):
                inside = pixel("xy"[axis], n, KEYPOINT_MARGIN_PX)
                bad = [inside.problem(float(c)) for c in t.uv[t.labelled, axis]]
                if any(bad):
                    raise ValueError(f"labelled keypoint {next(b for b in bad if b)} of the "
                                     f"{self.width}x{self.height} image")
        object.__setattr__(self, "turbines", turbines)

    def check_size(self, width: int, height: int) -> None:
        """Raise :class:`InputError` (naming the file) unless the image file's size
        ``width`` x ``height`` is the size its label entry says."""
        if (width, height) != (self.width, self.height):
            raise InputError(f"image is {width}x{height} but its label entry says "
                             f"{self.width}x{self.height}", path=self.path)


# ============================================================================== reading

def _kind(value: Any) -> str:
    """The JSON type name of a parsed value, for messages."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int | float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__  # pragma: no cover - json.loads makes nothing else


def _short(value: Any) -> str:
    """``value`` as JSON, shortened for a one-line message."""
    try:
        s = json.dumps(value)
    except ValueError:  # pragma: no cover - NaN etc. are allowed by default
        s = repr(value)
    return s if len(s) <= 40 else s[:37] + "..."


class _Reader:
    """Parsed JSON plus the file name, so that every check can name the file."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def error(self, message: str, field: str) -> InputError:
        return InputError(message, path=self.path, field=field)

    def list_of(self, top: dict[str, Any], key: str) -> list[Any]:
        if key not in top:
            raise self.error("missing", key)
        value = top[key]
        if not isinstance(value, list):
            raise self.error(f"expected a list, got {_kind(value)}", key)
        return value

    def obj(self, value: Any, field: str) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.error(f"expected an object, got {_kind(value)}", field)
        return value

    def member(self, entry: dict[str, Any], key: str, field: str) -> Any:
        if key not in entry:
            raise self.error("missing", f"{field}.{key}")
        return entry[key]

    def ident(self, entry: dict[str, Any], key: str, field: str) -> int | str:
        value = self.member(entry, key, field)
        if isinstance(value, bool) or not isinstance(value, int | str):
            raise self.error(f"expected an integer or string id, got {_short(value)}",
                             f"{field}.{key}")
        return value

    def positive_int(self, entry: dict[str, Any], key: str, field: str) -> int:
        value = self.member(entry, key, field)
        ok = isinstance(value, int) and not isinstance(value, bool)
        if isinstance(value, float) and math.isfinite(value) and value.is_integer():
            ok, value = True, int(value)
        if not ok or value <= 0:
            raise self.error(f"expected a positive integer, got {_short(value)}",
                             f"{field}.{key}")
        return int(value)

    def number(self, value: Any, field: str, what: str) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(f"{what}: expected a number, got {_short(value)}", field)
        try:
            v = float(value)
        except OverflowError:  # an integer beyond the float range
            v = math.inf
        if not math.isfinite(v):
            raise self.error(f"{what}: must be finite, got {value!r}", field)
        return v


def _load_json(path: Path) -> Any:
    text = read_text(path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"not valid JSON: {e.msg} (column {e.colno})", path=path,
                         line=e.lineno) from e
    except RecursionError as e:
        raise InputError("not valid JSON: nested too deeply", path=path) from e


def _keypoint_categories(r: _Reader, categories: list[Any]
                         ) -> tuple[dict[int | str, list[int]], set[int | str]]:
    """The used categories (id -> our index of each of the category's keypoints, in the
    file's order) and the ids of all categories."""
    all_ids: set[int | str] = set()
    candidates: list[tuple[int | str, str, int]] = []  # (id, name, index in categories)
    for i, entry in enumerate(categories):
        field = f"categories[{i}]"
        cat = r.obj(entry, field)
        cid = r.ident(cat, "id", field)
        if cid in all_ids:
            raise r.error(f"duplicate category id {cid!r}", f"{field}.id")
        all_ids.add(cid)
        name = cat.get("name", "")
        if not isinstance(name, str):
            raise r.error(f"expected a string, got {_short(name)}", f"{field}.name")
        kps = cat.get("keypoints")
        if kps is None:
            continue
        if not isinstance(kps, list):
            raise r.error(f"expected a list of keypoint names, got {_kind(kps)}",
                          f"{field}.keypoints")
        if kps:
            candidates.append((cid, name, i))
    if not candidates:
        raise r.error("no category has a 'keypoints' list", "categories")
    turbines = [c for c in candidates if "turbine" in c[1].lower()]
    used: dict[int | str, list[int]] = {}
    for cid, _name, i in turbines or candidates:
        mapping: list[int] = []
        seen: set[str] = set()
        for j, kname in enumerate(categories[i]["keypoints"]):
            field = f"categories[{i}].keypoints[{j}]"
            if not isinstance(kname, str):
                raise r.error(f"expected a keypoint name, got {_short(kname)}", field)
            if kname not in KEYPOINT_NAMES:
                raise r.error(f"unknown keypoint name {kname!r} "
                              f"(expected some of {', '.join(KEYPOINT_NAMES)})", field)
            if kname in seen:
                raise r.error(f"duplicate keypoint name {kname!r}", field)
            seen.add(kname)
            mapping.append(KEYPOINT_NAMES.index(kname))
        used[cid] = mapping
    return used, all_ids


def _split_name(file_name: str) -> str:
    """The last component of a posix or Windows path."""
    return re.split(r"[/\\]", file_name.rstrip("/\\"))[-1]


def _find_image(r: _Reader, images_dir: Path, image_id: int | str, file_name: str,
                field: str) -> Path:
    first = images_dir / file_name  # an absolute file_name replaces images_dir
    tried = [first]
    base = _split_name(file_name)
    if base and images_dir / base != first:
        tried.append(images_dir / base)
    for candidate in tried:
        try:
            if candidate.is_file():
                return candidate
        except OSError:  # pragma: no cover - e.g. a name too long for the file system
            continue
    raise r.error(f"image {image_id!r}: file not found (tried {', '.join(map(str, tried))})",
                  field)


def _parse_keypoints(r: _Reader, value: Any, mapping: list[int], field: str,
                     size: tuple[int, int]) -> TurbineKeypoints:
    k = len(mapping)
    if not isinstance(value, list):
        raise r.error(f"expected a list of {3 * k} numbers, got {_kind(value)}", field)
    if len(value) != 3 * k:
        raise r.error(f"expected {3 * k} numbers ({k} keypoints x 3), got {len(value)}", field)
    uv = np.zeros((_N, 2))
    vis = np.zeros(_N, dtype=np.int8)
    for j, ours in enumerate(mapping):
        name = KEYPOINT_NAMES[ours]
        x = r.number(value[3 * j], f"{field}[{3 * j}]", f"keypoint {name!r} x")
        y = r.number(value[3 * j + 1], f"{field}[{3 * j + 1}]", f"keypoint {name!r} y")
        v = value[3 * j + 2]
        if isinstance(v, bool) or not isinstance(v, int | float) or v not in _VISIBILITIES:
            raise r.error(f"keypoint {name!r} visibility: expected 0, 1 or 2, got {_short(v)}",
                          f"{field}[{3 * j + 2}]")
        if v > 0:  # a labelled point lies in its image (labelling tools clamp to its edges)
            for axis, c, n, at in (("x", x, size[0], 3 * j), ("y", y, size[1], 3 * j + 1)):
                why = pixel(f"keypoint {name!r} {axis}", n, KEYPOINT_MARGIN_PX).problem(c)
                if why is not None:
                    raise r.error(f"{why} of the {size[0]}x{size[1]} image", f"{field}[{at}]")
        uv[ours] = (x, y)
        vis[ours] = int(v)
    return TurbineKeypoints(uv, vis)


def read_coco_keypoints(json_path: StrPath, images_dir: StrPath) -> list[LabelledImage]:
    """Read the labelled turbine keypoints of a COCO keypoints file (see module docstring).

    Args:
        json_path: the COCO JSON file (as exported by CVAT, Label Studio, ...).
        images_dir: directory that ``file_name`` of each image is relative to.

    Returns:
        One :class:`LabelledImage` per entry of ``images``, in file order, each with its
        turbines in annotation order (pixel coordinates, u right, v down, pixel (0, 0) =
        centre of the top-left pixel). Images without annotations have no turbines.

    Raises:
        InputError: one line naming the file and the JSON field (or ``images_dir``), for
            any bad input; the whole file is checked before anything is returned, and
            every image file must exist (it is not decoded).
    """
    p = Path(json_path)
    idir = Path(images_dir)
    try:
        is_dir = idir.is_dir()
    except OSError as e:  # pragma: no cover - e.g. permissions on a parent
        raise InputError(f"cannot access images directory: {e.strerror or e}", path=idir) from e
    if not is_dir:
        what = "does not exist" if not os.path.lexists(idir) else "is not a directory"
        raise InputError(f"images directory {what}", path=idir)
    r = _Reader(p)
    top = _load_json(p)
    if not isinstance(top, dict):
        raise InputError(f"expected a JSON object at the top level, got {_kind(top)}", path=p)
    images = r.list_of(top, "images")
    annotations = r.list_of(top, "annotations")
    categories = r.list_of(top, "categories")
    used, all_categories = _keypoint_categories(r, categories)

    index: dict[int | str, int] = {}  # image id -> position in images
    entries: list[tuple[Path, int, int]] = []
    for i, entry in enumerate(images):
        field = f"images[{i}]"
        img = r.obj(entry, field)
        iid = r.ident(img, "id", field)
        if iid in index:
            raise r.error(f"duplicate image id {iid!r} (also images[{index[iid]}])",
                          f"{field}.id")
        index[iid] = i
        file_name = r.member(img, "file_name", field)
        if not isinstance(file_name, str) or not file_name.strip():
            raise r.error(f"expected a non-empty string, got {_short(file_name)}",
                          f"{field}.file_name")
        width = r.positive_int(img, "width", field)
        height = r.positive_int(img, "height", field)
        entries.append((_find_image(r, idir, iid, file_name, f"{field}.file_name"),
                        width, height))

    turbines: list[list[TurbineKeypoints]] = [[] for _ in entries]
    for a, entry in enumerate(annotations):
        field = f"annotations[{a}]"
        ann = r.obj(entry, field)
        iid = r.ident(ann, "image_id", field)
        if iid not in index:
            raise r.error(f"image id {iid!r} is not among images", f"{field}.image_id")
        cid = r.ident(ann, "category_id", field)
        if cid not in all_categories:
            raise r.error(f"category id {cid!r} is not among categories",
                          f"{field}.category_id")
        if cid not in used:
            continue
        kps = r.member(ann, "keypoints", field)
        size = entries[index[iid]][1:]
        turbines[index[iid]].append(_parse_keypoints(r, kps, used[cid], f"{field}.keypoints",
                                                     size))

    return [LabelledImage(path, w, h, tuple(t))
            for (path, w, h), t in zip(entries, turbines, strict=True)]


# ============================================================================== writing

def _relative_name(path: Path, images_dir: Path, where: Path | None, field: str) -> str:
    """``path`` relative to ``images_dir`` as a posix string, else an InputError naming
    ``where`` and ``field``."""
    pairs: list[tuple[PurePath, PurePath]] = []
    if path.is_absolute() == images_dir.is_absolute():
        pairs.append((path, images_dir))
    pairs.append((path.absolute(), images_dir.absolute()))
    try:
        pairs.append((path.resolve(), images_dir.resolve()))
    except (OSError, RuntimeError):  # pragma: no cover - symbolic-link loops
        pass
    for a, b in pairs:
        try:
            rel = a.relative_to(b)
        except ValueError:
            continue
        if rel.parts:
            return rel.as_posix()
    raise InputError(f"image {str(path)!r} is not inside the images directory "
                     f"{str(images_dir)!r}", path=where, field=field)


def _format(images: Sequence[LabelledImage], images_dir: Path, where: Path | None) -> str:
    image_entries: list[dict[str, Any]] = []
    annotations: list[dict[str, Any]] = []
    for i, img in enumerate(images, start=1):
        if not isinstance(img, LabelledImage):
            raise TypeError(f"images[{i - 1}] is a {type(img).__name__}, expected LabelledImage")
        name = _relative_name(img.path, images_dir, where, f"images[{i - 1}].path")
        image_entries.append({"id": i, "file_name": name, "width": img.width,
                              "height": img.height})
        for t in img.turbines:
            flat: list[float | int] = []
            for (x, y), v in zip(t.uv.tolist(), t.visibility.tolist(), strict=True):
                flat += [float(x), float(y), int(v)]
            lab = t.uv[t.labelled]
            if len(lab):
                x0, y0 = (float(c) for c in lab.min(axis=0))
                w, h = (float(c) for c in lab.max(axis=0) - lab.min(axis=0))
            else:
                x0 = y0 = w = h = 0.0
            annotations.append({
                "id": len(annotations) + 1, "image_id": i, "category_id": 1,
                "keypoints": flat, "num_keypoints": int(np.count_nonzero(t.labelled)),
                "bbox": [x0, y0, w, h], "area": w * h, "iscrowd": 0,
            })
    category = {"id": 1, "name": CATEGORY_NAME, "supercategory": "",
                "keypoints": list(KEYPOINT_NAMES), "skeleton": [list(s) for s in SKELETON]}

    def dump(value: Any) -> str:
        return json.dumps(value, allow_nan=False, ensure_ascii=False)

    def block(key: str, entries: Sequence[Any]) -> str:
        if not entries:
            return f"  {dump(key)}: []"
        return f"  {dump(key)}: [\n" + ",\n".join("    " + dump(e) for e in entries) + "\n  ]"

    parts = [f'  "info": {dump({"description": "turbinefit wind-turbine keypoints"})}',
             '  "licenses": []',
             block("images", image_entries),
             block("annotations", annotations),
             block("categories", [category])]
    return "{\n" + ",\n".join(parts) + "\n}\n"


def format_coco_keypoints(images: Sequence[LabelledImage], images_dir: StrPath) -> str:
    """The COCO keypoints JSON text that :func:`write_coco_keypoints` writes.

    Args:
        images: the labelled images; each ``path`` must lie inside ``images_dir``.
        images_dir: directory that the written ``file_name`` entries are relative to.

    Returns:
        JSON text (one image or annotation per line, ``\\n`` line ends), see the module
        docstring for its content.

    Raises:
        InputError: an image path that is not inside ``images_dir`` (compared as given,
            as absolute paths and with symbolic links resolved).
    """
    return _format(images, Path(images_dir), None)


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        pass
    try:
        return a.resolve() == b.resolve()
    except (OSError, RuntimeError):  # pragma: no cover - symbolic-link loops
        return a.absolute() == b.absolute()


def write_coco_keypoints(images: Sequence[LabelledImage], json_path: StrPath,
                         images_dir: StrPath) -> Path:
    """Write labelled images as a COCO keypoints file, atomically.

    Args:
        images: the labelled images (pixel coordinates, see :class:`TurbineKeypoints`);
            each ``path`` must lie inside ``images_dir``. The image files are not read.
        json_path: destination JSON file (replaced if it exists, unless it is one of the
            images). Missing parent directories are created.
        images_dir: directory that the written ``file_name`` entries are relative to.

    Returns:
        The path written.

    Raises:
        InputError: naming ``json_path`` for a destination that is one of the image files
            (or a directory, or cannot be written), or an image outside ``images_dir``.
            Nothing is written then.
    """
    p = Path(json_path)
    for i, img in enumerate(images):
        if isinstance(img, LabelledImage) and _same_file(p, img.path):
            raise InputError(f"refusing to overwrite an input: it is the image of images[{i}]",
                             path=p)
    return write_text_atomic(p, _format(images, Path(images_dir), p))
