"""``turbinefit evaluate``: the shipped model measured on rendered photos written as COCO
keypoints, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from support import photo_px

from turbinefit.cli import main
from turbinefit.io.coco import LabelledImage, TurbineKeypoints, write_coco_keypoints
from turbinefit.io.images import write_png
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
