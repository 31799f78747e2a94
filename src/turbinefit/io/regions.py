"""Box and mask labels of turbine photos: the labels users have when they have no keypoints.

Three formats, each read into :class:`RegionLabel` s (one per photo, in file order), every
photo found on disk and every box checked before anything is returned:

* **Box CSV** (:func:`read_box_csv`), one box a row::

      filename,width,height,class,xmin,ymin,xmax,ymax

  with or without that header line (any other header is refused), and optionally a ninth
  column ``defect`` naming the known defect the box shows (``simulate``'s
  ``defect_boxes.csv``; every row then has it, it may be empty). Coordinates are pixel
  edges (0 is the left edge of the first pixel, ``xmax`` = ``width`` the right edge of the
  last): ``0 <= xmin < xmax <= width``, the same in y. Rows of one ``filename`` are boxes of
  one photo and must agree on its size. The photo is ``images_dir / filename``, or, if
  there is none, ``images_dir / class / filename`` (a folder per class, as public data
  sets ship them).
* **COCO boxes and outlines** (:func:`read_coco_boxes`): ``images`` (``id``,
  ``file_name``, ``width``, ``height``), ``annotations`` (``image_id``, ``category_id``,
  ``bbox`` = ``[x, y, w, h]``, pixel edges, and, where the labelling tool exported them,
  ``segmentation`` polygons ``[[x1, y1, x2, y2, ...], ...]``, which then stand for the
  annotation instead of its box, or a run-length-encoded mask, COCO's RLE ``{"size": [h,
  w], "counts": ...}``, compressed or not, decoded by pycocotools, the ``coco`` extra),
  ``categories`` (``id``, ``name``: the class); photos resolved as
  :mod:`turbinefit.io.coco` does. An image without annotations is a negative (no
  turbine).
* **Masks** (:func:`read_mask_folder`): a folder of label PNGs, ``<stem>.png`` the mask of
  the photo ``images_dir / <stem>.*`` (PNG or JPEG); any value above 0 is turbine. The
  mask's size must be its photo's (checked by the job from the headers,
  :meth:`RegionLabel.check_size`).

Errors are :class:`~turbinefit.errors.InputError` s of one line naming the file and row
(CSV line, JSON field or mask file): unknown columns, a box outside its image or empty, a
photo that is missing, sizes that disagree.
"""

from __future__ import annotations

import csv
import functools
import io
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import InputError
from turbinefit.io.atomic import StrPath, read_text
from turbinefit.io.images import IMAGE_SUFFIXES

#: The columns of a box CSV, in order.
BOX_COLUMNS = ("filename", "width", "height", "class", "xmin", "ymin", "xmax", "ymax")
#: The optional last column of a box CSV: the known defect a box shows.
DEFECT_COLUMN = "defect"

Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class RegionLabel:
    """One labelled photo.

    Attributes:
        path: the photo file (found on disk).
        size: (width, height) the label says the photo is; None for a mask (its own size).
        boxes: (class, (left, top, right, bottom)) of each box, pixel edges; empty for a
            mask or a negative.
        mask: the mask PNG, or None.
        where: file and row the label came from, for messages (``boxes.csv:12``).
        polygons: (class, (x1, y1, x2, y2, ...)) of each outline (COCO ``segmentation``),
            pixel edges.
        rles: (class, RLE) of each run-length-encoded mask (COCO ``segmentation``;
            :func:`decode_rle`).
        defects: the known defect each box shows (a box CSV's ``defect`` column, one per
            box, ``""`` for none); empty without that column.
    """

    path: Path
    size: tuple[int, int] | None
    boxes: tuple[tuple[str, Box], ...] = ()
    mask: Path | None = None
    where: str = ""
    polygons: tuple[tuple[str, tuple[float, ...]], ...] = ()
    rles: tuple[tuple[str, dict[str, Any]], ...] = ()
    defects: tuple[str, ...] = ()

    @property
    def classes(self) -> tuple[str, ...]:
        """The classes of its boxes and outlines in first-seen order (``("turbine",)`` for
        a mask)."""
        if self.mask is not None:
            return ("turbine",)
        return tuple(dict.fromkeys(c for c, _ in (*self.boxes, *self.polygons, *self.rles)))

    @property
    def outlined(self) -> bool:
        """Whether the label outlines the turbine (a mask, or outlines and no boxes), so
        that the region's skeleton is the turbine's."""
        return self.mask is not None or (bool(self.polygons or self.rles) and not self.boxes)

    def check_size(self, width: int, height: int, mask_size: tuple[int, int] | None = None
                   ) -> None:
        """Raise :class:`InputError` naming the label's row unless the photo's size
        ``width`` x ``height`` is the label's (or, for a mask, the mask's ``mask_size``)."""
        want = mask_size if self.mask is not None else self.size
        if want is not None and tuple(want) != (width, height):
            what = "the mask" if self.mask is not None else "the label"
            raise InputError(f"photo {self.path} is {width}x{height} but {what} is "
                             f"{want[0]}x{want[1]}", path=self.where)


def _check_box(box: Box, size: tuple[int, int], where: str) -> None:
    x0, y0, x1, y1 = box
    w, h = size
    if not all(math.isfinite(v) for v in box):
        raise InputError(f"box {list(box)} has a non-finite coordinate", path=where)
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise InputError(f"box ({x0:g}, {y0:g})-({x1:g}, {y1:g}) is empty or outside its "
                         f"{w}x{h} image", path=where)


def _find_photo(images_dir: Path, names: list[str], where: str) -> Path:
    tried = [images_dir / n for n in names]
    for p in tried:
        if p.is_file():
            return p
    raise InputError(f"photo not found (tried {', '.join(map(str, tried))})", path=where)


def read_box_csv(path: StrPath, images_dir: StrPath) -> list[RegionLabel]:
    """Photos and boxes of a box CSV (module docstring), one label per photo."""
    p, d = Path(path), Path(images_dir)
    if not d.is_dir():
        raise InputError("images folder is not a directory", path=d)
    rows = list(csv.reader(io.StringIO(read_text(p))))
    out: dict[str, tuple[Path, tuple[int, int], list[tuple[str, Box]], str]] = {}
    names: dict[str, list[str]] = {}
    columns: tuple[str, ...] | None = None  # fixed by the header or the first row
    both = f"{','.join(BOX_COLUMNS)}[,{DEFECT_COLUMN}]"
    for k, row in enumerate(rows, start=1):
        where = f"{p}:{k}"
        cells = [c.strip() for c in row]
        if not cells or cells == [""]:
            continue
        if k == 1 and len(cells) > 1 and not cells[1].lstrip("-").isdigit():  # a header
            columns = tuple(c.lower() for c in cells)
            if columns not in (BOX_COLUMNS, (*BOX_COLUMNS, DEFECT_COLUMN)):
                raise InputError(f"unknown columns {','.join(cells)}; expected {both}",
                                 path=where)
            continue
        if columns is None and len(cells) in (len(BOX_COLUMNS), len(BOX_COLUMNS) + 1):
            columns = (BOX_COLUMNS if len(cells) == len(BOX_COLUMNS)
                       else (*BOX_COLUMNS, DEFECT_COLUMN))
        want = columns or BOX_COLUMNS
        if len(cells) != len(want):
            raise InputError(f"{len(cells)} columns, expected {len(want)} "
                             f"({','.join(want)})", path=where)
        name, ws, hs, cls = cells[:4]
        try:
            size = (int(ws), int(hs))
            box = tuple(float(v) for v in cells[4:8])
        except ValueError:
            raise InputError(f"width, height and coordinates must be numbers: {','.join(cells)}",
                             path=where) from None
        if min(size) <= 0 or not name or not cls:
            raise InputError("empty filename or class, or a size that is not positive",
                             path=where)
        _check_box(box, size, where)  # type: ignore[arg-type]
        if name not in out:
            out[name] = (_find_photo(d, [name, f"{cls}/{name}"], where), size, [], where)
        elif out[name][1] != size:
            raise InputError(f"{name} is {size[0]}x{size[1]} here but "
                             f"{out[name][1][0]}x{out[name][1][1]} at {out[name][3]}",
                             path=where)
        out[name][2].append((cls, box))  # type: ignore[arg-type]
        names.setdefault(name, []).append(cells[8] if len(cells) > 8 else "")
    if not out:
        raise InputError("no boxes in the file", path=p)
    with_defects = columns is not None and DEFECT_COLUMN in columns
    return [RegionLabel(ph, size, tuple(boxes), None, where,
                        defects=tuple(names[name]) if with_defects else ())
            for name, (ph, size, boxes, where) in out.items()]


def decode_rle(rle: dict[str, Any]) -> NDArray[np.bool_]:
    """The (h, w) mask of a COCO run-length encoding (``counts`` a list, or COCO's
    compressed string), by pycocotools (the ``coco`` extra)."""
    from pycocotools import mask as coco_mask

    h, w = rle["size"]
    counts = rle["counts"]
    if isinstance(counts, str):
        obj = {"size": [h, w], "counts": counts.encode("ascii")}
    else:
        obj = coco_mask.frPyObjects({"size": [h, w], "counts": list(counts)}, h, w)
    with warnings.catch_warnings():  # pycocotools 2.0's numpy-2 deprecation, not ours
        warnings.filterwarnings("ignore", category=DeprecationWarning, module="pycocotools")
        return np.asarray(coco_mask.decode(obj), dtype=bool)


def _rle(seg: dict[str, Any], size: tuple[int, int], error: Callable[[str], InputError]
         ) -> dict[str, Any]:
    """A COCO RLE, checked (its size the image's, its counts whole and adding up)."""
    w, h = size
    hw = seg.get("size")
    if hw != [h, w]:
        raise error(f"RLE size {hw!r} is not its image's [height, width] [{h}, {w}]")
    counts = seg.get("counts")
    if isinstance(counts, list):
        if not all(isinstance(c, int) and not isinstance(c, bool) and c >= 0 for c in counts):
            raise error("RLE counts must be whole numbers of at least 0")
        if sum(counts) != h * w:
            raise error(f"RLE counts add up to {sum(counts)}, not the image's {h * w} pixels")
    elif not (isinstance(counts, str) and counts.isascii() and counts):
        raise error("RLE counts must be a list of whole numbers or COCO's compressed string")
    try:  # decoded once here, so that a bad one fails before any photo is run
        decode_rle({"size": [h, w], "counts": counts})
    except ImportError:
        raise error("is run-length encoded (RLE), which needs pycocotools: "
                    "pip install 'turbinefit[coco]'") from None
    except Exception as e:  # pycocotools' own complaint about a malformed string
        raise error(f"cannot decode the RLE: {e}") from None
    return {"size": [h, w], "counts": counts}


def _polygons(seg: Any, size: tuple[int, int], error: Callable[[str], InputError]
              ) -> list[tuple[float, ...]]:
    """The outlines of a COCO ``segmentation`` (a list of polygons), each checked;
    ``error`` makes the exception of a message (naming the file and field)."""
    if not isinstance(seg, list):
        raise error("expected a list of polygons [[x1, y1, x2, y2, ...], ...] or an RLE")
    out = []
    w, h = size
    for n, poly in enumerate(seg):
        if not (isinstance(poly, list) and len(poly) >= 6 and len(poly) % 2 == 0
                and all(isinstance(v, int | float) and not isinstance(v, bool) for v in poly)):
            raise error(f"polygon {n}: expected [x1, y1, x2, y2, x3, y3, ...] (three or more "
                        "points)")
        xy = tuple(float(v) for v in poly)
        if not all(math.isfinite(v) for v in xy):
            raise error(f"polygon {n} has a non-finite coordinate")
        if not (all(0 <= x <= w for x in xy[0::2]) and all(0 <= y <= h for y in xy[1::2])):
            raise error(f"polygon {n} reaches outside its {w}x{h} image")
        out.append(xy)
    return out


def read_coco_boxes(path: StrPath, images_dir: StrPath) -> list[RegionLabel]:
    """Photos, boxes and outlines of a COCO file's annotations (module docstring): an
    annotation with ``segmentation`` polygons is outlined by them, one without by its
    ``bbox``."""
    from turbinefit.io.coco import _find_image, _load_json, _Reader

    p, d = Path(path), Path(images_dir)
    if not d.is_dir():
        raise InputError("images folder is not a directory", path=d)
    top = _load_json(p)
    r = _Reader(p)
    if not isinstance(top, dict):
        raise InputError("expected a JSON object at the top level", path=p)

    def num(obj: Any, key: str, where: str) -> float:
        v = obj.get(key) if isinstance(obj, dict) else None
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise r.error(f"missing or not a number: {v!r}", f"{where}.{key}")
        return float(v)

    cats = {c.get("id"): str(c.get("name", c.get("id")))
            for c in r.list_of(top, "categories") if isinstance(c, dict)}
    images: dict[Any, tuple[Path, tuple[int, int], list[tuple[str, Box]], str]] = {}
    outlines: dict[Any, list[tuple[str, tuple[float, ...]]]] = {}
    rles: dict[Any, list[tuple[str, dict[str, Any]]]] = {}
    for i, im in enumerate(r.list_of(top, "images")):
        f = f"images[{i}]"
        w, h = num(im, "width", f), num(im, "height", f)
        if w <= 0 or h <= 0 or w != int(w) or h != int(h):
            raise r.error(f"size {w:g}x{h:g} is not positive whole pixels", f)
        name = im.get("file_name")
        if not isinstance(name, str) or not name:
            raise r.error("missing or empty", f"{f}.file_name")
        images[im.get("id")] = (_find_image(r, d, im.get("id"), name, f),
                                (int(w), int(h)), [], f"{p} [{f}]")
    for i, a in enumerate(r.list_of(top, "annotations")):
        f = f"annotations[{i}]"
        if not isinstance(a, dict) or a.get("image_id") not in images:
            raise r.error("image_id matches no image", f)
        if a.get("category_id") not in cats:
            raise r.error("category_id matches no category", f)
        seg = a.get("segmentation")
        if seg not in (None, []):
            size = images[a["image_id"]][1]
            error = functools.partial(r.error, field=f"{f}.segmentation")
            cls = cats[a["category_id"]]
            if isinstance(seg, dict):
                rles.setdefault(a["image_id"], []).append((cls, _rle(seg, size, error)))
            else:
                outlines.setdefault(a["image_id"], []).extend(
                    (cls, xy) for xy in _polygons(seg, size, error))
            continue
        bb = a.get("bbox")
        if not (isinstance(bb, list) and len(bb) == 4
                and all(isinstance(v, int | float) and not isinstance(v, bool) for v in bb)):
            raise r.error(f"expected [x, y, width, height], got {bb!r}", f"{f}.bbox")
        _, size, boxes, _ = images[a["image_id"]]
        box = (float(bb[0]), float(bb[1]), float(bb[0]) + bb[2], float(bb[1]) + bb[3])
        _check_box(box, size, f"{p} [{f}.bbox]")
        boxes.append((cats[a["category_id"]], box))
    if not images:
        raise InputError("no images in the file", path=p)
    return [RegionLabel(ph, size, tuple(boxes), None, where, tuple(outlines.get(i, ())),
                        tuple(rles.get(i, ())))
            for i, (ph, size, boxes, where) in images.items()]


def read_mask_folder(masks_dir: StrPath, images_dir: StrPath) -> list[RegionLabel]:
    """One label per ``<stem>.png`` in ``masks_dir`` (sorted by name), its photo
    ``images_dir / <stem>.*`` (module docstring)."""
    m, d = Path(masks_dir), Path(images_dir)
    for folder in (m, d):
        if not folder.is_dir():
            raise InputError("not a directory", path=folder)
    masks = sorted(q for q in m.iterdir() if q.is_file() and q.suffix.lower() == ".png")
    if not masks:
        raise InputError("no mask PNGs in the folder", path=m)
    out = []
    for q in masks:
        photo = _find_photo(d, [q.stem + s for s in (*IMAGE_SUFFIXES, ".JPG", ".PNG")],
                            str(q))
        out.append(RegionLabel(photo, None, (), q, str(q)))
    return out


def read_region_labels(boxes: StrPath | None, masks: StrPath | None, images_dir: StrPath
                       ) -> list[RegionLabel]:
    """The labels of a box file (``.json``: COCO, else CSV) or a mask folder."""
    if (boxes is None) == (masks is None):
        raise ValueError("give exactly one of boxes and masks")
    if masks is not None:
        return read_mask_folder(masks, images_dir)
    assert boxes is not None
    if Path(boxes).suffix.lower() == ".json":
        return read_coco_boxes(boxes, images_dir)
    return read_box_csv(boxes, images_dir)
