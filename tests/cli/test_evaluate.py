"""``turbinefit evaluate``: the shipped model measured on rendered photos written as COCO
keypoints, and bad input."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from support import assert_one_line_error, assert_valid_png, photo_px, run

from turbinefit.cli import main
from turbinefit.io.coco import LabelledImage, TurbineKeypoints, write_coco_keypoints
from turbinefit.io.images import read_image, write_png
from turbinefit.sim.dataset import DatasetSpec, render_sample


@pytest.fixture(scope="module")
def labelled(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three rendered 320x240 photos whose hub is in view, labelled as COCO keypoints."""
    root = tmp_path_factory.mktemp("labelled")
    spec = DatasetSpec(40, seed=11)
    items = []
    for i in range(40):
        s = render_sample(spec, i)
        if not (s.visible[2] and s.visible[1]):
            continue
        p = root / f"p{i}.png"
        write_png(p, s.image)
        vis = np.where(s.in_sight, 2, np.where(s.visible, 1, 0)).astype(np.int8)
        uv = np.where(vis[:, None] > 0, photo_px(s.points, 2), 0.0)
        items.append(LabelledImage(p, 320, 240, (TurbineKeypoints(uv, vis),)))
        if len(items) == 3:
            break
    assert len(items) == 3
    write_coco_keypoints(items, root / "labels.json", root)
    return root


def test_evaluate_cli_measures_the_shipped_model(labelled: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    report = tmp_path / "report.json"
    args = ["evaluate", "--labels", str(labelled / "labels.json"), "--images-dir",
            str(labelled), "--quiet"]
    assert main([*args, "--out", str(report)]) == 0
    out = capsys.readouterr().out
    assert "3 photo(s), 3 labelled turbine(s)" in out and "hub" in out
    data = json.loads(report.read_text())  # strict JSON: NaN is written as null
    m = data["metrics"]
    assert m["hub_labelled"] == 3 and m["hub_recall"] >= 2 / 3  # found within 5 px
    assert m["hub_median_px"] < 3.0
    assert data["input_width"] == 320 and data["match_px"] == 5.0
    # an existing report is kept unless --overwrite
    before = report.read_text()
    assert main([*args, "--out", str(report), "--match-px", "3"]) == 2
    assert "exists" in capsys.readouterr().err and report.read_text() == before
    assert main([*args, "--out", str(report), "--match-px", "3", "--overwrite"]) == 0
    assert json.loads(report.read_text())["match_px"] == 3.0
    # the tip shift used is reported; --tip-shift 0 turns it off
    from turbinefit.detect import HeatmapDetector

    assert data["tip_shift_px"] == HeatmapDetector(threads=1).info.tip_shift_px > 0
    assert main([*args, "--out", str(report), "--overwrite", "--tip-shift", "0"]) == 0
    assert json.loads(report.read_text())["tip_shift_px"] == 0.0
    assert "tip shift 0 px" in capsys.readouterr().out
    # so are flip averaging and zoom, on for the shipped model; --no-zoom turns zoom off
    assert data["flip"] is True and data["zoom"] is True
    assert main([*args, "--out", str(report), "--overwrite", "--no-zoom"]) == 0
    assert json.loads(report.read_text())["zoom"] is False
    assert "flip averaging on, zoom off" in capsys.readouterr().out


@pytest.mark.parametrize("bad", ["out_is_input", "wrong_size", "unknown_name", "bad_model"])
def test_evaluate_bad_input_is_one_clear_error(labelled: Path, tmp_path: Path, bad: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    labels = labelled / "labels.json"
    report = tmp_path / "report.json"
    extra: list[str] = []
    if bad == "out_is_input":
        report = labels
    elif bad == "wrong_size":
        doc = json.loads(labels.read_text())
        doc["images"][0]["width"] = 640
        labels = tmp_path / "labels.json"
        labels.write_text(json.dumps(doc))
    elif bad == "unknown_name":
        doc = json.loads(labels.read_text())
        doc["categories"][0]["keypoints"][0] = "foot"
        labels = tmp_path / "labels.json"
        labels.write_text(json.dumps(doc))
    else:
        model = tmp_path / "m.onnx"
        model.write_bytes(b"not a model")
        extra = ["--model", str(model)]
    before = labels.read_text()
    code = main(["evaluate", "--labels", str(labels), "--images-dir", str(labelled),
                 "--out", str(report), "--quiet", *extra])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("turbinefit: error:") and len(err.strip().splitlines()) == 1
    assert labels.read_text() == before  # the input is untouched
    if bad != "out_is_input":
        assert not report.exists()


@pytest.fixture(scope="module")
def boxed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two rendered 320x240 photos with a box round each turbine's heat-map targets
    (CSV and COCO), masks of them, and COCO outlines (each visible part's targets'
    convex hull)."""
    from scipy import ndimage
    from scipy.spatial import ConvexHull

    root = tmp_path_factory.mktemp("boxed")
    spec = DatasetSpec(20, seed=12, closeup_fraction=0.0)  # whole turbines
    rows: list[str] = []
    coco_images: list[dict] = []
    coco_anns: list[dict] = []
    outlines: list[dict] = []
    (root / "masks").mkdir()
    for i in range(20):
        s = render_sample(spec, i)
        on = s.target.max(axis=0) > 0.05
        if on.sum() < 200:
            continue
        ii, jj = np.nonzero(on)
        box = (2 * jj.min(), 2 * ii.min(), 2 * jj.max() + 2, 2 * ii.max() + 2)
        name = f"p{i}.png"
        write_png(root / name, s.image)
        big = np.repeat(np.repeat(on, 2, axis=0), 2, axis=1)
        write_png(root / "masks" / name, np.repeat(big[..., None] * 255, 3, axis=2).astype(np.uint8))
        rows.append(f"{name},320,240,turbine,{box[0]},{box[1]},{box[2]},{box[3]}")
        coco_images.append({"id": len(coco_images) + 1, "file_name": name, "width": 320,
                            "height": 240})
        bbox = [int(box[0]), int(box[1]), int(box[2] - box[0]), int(box[3] - box[1])]
        coco_anns.append({"id": len(coco_anns) + 1, "image_id": len(coco_images),
                          "category_id": 1, "bbox": bbox})
        parts, n = ndimage.label(on)
        for k in range(1, n + 1):  # the outline of each separate part, in photo px
            pi, pj = np.nonzero(parts == k)
            corners = np.concatenate([np.stack([2 * pj + a, 2 * pi + b], axis=-1)
                                      for a in (0, 2) for b in (0, 2)])
            hull = corners[ConvexHull(corners).vertices].astype(float)
            outlines.append({"id": len(outlines) + 1, "image_id": len(coco_images),
                             "category_id": 1, "bbox": bbox,
                             "segmentation": [hull.ravel().tolist()]})
        if len(rows) == 2:
            break
    (root / "boxes.csv").write_text("\n".join(rows) + "\n")
    (root / "boxes.json").write_text(json.dumps({
        "images": coco_images, "annotations": coco_anns,
        "categories": [{"id": 1, "name": "turbine"}]}))
    (root / "outlines.json").write_text(json.dumps({
        "images": coco_images, "annotations": outlines,
        "categories": [{"id": 1, "name": "turbine"}]}))
    # the masks as COCO run-length encodings (the coco extra): the first compressed, the
    # second not
    try:
        from pycocotools import mask as coco_mask
    except ImportError:
        return root
    rles = []
    for n, im in enumerate(coco_images):
        m = read_image(root / "masks" / im["file_name"]).max(axis=2) > 0
        if n == 0:
            rle = coco_mask.encode(np.asfortranarray(m.astype(np.uint8)))
            seg = {"size": rle["size"], "counts": rle["counts"].decode("ascii")}
        else:  # runs of 0s and 1s in column-major order, starting with 0s
            flat = m.T.ravel().astype(np.int8)
            edges = np.flatnonzero(np.diff(np.concatenate([[0], flat, [1 - flat[-1]]])))
            seg = {"size": [240, 320], "counts": np.diff(np.concatenate([[0], edges])).tolist()}
        rles.append({"id": n + 1, "image_id": im["id"], "category_id": 1, "iscrowd": 1,
                     "bbox": coco_anns[n]["bbox"], "segmentation": seg})
    (root / "rle.json").write_text(json.dumps({
        "images": coco_images, "annotations": rles,
        "categories": [{"id": 1, "name": "turbine"}]}))
    return root


@pytest.mark.parametrize("labels", ["boxes.csv", "boxes.json", "outlines.json", "rle.json",
                                    "masks"])
def test_evaluate_boxes_and_masks(boxed: Path, labels: str, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    if not (boxed / labels).exists():
        pytest.skip("RLE needs the coco extra (pycocotools)")
    report, sheet = tmp_path / "r.json", tmp_path / "worst.png"
    opt = "--masks" if labels == "masks" else "--boxes"
    assert main(["evaluate", opt, str(boxed / labels), "--images-dir", str(boxed), "--quiet",
                 "--out", str(report), "--sheet", str(sheet), "--worst", "2"]) == 0
    out = capsys.readouterr().out
    assert "2 photo(s)" in out and "turbine" in out
    m = json.loads(report.read_text())["metrics"]
    assert m["overall"]["photos"] == 2 and m["turbine"]["found"] == 1.0
    assert m["turbine"]["line_mass_inside"] > 0.8  # the shipped net on its own renders
    if labels in ("masks", "outlines.json", "rle.json"):
        assert m["turbine"]["skeleton_covered"] > 0.5
    else:
        assert m["turbine"]["skeleton_covered"] is None
    assert assert_valid_png(sheet)[0] == 2 * 320


@pytest.mark.parametrize("case, words", [
    ("header", ["boxes.csv:1", "unknown columns"]),
    ("outside", ["boxes.csv:2", "outside its 320x240 image"]),
    ("missing", ["boxes.csv:2", "photo not found"]),
    ("size", ["boxes.csv:1", "is 320x240 but the label is 640x480"]),
    ("mask", ["masks/p", "the mask is 40x30"]),
])
def test_evaluate_regions_bad_input(boxed: Path, tmp_path: Path, case: str, words: list[str],
                                    capsys: pytest.CaptureFixture[str]) -> None:
    lines = (boxed / "boxes.csv").read_text().splitlines()
    bad = tmp_path / "boxes.csv"
    opt, labels = "--boxes", str(bad)
    if case == "header":
        lines.insert(0, "file,w,h,label,x0,y0,x1,y1")
    elif case == "outside":
        lines[1] = ",".join([*lines[1].split(",")[:6], "321", "200"])
    elif case == "missing":
        lines[1] = "gone.png" + lines[1][lines[1].index(","):]
    elif case == "size":
        lines[0] = lines[0].replace("320,240", "640,480")
    else:
        masks = tmp_path / "masks"
        masks.mkdir()
        for p in (boxed / "masks").iterdir():
            write_png(masks / p.name, np.zeros((30, 40, 3), np.uint8))
        opt, labels = "--masks", str(masks)
    bad.write_text("\n".join(lines) + "\n")
    report = tmp_path / "r.json"
    rc, out, err = run(capsys, "evaluate", opt, labels, "--images-dir", str(boxed), "--quiet",
                       "--out", str(report))
    assert_one_line_error(rc, out, err, *map(re.escape, words))
    assert not report.exists()


@pytest.mark.parametrize("case, words", [
    ("rle size", ["outlines.json", "annotations[0].segmentation",
                  "RLE size [100, 100] is not its image's [height, width] [240, 320]"]),
    ("rle counts", ["outlines.json", "annotations[0].segmentation",
                    "RLE counts add up to 76799, not the image's 76800 pixels"]),
    ("outside", ["outlines.json", "annotations[0].segmentation",
                 "polygon 0 reaches outside its 320x240 image"]),
    ("odd", ["outlines.json", "annotations[0].segmentation", "polygon 0: expected"]),
    ("not a list", ["outlines.json", "annotations[0].segmentation", "a list of polygons"]),
])
def test_evaluate_outlines_bad_input(boxed: Path, tmp_path: Path, case: str, words: list[str],
                                     capsys: pytest.CaptureFixture[str]) -> None:
    coco = json.loads((boxed / "outlines.json").read_text())
    seg = coco["annotations"][0]["segmentation"]
    if case == "rle size":
        coco["annotations"][0]["segmentation"] = {"size": [100, 100], "counts": [10000]}
    elif case == "rle counts":
        coco["annotations"][0]["segmentation"] = {"size": [240, 320], "counts": [76000, 799]}
    elif case == "outside":
        seg[0][0] = 400.0
    elif case == "odd":
        seg[0] = seg[0][:5]
    else:
        coco["annotations"][0]["segmentation"] = "p0"
    bad = tmp_path / "outlines.json"
    bad.write_text(json.dumps(coco))
    before = bad.read_text()
    report = tmp_path / "r.json"
    rc, out, err = run(capsys, "evaluate", "--boxes", str(bad), "--images-dir", str(boxed),
                       "--quiet", "--out", str(report))
    assert_one_line_error(rc, out, err, *map(re.escape, words))
    assert not report.exists() and bad.read_text() == before
