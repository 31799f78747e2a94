"""COCO outlines of turbine photos: polygons and run-length encodings read back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from turbinefit.errors import InputError
from turbinefit.io.images import write_png
from turbinefit.io.regions import decode_rle, read_box_csv, read_coco_boxes


def _mask() -> np.ndarray:
    m = np.zeros((24, 32), dtype=bool)
    m[3:20, 5:9] = True   # a tower
    m[4, 9:30] = True     # a blade one pixel thin
    return m


def _uncompressed(m: np.ndarray) -> list[int]:
    """COCO's uncompressed RLE: run lengths in column-major order, 0s first."""
    flat = m.T.ravel().astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flat, [1 - flat[-1]]])))
    return np.diff(np.concatenate([[0], edges])).tolist()


def test_decode_rle_of_both_encodings_gives_the_mask_back() -> None:
    coco_mask = pytest.importorskip("pycocotools.mask")
    m = _mask()
    compressed = coco_mask.encode(np.asfortranarray(m.astype(np.uint8)))["counts"].decode()
    assert np.array_equal(decode_rle({"size": [24, 32], "counts": compressed}), m)
    assert np.array_equal(decode_rle({"size": [24, 32], "counts": _uncompressed(m)}), m)
    assert sum(_uncompressed(m)) == m.size


def test_read_coco_boxes_keeps_boxes_polygons_and_rles_apart(tmp_path: Path) -> None:
    pytest.importorskip("pycocotools")  # RLEs are decoded when read, to check them
    write_png(tmp_path / "a.png", np.zeros((24, 32, 3), np.uint8))
    tri = [1.0, 1.0, 20.0, 1.0, 1.0, 20.0]
    anns = [
        {"id": 1, "image_id": 7, "category_id": 1, "bbox": [2, 3, 10, 12]},
        {"id": 2, "image_id": 7, "category_id": 2, "bbox": [0, 0, 1, 1],
         "segmentation": [tri]},
        {"id": 3, "image_id": 7, "category_id": 2, "iscrowd": 1, "bbox": [0, 0, 1, 1],
         "segmentation": {"size": [24, 32], "counts": _uncompressed(_mask())}},
    ]
    path = tmp_path / "labels.json"
    path.write_text(json.dumps({
        "images": [{"id": 7, "file_name": "a.png", "width": 32, "height": 24}],
        "annotations": anns,
        "categories": [{"id": 1, "name": "turbine"}, {"id": 2, "name": "blade"}]}))
    (lab,) = read_coco_boxes(path, tmp_path)
    assert lab.boxes == (("turbine", (2.0, 3.0, 12.0, 15.0)),)
    assert lab.polygons == (("blade", tuple(tri)),)
    assert [c for c, _ in lab.rles] == ["blade"] and lab.classes == ("turbine", "blade")
    assert not lab.outlined  # a box among them: its skeleton is not the turbine's


def _box_csv(tmp_path: Path, text: str) -> Path:
    (tmp_path / "a.png").write_bytes(b"")
    (tmp_path / "b.csv").write_text(text)
    return tmp_path / "b.csv"


def test_box_csv_with_and_without_the_defect_column(tmp_path: Path) -> None:
    plain = _box_csv(tmp_path, "a.png,64,48,crack,1,2,3,4\n")
    (lab,) = read_box_csv(plain, tmp_path)
    assert lab.boxes == (("crack", (1.0, 2.0, 3.0, 4.0)),) and lab.defects == ()
    named = _box_csv(tmp_path, "filename,width,height,class,xmin,ymin,xmax,ymax,defect\n"
                     "a.png,64,48,crack,1,2,3,4,D7\na.png,64,48,burn,5,6,7,8,\n")
    (lab,) = read_box_csv(named, tmp_path)
    assert lab.defects == ("D7", "") and len(lab.boxes) == 2
    headerless = _box_csv(tmp_path, "a.png,64,48,crack,1,2,3,4,D7\n")
    assert read_box_csv(headerless, tmp_path)[0].defects == ("D7",)


@pytest.mark.parametrize(("text", "line", "words"), [
    ("a.png,64,48,crack,1,2,3,4,D7\na.png,64,48,crack,1,2,3,4\n", 2, "8 columns, expected 9"),
    ("filename,width,height,class,xmin,ymin,xmax,ymax\na.png,64,48,c,1,2,3,4,D\n", 2,
     "9 columns, expected 8"),
    ("filename,width,height,class,xmin,ymin,xmax,ymax,name\n", 1, "unknown columns"),
    ("a.png,64,48,crack,1,2,3,4,D7,x\n", 1, "10 columns"),
])
def test_box_csv_defect_column_errors(tmp_path: Path, text: str, line: int, words: str) -> None:
    p = _box_csv(tmp_path, text)
    with pytest.raises(InputError, match=rf"b\.csv:{line}: .*{words}"):
        read_box_csv(p, tmp_path)
