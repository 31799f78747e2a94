"""COCO keypoint files (turbinefit.io.coco): round trips, CVAT and Label Studio exports,
and bad input named by file and field."""

from __future__ import annotations

import copy
import json
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from turbinefit.errors import InputError
from turbinefit.io.coco import (
    KEYPOINT_NAMES,
    LabelledImage,
    TurbineKeypoints,
    format_coco_keypoints,
    read_coco_keypoints,
    write_coco_keypoints,
)
from turbinefit.turbine.model import POINT_NAMES


def png(path: Path, w: int = 8, h: int = 6) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.new("RGB", (w, h), (40, 90, 200)).save(path)
    return path


def raises_input_error(path: Path, field: str | None = None, match: str = ""):
    """pytest.raises for an InputError whose message starts by naming ``path`` [and field]."""
    pattern = "^" + re.escape(str(path))
    pattern += re.escape(f" [{field}]") if field is not None else r"(?::\d+)?"
    return pytest.raises(InputError, match=pattern + ": " + match)


def dump(tmp_path: Path, doc: Any, name: str = "labels.json") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(doc) if not isinstance(doc, str) else doc, encoding="utf-8")
    return p


def kp(uv: list[tuple[float, float]], vis: list[int]) -> TurbineKeypoints:
    return TurbineKeypoints(np.array(uv, dtype=float), np.array(vis))


UV = [(3.25, 5.5), (3.0, 1.125), (4.5, 1.0), (4.0, 0.0), (7.75, 2.5), (1.0, 3.0)]


def test_keypoint_names_are_the_model_points() -> None:
    assert KEYPOINT_NAMES == POINT_NAMES == ("base", "tower_top", "hub", "tip_1", "tip_2", "tip_3")


def test_round_trip_exact(tmp_path: Path) -> None:
    imgs = tmp_path / "imgs"
    a, b, c = png(imgs / "a.png"), png(imgs / "sub" / "b.png", 10, 7), png(imgs / "c.png")
    rng = np.random.default_rng(3)
    t1 = TurbineKeypoints(rng.uniform(-1, 6, size=(6, 2)), [2, 2, 1, 2, 0, 2])
    t2 = TurbineKeypoints(rng.uniform(0, 5.5, size=(6, 2)), [0, 1, 2, 2, 2, 1])
    t3 = TurbineKeypoints(np.zeros((6, 2)), [0] * 6)
    labels = [LabelledImage(a, 8, 6, (t1, t2)), LabelledImage(b, 10, 7, (t3,)),
              LabelledImage(c, 8, 6)]
    out = tmp_path / "out" / "labels.json"
    assert write_coco_keypoints(labels, out, imgs) == out
    back = read_coco_keypoints(out, imgs)
    assert back == labels
    assert [x.path for x in back] == [a, b, c]
    np.testing.assert_array_equal(back[0].turbines[0].uv, t1.uv)  # exact, repr precision
    assert back[0].turbines[0].visibility.dtype == np.int8
    assert back[0].turbines[0].uv.dtype == np.float64

    doc = json.loads(out.read_text())
    assert doc["categories"] == [{
        "id": 1, "name": "wind_turbine", "supercategory": "", "keypoints": list(KEYPOINT_NAMES),
        "skeleton": [[1, 2], [2, 3], [3, 4], [3, 5], [3, 6]]}]
    assert [i["file_name"] for i in doc["images"]] == ["a.png", "sub/b.png", "c.png"]
    assert [(i["id"], i["width"], i["height"]) for i in doc["images"]] == [
        (1, 8, 6), (2, 10, 7), (3, 8, 6)]
    anns = doc["annotations"]
    assert [(x["id"], x["image_id"], x["category_id"], x["iscrowd"]) for x in anns] == [
        (1, 1, 1, 0), (2, 1, 1, 0), (3, 2, 1, 0)]
    assert [x["num_keypoints"] for x in anns] == [5, 5, 0]
    lab = t1.uv[t1.labelled]
    x0, y0 = lab.min(axis=0)
    w, h = lab.max(axis=0) - lab.min(axis=0)
    assert anns[0]["bbox"] == pytest.approx([x0, y0, w, h], abs=0)
    assert anns[0]["area"] == pytest.approx(w * h)
    assert anns[2]["bbox"] == [0, 0, 0, 0] and anns[2]["area"] == 0
    assert len(anns[0]["keypoints"]) == 18
    assert anns[0]["keypoints"][14] == 0  # tip_2 of t1 not labelled
    assert anns[0]["keypoints"][12:14] == [0, 0]
    assert format_coco_keypoints(labels, imgs) == out.read_text()


def test_write_leaves_no_temp_file(tmp_path: Path) -> None:
    imgs = tmp_path / "imgs"
    a = png(imgs / "a.png")
    labels = [LabelledImage(a, 8, 6, (kp(UV, [2] * 6),))]
    out = imgs / "labels.json"
    write_coco_keypoints(labels, out, imgs)
    write_coco_keypoints(labels, out, imgs)  # replacing an old output is fine
    assert sorted(os.listdir(imgs)) == ["a.png", "labels.json"]
    assert read_coco_keypoints(out, imgs) == labels

    # a failing write leaves nothing behind and the old file untouched
    before = out.read_text()
    outside = png(tmp_path / "elsewhere" / "x.png")
    bad = [*labels, LabelledImage(outside, 8, 6)]
    with raises_input_error(out, "images[1].path", "image .* is not inside the images directory"):
        write_coco_keypoints(bad, out, imgs)
    assert out.read_text() == before
    new = tmp_path / "new.json"
    with pytest.raises(InputError):
        write_coco_keypoints(bad, new, imgs)
    assert sorted(os.listdir(imgs)) == ["a.png", "labels.json"]
    assert sorted(os.listdir(tmp_path)) == ["elsewhere", "imgs"]


def test_write_never_overwrites_an_image(tmp_path: Path) -> None:
    a = png(tmp_path / "a.png")
    data = a.read_bytes()
    labels = [LabelledImage(a, 8, 6)]
    with raises_input_error(a, None, "refusing to overwrite an input"):
        write_coco_keypoints(labels, a, tmp_path)
    with raises_input_error(tmp_path / "." / "a.png", None, "refusing to overwrite an input"):
        write_coco_keypoints(labels, tmp_path / "." / "a.png", tmp_path)
    assert a.read_bytes() == data
    assert sorted(os.listdir(tmp_path)) == ["a.png"]


def test_write_relative_and_absolute_paths_mixed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                 ) -> None:
    monkeypatch.chdir(tmp_path)
    a = png(tmp_path / "imgs" / "d" / "a.png")
    text = format_coco_keypoints([LabelledImage(a, 8, 6)], "imgs")  # absolute in relative dir
    assert json.loads(text)["images"][0]["file_name"] == "d/a.png"
    text = format_coco_keypoints([LabelledImage(Path("imgs/d/a.png"), 8, 6)], tmp_path / "imgs")
    assert json.loads(text)["images"][0]["file_name"] == "d/a.png"
    with pytest.raises(InputError, match=r"^images\[0\]\.path: .*not inside"):
        format_coco_keypoints([LabelledImage(a, 8, 6)], tmp_path / "other")


def test_turbine_keypoints_checks_and_normalises() -> None:
    t = kp(UV, [2, 0, 1, 2, 0, 2])
    np.testing.assert_array_equal(t.uv[[1, 4]], 0.0)  # unlabelled -> 0
    np.testing.assert_array_equal(t.labelled, [True, False, True, True, False, True])
    assert t == kp([(x, y) if i not in (1, 4) else (9.0, 9.0) for i, (x, y) in enumerate(UV)],
                   [2, 0, 1, 2, 0, 2])
    assert hash(t) == hash(kp(UV, [2, 0, 1, 2, 0, 2]))
    assert t != kp(UV, [2, 0, 2, 2, 0, 2])
    with pytest.raises(ValueError):
        t.uv[0, 0] = 1.0  # read-only
    uv = np.array(UV)
    uv[2, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        TurbineKeypoints(uv, [2] * 6)
    with pytest.raises(ValueError, match="shape"):
        TurbineKeypoints(np.zeros((5, 2)), [2] * 5)
    with pytest.raises(ValueError, match="0, 1 or 2"):
        TurbineKeypoints(np.zeros((6, 2)), [2, 2, 3, 2, 2, 2])
    with pytest.raises(ValueError, match="positive integer"):
        LabelledImage(Path("a.png"), 0, 6)
    with pytest.raises(ValueError, match="positive integer"):
        LabelledImage(Path("a.png"), 8, 6.0)  # type: ignore[arg-type]


def cvat_doc() -> dict[str, Any]:
    """A CVAT-style export: plain file names, keypoints in another order, tower_top missing,
    a bounding-box category too."""
    return {
        "licenses": [{"name": "", "id": 0, "url": ""}],
        "info": {"contributor": "", "date_created": "", "description": ""},
        "categories": [
            {"id": 1, "name": "car", "supercategory": ""},
            {"id": 2, "name": "turbine", "supercategory": "",
             "keypoints": ["hub", "tip_2", "base", "tip_1", "tip_3"], "skeleton": [[1, 3]]},
        ],
        "images": [
            {"id": 7, "width": 8, "height": 6, "file_name": "frame_000.png", "license": 0},
            {"id": 9, "width": 8, "height": 6, "file_name": "frame_001.png", "license": 0},
        ],
        "annotations": [
            {"id": 1, "image_id": 7, "category_id": 2, "segmentation": [], "area": 12.0,
             "bbox": [1, 1, 4, 3], "iscrowd": 0, "num_keypoints": 4,
             "keypoints": [4.5, 1.25, 2, 6.0, 0.5, 1, 3.0, 5.75, 2, 0, 0, 0, 1.5, 2.5, 2]},
            {"id": 2, "image_id": 7, "category_id": 1, "segmentation": [], "area": 4.0,
             "bbox": [0, 0, 2, 2], "iscrowd": 0},
            {"id": 3, "image_id": 7, "category_id": 2, "iscrowd": 0, "num_keypoints": 1,
             "keypoints": [1, 2, 1, 17.5, -3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]},
        ],
    }


def test_cvat_order_and_missing_name(tmp_path: Path) -> None:
    for name in ("frame_000.png", "frame_001.png"):
        png(tmp_path / name)
    labels = read_coco_keypoints(dump(tmp_path, cvat_doc()), tmp_path)
    assert [x.path for x in labels] == [tmp_path / "frame_000.png", tmp_path / "frame_001.png"]
    assert [(x.width, x.height) for x in labels] == [(8, 6), (8, 6)]
    first, second = labels[0].turbines
    # ours: base, tower_top, hub, tip_1, tip_2, tip_3
    np.testing.assert_array_equal(first.visibility, [2, 0, 2, 0, 1, 2])
    np.testing.assert_array_equal(first.uv, [[3.0, 5.75], [0, 0], [4.5, 1.25], [0, 0],
                                             [6.0, 0.5], [1.5, 2.5]])
    np.testing.assert_array_equal(second.visibility, [0, 0, 1, 0, 0, 0])
    np.testing.assert_array_equal(second.uv, [[0, 0], [0, 0], [1, 2], [0, 0], [0, 0], [0, 0]])
    assert labels[1].turbines == ()  # labelled negative, kept


def test_label_studio_paths_resolve_by_basename(tmp_path: Path) -> None:
    imgs = tmp_path / "imgs"
    png(imgs / "abc.png")
    png(imgs / "def.png")
    png(imgs / "images" / "ghi.png")
    png(imgs / "win.png")
    absolute = png(tmp_path / "abs" / "jkl.png")
    names = ["images/abc.png", "/data/upload/1/def.png", "images/ghi.png", r"C:\labels\win.png",
             str(absolute)]
    doc = {
        "images": [{"id": i, "width": 8, "height": 6, "file_name": n} for i, n in enumerate(names)],
        "annotations": [{"id": 0, "image_id": 1, "category_id": 0,
                         "keypoints": [v for x, y in UV for v in (x, y, 2)]}],
        "categories": [{"id": 0, "name": "blade_thing", "keypoints": list(KEYPOINT_NAMES)}],
    }
    labels = read_coco_keypoints(dump(tmp_path, doc), imgs)
    assert [x.path for x in labels] == [imgs / "abc.png", imgs / "def.png",
                                        imgs / "images" / "ghi.png", imgs / "win.png", absolute]
    assert labels[1].turbines == (kp(UV, [2] * 6),)
    assert [len(x.turbines) for x in labels] == [0, 1, 0, 0, 0]


def test_category_rule_prefers_turbine_names(tmp_path: Path) -> None:
    png(tmp_path / "a.png")
    doc = {
        "images": [{"id": 1, "width": 8, "height": 6, "file_name": "a.png"}],
        "annotations": [
            {"image_id": 1, "category_id": 1, "keypoints": [1, 1, 2, 2, 2, 2]},
            {"image_id": 1, "category_id": 2, "keypoints": [4, 5, 2]},
            {"image_id": 1, "category_id": 3, "keypoints": [6, 5.5, 1]},
        ],
        "categories": [
            {"id": 1, "name": "person", "keypoints": ["nose", "left_eye"]},
            {"id": 2, "name": "Wind Turbine", "keypoints": ["hub"]},
            {"id": 3, "name": "turbine_far", "keypoints": ["base"]},
            {"id": 4, "name": "turbine_empty", "keypoints": []},
        ],
    }
    (img,) = read_coco_keypoints(dump(tmp_path, doc), tmp_path)
    assert [t.visibility.tolist() for t in img.turbines] == [[0, 0, 2, 0, 0, 0], [1, 0, 0, 0, 0, 0]]
    # without a "turbine" name, all keypoint categories are used: "nose" is then unknown
    doc["categories"][1]["name"] = "wt"
    doc["categories"][2]["name"] = "wt2"
    doc["categories"][3]["name"] = "wt3"
    p = dump(tmp_path, doc)
    with raises_input_error(p, "categories[0].keypoints[0]", "unknown keypoint name 'nose'"):
        read_coco_keypoints(p, tmp_path)


def test_json_with_bom_and_no_annotations(tmp_path: Path) -> None:
    png(tmp_path / "a.png")
    doc = {"images": [{"id": 1, "width": 8, "height": 6, "file_name": "a.png"}],
           "annotations": [], "categories": [{"id": 1, "name": "x", "keypoints": ["hub"]}]}
    p = tmp_path / "labels.json"
    p.write_bytes(b"\xef\xbb\xbf" + json.dumps(doc).encode())
    assert read_coco_keypoints(p, tmp_path) == [LabelledImage(tmp_path / "a.png", 8, 6)]
    doc["images"] = []
    assert read_coco_keypoints(dump(tmp_path, doc), tmp_path) == []


def good_doc() -> dict[str, Any]:
    return {
        "images": [{"id": 1, "width": 8, "height": 6, "file_name": "a.png"},
                   {"id": 2, "width": 8, "height": 6, "file_name": "b.png"}],
        "annotations": [
            {"id": 1, "image_id": 1, "category_id": 1,
             "keypoints": [v for x, y in UV for v in (x, y, 2)]},
            {"id": 2, "image_id": 2, "category_id": 1,
             "keypoints": [v for x, y in UV for v in (x, y, 1)]},
            {"id": 3, "image_id": 2, "category_id": 1,
             "keypoints": [v for x, y in UV for v in (x, y, 0)]},
            {"id": 4, "image_id": 1, "category_id": 1,
             "keypoints": [v for x, y in UV for v in (x, y, 2)]},
        ],
        "categories": [{"id": 1, "name": "wind_turbine", "keypoints": list(KEYPOINT_NAMES)}],
    }


def setter(*keys: Any, value: Any) -> Callable[[dict[str, Any]], None]:
    def f(doc: dict[str, Any]) -> None:
        d: Any = doc
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value
    return f


def deleter(*keys: Any) -> Callable[[dict[str, Any]], None]:
    def f(doc: dict[str, Any]) -> None:
        d: Any = doc
        for k in keys[:-1]:
            d = d[k]
        del d[keys[-1]]
    return f


def kps_with(index: int, value: Any) -> Callable[[dict[str, Any]], None]:
    """Set element ``index`` of the last annotation's keypoints."""
    def f(doc: dict[str, Any]) -> None:
        doc["annotations"][3]["keypoints"][index] = value
    return f


BAD_CASES: list[tuple[str, Callable[[dict[str, Any]], None], str, str]] = [
    ("missing images", deleter("images"), "images", "missing$"),
    ("missing annotations", deleter("annotations"), "annotations", "missing$"),
    ("missing categories", deleter("categories"), "categories", "missing$"),
    ("images not a list", setter("images", value={}), "images", "expected a list, got an object"),
    ("no keypoint category", deleter("categories", 0, "keypoints"), "categories",
     "no category has a 'keypoints' list"),
    ("empty keypoint list", setter("categories", 0, "keypoints", value=[]), "categories",
     "no category has a 'keypoints' list"),
    ("unknown name", setter("categories", 0, "keypoints", 4, value="x"),
     "categories[0].keypoints[4]",
     re.escape("unknown keypoint name 'x' (expected some of base, tower_top, hub, tip_1, "
               "tip_2, tip_3)") + "$"),
    ("duplicate name", setter("categories", 0, "keypoints", 4, value="hub"),
     "categories[0].keypoints[4]", "duplicate keypoint name 'hub'"),
    ("keypoints length", setter("annotations", 3, "keypoints", value=[1.0] * 15),
     "annotations[3].keypoints", re.escape("expected 18 numbers (6 keypoints x 3), got 15") + "$"),
    ("keypoints not a list", setter("annotations", 3, "keypoints", value="1 2 2"),
     "annotations[3].keypoints", "expected a list"),
    ("keypoints missing", deleter("annotations", 3, "keypoints"), "annotations[3].keypoints",
     "missing$"),
    ("string coordinate", kps_with(6, "4.5"), "annotations[3].keypoints[6]",
     "keypoint 'hub' x: expected a number"),
    ("null coordinate", kps_with(7, None), "annotations[3].keypoints[7]",
     "keypoint 'hub' y: expected a number"),
    ("bool coordinate", kps_with(0, True), "annotations[3].keypoints[0]",
     "keypoint 'base' x: expected a number, got true"),
    ("NaN coordinate", kps_with(3, float("nan")), "annotations[3].keypoints[3]",
     "keypoint 'tower_top' x: must be finite"),
    ("inf coordinate", kps_with(4, float("inf")), "annotations[3].keypoints[4]",
     "keypoint 'tower_top' y: must be finite"),
    ("visibility 3", kps_with(17, 3), "annotations[3].keypoints[17]",
     "keypoint 'tip_3' visibility: expected 0, 1 or 2, got 3"),
    ("visibility -1", kps_with(2, -1), "annotations[3].keypoints[2]", ".*expected 0, 1 or 2, got -1"),
    ("visibility 1.5", kps_with(2, 1.5), "annotations[3].keypoints[2]", ".*got 1.5$"),
    ("visibility string", kps_with(2, "2"), "annotations[3].keypoints[2]", '.*got "2"$'),
    ("visibility bool", kps_with(2, True), "annotations[3].keypoints[2]", ".*got true$"),
    ("unknown image id", setter("annotations", 3, "image_id", value=5),
     "annotations[3].image_id", "image id 5 is not among images"),
    ("image id type mismatch", setter("annotations", 3, "image_id", value="1"),
     "annotations[3].image_id", "image id '1' is not among images"),
    ("missing image_id", deleter("annotations", 3, "image_id"), "annotations[3].image_id",
     "missing$"),
    ("unknown category id", setter("annotations", 3, "category_id", value=8),
     "annotations[3].category_id", "category id 8 is not among categories"),
    ("annotation not an object", setter("annotations", 3, value=[1, 2]), "annotations[3]",
     "expected an object, got a list"),
    ("duplicate image id", setter("images", 1, "id", value=1), "images[1].id",
     r"duplicate image id 1 \(also images\[0\]\)"),
    ("duplicate category id", lambda d: d["categories"].append({"id": 1, "name": "car"}),
     "categories[1].id", "duplicate category id 1"),
    ("missing image file", setter("images", 1, "file_name", value="sub/zzz.png"),
     "images[1].file_name", "image 2: file not found .*sub/zzz.png.*zzz.png"),
    ("empty file name", setter("images", 1, "file_name", value=""), "images[1].file_name",
     "expected a non-empty string"),
    ("missing file name", deleter("images", 1, "file_name"), "images[1].file_name", "missing$"),
    ("width 0", setter("images", 0, "width", value=0), "images[0].width",
     "expected a positive integer, got 0"),
    ("height negative", setter("images", 1, "height", value=-6), "images[1].height",
     "expected a positive integer, got -6"),
    ("width fraction", setter("images", 0, "width", value=8.5), "images[0].width",
     "expected a positive integer, got 8.5"),
    ("width string", setter("images", 0, "width", value="8"), "images[0].width",
     "expected a positive integer"),
    ("missing height", deleter("images", 0, "height"), "images[0].height", "missing$"),
    ("image id bool", setter("images", 0, "id", value=True), "images[0].id",
     "expected an integer or string id"),
]


@pytest.mark.parametrize("mutate, field, match", [c[1:] for c in BAD_CASES],
                         ids=[c[0] for c in BAD_CASES])
def test_bad_input_names_file_and_field(tmp_path: Path, mutate: Callable[[dict[str, Any]], None],
                                        field: str, match: str) -> None:
    png(tmp_path / "a.png")
    png(tmp_path / "b.png")
    doc = good_doc()
    assert len(read_coco_keypoints(dump(tmp_path, doc), tmp_path)) == 2  # the base case is fine
    bad = copy.deepcopy(doc)
    mutate(bad)
    p = dump(tmp_path, bad)
    with raises_input_error(p, field, match) as info:
        read_coco_keypoints(p, tmp_path)
    assert "\n" not in str(info.value)


def test_missing_image_message(tmp_path: Path) -> None:
    png(tmp_path / "a.png")
    doc = good_doc()
    doc["images"][1]["file_name"] = "/data/upload/1/b.png"
    p = dump(tmp_path, doc)
    with pytest.raises(InputError) as info:
        read_coco_keypoints(p, tmp_path)
    assert str(info.value) == (f"{p} [images[1].file_name]: image 2: file not found "
                               f"(tried /data/upload/1/b.png, {tmp_path / 'b.png'})")
    doc["images"][1]["file_name"] = "b.png"
    doc["images"][1]["id"] = "img-b"
    doc["annotations"][1]["image_id"] = doc["annotations"][2]["image_id"] = "img-b"
    p = dump(tmp_path, doc)
    with pytest.raises(InputError) as info:
        read_coco_keypoints(p, tmp_path)
    assert str(info.value) == (f"{p} [images[1].file_name]: image 'img-b': file not found "
                               f"(tried {tmp_path / 'b.png'})")


def test_directory_is_not_an_image(tmp_path: Path) -> None:
    png(tmp_path / "a.png")
    (tmp_path / "b.png").mkdir()
    p = dump(tmp_path, good_doc())
    with raises_input_error(p, "images[1].file_name", "image 2: file not found"):
        read_coco_keypoints(p, tmp_path)


@pytest.mark.parametrize("text, line, match", [
    ('{\n  "images": [\n    {"id": 1,,}\n  ]\n}', 3, r"not valid JSON: .* \(column \d+\)"),
    ("", 1, "not valid JSON"),
    ('{"images": []', 1, "not valid JSON"),
])
def test_not_json(tmp_path: Path, text: str, line: int, match: str) -> None:
    p = dump(tmp_path, text)
    with pytest.raises(InputError, match="^" + re.escape(f"{p}:{line}: ") + match):
        read_coco_keypoints(p, tmp_path)


@pytest.mark.parametrize("top, kind", [("[]", "a list"), ('"x"', "a string"), ("3", "a number"),
                                       ("null", "null")])
def test_top_level_not_an_object(tmp_path: Path, top: str, kind: str) -> None:
    p = dump(tmp_path, top)
    with raises_input_error(p, None, f"expected a JSON object at the top level, got {kind}$"):
        read_coco_keypoints(p, tmp_path)


def test_json_file_missing_unreadable_or_binary(tmp_path: Path) -> None:
    missing = tmp_path / "nope.json"
    with raises_input_error(missing, None, "file not found"):
        read_coco_keypoints(missing, tmp_path)
    with raises_input_error(tmp_path, None, "is a directory"):
        read_coco_keypoints(tmp_path, tmp_path)
    binary = tmp_path / "bin.json"
    binary.write_bytes(b"\xff\xfe\x00{")
    with raises_input_error(binary, None, "not a UTF-8 text file"):
        read_coco_keypoints(binary, tmp_path)
    big = dump(tmp_path, '{"images": [], "annotations": [], "categories": [' * 1 + "[" * 100000)
    with raises_input_error(big, None, "not valid JSON"):
        read_coco_keypoints(big, tmp_path)


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="root can read anything")
def test_json_file_unreadable(tmp_path: Path) -> None:
    p = dump(tmp_path, good_doc())
    p.chmod(0)
    try:
        with raises_input_error(p, None, "cannot read"):
            read_coco_keypoints(p, tmp_path)
    finally:
        p.chmod(0o644)


def test_images_dir_not_a_directory(tmp_path: Path) -> None:
    a = png(tmp_path / "a.png")
    p = dump(tmp_path, good_doc())
    with raises_input_error(a, None, "images directory is not a directory"):
        read_coco_keypoints(p, a)
    with raises_input_error(tmp_path / "none", None, "images directory does not exist"):
        read_coco_keypoints(p, tmp_path / "none")


def test_huge_integer_coordinate(tmp_path: Path) -> None:
    png(tmp_path / "a.png")
    png(tmp_path / "b.png")
    doc = good_doc()
    p = dump(tmp_path, doc)
    text = p.read_text().replace("3.25", "1" + "0" * 400, 1)
    p.write_text(text)
    with raises_input_error(p, "annotations[0].keypoints[0]", "keypoint 'base' x: must be finite"):
        read_coco_keypoints(p, tmp_path)


@pytest.mark.parametrize(("x", "y", "at", "match"), [
    (1e9, 2.0, 0, r"keypoint 'base' x 1000000000.0 px is out of range: it must be between -1 "
     r"and 320 px of the 320x240 image"),
    (5.0, -1.5, 1, r"keypoint 'base' y -1.5 px"),
    (5.0, 240.5, 1, r"keypoint 'base' y 240.5 px"),
])
def test_a_labelled_keypoint_outside_its_image_is_refused(
        tmp_path: Path, x: float, y: float, at: int, match: str) -> None:
    png(tmp_path / "a.png", 320, 240)
    doc = {"images": [{"id": 1, "width": 320, "height": 240, "file_name": "a.png"}],
           "annotations": [{"image_id": 1, "category_id": 1,
                            "keypoints": [x, y, 2] + [0, 0, 0] * 5}],
           "categories": [{"id": 1, "name": "turbine", "keypoints": list(KEYPOINT_NAMES)}]}
    p = dump(tmp_path, doc)
    with raises_input_error(p, f"annotations[0].keypoints[{at}]", match):
        read_coco_keypoints(p, tmp_path)
    # on its edge, or not labelled (visibility 0: the coordinates mean nothing), it is read
    doc["annotations"][0]["keypoints"][:3] = [x, y, 0]
    assert read_coco_keypoints(dump(tmp_path, doc), tmp_path)[0].turbines[0].labelled.sum() == 0
    doc["annotations"][0]["keypoints"][:3] = [-1, 240, 1]
    (img,) = read_coco_keypoints(dump(tmp_path, doc), tmp_path)
    assert img.turbines[0].uv[0].tolist() == [-1.0, 240.0]


def test_a_labelled_keypoint_outside_its_image_is_never_written(tmp_path: Path) -> None:
    t = TurbineKeypoints(np.array([[9.5, 1.0]] + [[0.0, 0.0]] * 5), [2, 0, 0, 0, 0, 0])
    with pytest.raises(ValueError, match=r"x 9.5 px is out of range.*8x6 image"):
        LabelledImage(png(tmp_path / "a.png"), 8, 6, (t,))
