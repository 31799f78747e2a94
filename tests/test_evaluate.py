"""Detection metrics on labelled photos: InstanceStats on hand-made maps, and
``turbinefit evaluate`` on rendered photos written as COCO keypoints."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from turbinefit.cli import main
from turbinefit.eval.detection import InstanceStats
from turbinefit.heatmaps.targets import render_keypoint_heatmaps
from turbinefit.io.coco import LabelledImage, TurbineKeypoints, write_coco_keypoints
from turbinefit.io.images import write_png
from turbinefit.sim.dataset import DatasetSpec, render_sample

#: Two upright turbines side by side (base, tower top, hub, three tips) [px].
_A = np.array([[20, 55], [20, 20], [23, 20], [23, 8], [14, 25], [31, 25]], float)
_B = _A + np.array([40.0, 0.0])


def _maps(uvs: list[np.ndarray], labs: list[np.ndarray]) -> np.ndarray:
    return render_keypoint_heatmaps(60, 80, uvs, labs, sigma_px=1.5)


def test_instance_stats_match_every_turbine() -> None:
    """Turbine A detected, B not: recall 1/2 per point type, precision 1; a negative
    photo with a hub blob: one false detection; lines judged only where labelled."""
    all6 = np.ones(6, bool)
    target = _maps([_A, _B], [all6, all6])
    pred = _maps([_A], [all6])
    vis = np.full((2, 6), 2, np.int8)
    vis[1, 3] = 1  # B's first tip labelled as occluded
    st = InstanceStats(threshold=0.5)
    st.add(pred, target, np.stack([_A, _B]), vis)
    m = st.summary()
    for name in ("base", "tower_top", "hub"):
        assert m[f"{name}_recall"] == 0.5 and m[f"{name}_precision"] == 1.0
        assert m[f"{name}_median_px"] < 0.2
    assert m["tips_labelled"] == 6 and m["tips_recall"] == 0.5
    assert m["tips_recall_in_sight"] == pytest.approx(3 / 5)
    assert 0.3 < m["iou_tower"] < 0.7  # half the labelled towers found
    assert m["iou_tower_photos"] == 1
    # a negative photo: the hub blob is a false detection; its lines are all judged
    st.add(_maps([_A], [np.array([False, False, True, False, False, False])]),
           np.zeros((7, 60, 80)), np.zeros((0, 6, 2)), np.zeros((0, 6), np.int8))
    m = st.summary()
    assert m["hub_precision"] == 0.5 and m["photos"] == 2 and m["turbines"] == 2
    assert m["iou_tower_photos"] == 2
    # a turbine whose base is not labelled (out of frame): no tower target, not judged
    vis_nobase = np.full((1, 6), 2, np.int8)
    vis_nobase[0, 0] = 0
    st2 = InstanceStats(threshold=0.5)
    st2.add(target, _maps([_A], [vis_nobase[0] > 0]), _A[None], vis_nobase)
    m2 = st2.summary()
    assert np.isnan(m2["iou_tower"]) and m2["iou_tower_photos"] == 0
    assert m2["iou_nacelle"] > 0.3 and np.isnan(m2["base_recall"])


def _photo_px(uv: np.ndarray) -> np.ndarray:
    return (np.asarray(uv, dtype=np.float64) + 0.5) * 2 - 0.5


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
        uv = np.where(vis[:, None] > 0, _photo_px(s.points), 0.0)
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
