"""``turbinefit train``: a smoke run, resume and fine-tuning, lifting, widening and adding a
fine branch to ``--init`` weights, extra datasets, and bad input.

Needs the optional extra ``turbinefit[train]``; skipped without PyTorch."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from support import photo_px

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")

from turbinefit.cli import main  # noqa: E402
from turbinefit.detect import HeatmapDetector  # noqa: E402
from turbinefit.errors import InputError  # noqa: E402
from turbinefit.io.coco import LabelledImage, TurbineKeypoints, write_coco_keypoints  # noqa: E402
from turbinefit.io.images import read_image, write_png  # noqa: E402
from turbinefit.sim.dataset import DatasetSpec, build_dataset, render_sample  # noqa: E402
from turbinefit.train.net import HeatmapNet, architecture, fine_width  # noqa: E402
from turbinefit.train.trainer import TrainConfig  # noqa: E402

torch.set_num_threads(1)


def test_bad_channel_weights_are_one_clear_error(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    for bad in ("1,1,1", "1,1,1,3,1,2,x", "1,1,1,-3,1,2,1"):
        with pytest.raises(SystemExit) as e:
            main(["train", "--out", str(tmp_path / "m"), "--channel-weights", bad])
        assert e.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert "--channel-weights" in err[-1] and "Traceback" not in "\n".join(err)
    with pytest.raises(InputError, match="channel_weights"):
        TrainConfig(out_dir=tmp_path, channel_weights=(0.0,) * 7)
    for bad in ("1.5", "-0.1", "x", "nan"):
        with pytest.raises(SystemExit) as e:
            main(["train", "--out", str(tmp_path / "m"), "--closeups", bad])
        assert e.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert "--closeups" in err[-1] and "Traceback" not in "\n".join(err)
    assert not (tmp_path / "m").exists()


def test_train_cli_smoke_resume_and_fine_tune(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "model"
    args = ["train", "--out", str(out), "--images", "16", "--val-images", "8", "--epochs", "2",
            "--batch", "8", "--workers", "1", "--quiet", "--data", str(tmp_path / "data")]
    assert main([*args, "--max-steps", "2"]) == 0
    first = (out / "history.csv").read_text().splitlines()
    assert len(first) == 2  # header + epoch 1 (max-steps stopped it)
    assert (out / "model.onnx").is_file() and (out / "weights.npz").is_file()
    # the same command resumes after the checkpointed epoch and finishes the run
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "resuming" in text
    assert len((out / "history.csv").read_text().splitlines()) == 3
    det = HeatmapDetector(out / "model.onnx", threads=1)
    assert det.detect(np.zeros((60, 80, 3), np.uint8)).shape == (7, 60, 80)
    meta = dict(det.session.get_modelmeta().custom_metadata_map)
    assert abs(float(meta["turbinefit.tip_shift_px"])) < 20  # calibrated at export
    # a resumed run with other settings is refused
    assert main([*args[:-2], "--data", str(tmp_path / "data"), "--lr", "0.01"]) == 2
    # fine-tuning on COCO-labelled photos from these weights
    s = render_sample(DatasetSpec(1, seed=0), 0)
    write_png(tmp_path / "p.png", s.image)
    write_coco_keypoints([LabelledImage(tmp_path / "p.png", 320, 240, (
        TurbineKeypoints(photo_px(s.points, 2), np.where(s.visible, 2, 0).astype(np.int8)),))],
        tmp_path / "l.json", tmp_path)
    ft = tmp_path / "ft"
    assert main(["train", "--out", str(ft), "--images", "16", "--val-images", "0", "--epochs",
                 "1", "--batch", "8", "--workers", "1", "--quiet", "--data", str(tmp_path / "data"),
                 "--labels", str(tmp_path / "l.json"), "--images-dir", str(tmp_path),
                 "--init", str(out / "weights.npz")]) == 0
    assert (ft / "model.onnx").is_file()


def test_train_lifts_160_px_weights_to_320_px(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """--init weights of a 160-px net with --input-scale 2 start a 320-px net; weights of
    a 320-px net cannot start a 160-px one (one line, exit 2, nothing written)."""
    from turbinefit.train.export import save_npz

    save_npz(HeatmapNet(input_scale=1), tmp_path / "old.npz")
    out = tmp_path / "lifted"
    common = _one_step_args(tmp_path)
    assert main(["train", "--out", str(out), "--init", str(tmp_path / "old.npz"),
                 "--input-scale", "2", *common]) == 0
    det = HeatmapDetector(out / "model.onnx", threads=1)
    assert (det.info.input_width, det.info.output_scale) == (320, 2)
    with np.load(out / "weights.npz") as z:
        assert "pre.0.weight" in z.files
    capsys.readouterr()
    back = tmp_path / "back"
    assert main(["train", "--out", str(back), "--init", str(out / "weights.npz"),
                 "--input-scale", "1", *common]) == 2
    err = capsys.readouterr().err
    assert "input scale 2" in err and len(err.strip().splitlines()) == 1
    assert not back.exists()


def _one_step_args(tmp_path: Path) -> list[str]:
    """`train` options of a one-step run on 16 renders in ``tmp_path/data``."""
    return ["--images", "16", "--val-images", "0", "--epochs", "1", "--batch", "8",
            "--workers", "1", "--quiet", "--data", str(tmp_path / "data"), "--max-steps", "1"]


def test_train_widens_init_weights(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--widths wider than the --init weights' starts a wider net from them; narrower ones
    and malformed widths are one clear error each (exit 2, nothing written)."""
    from turbinefit.train.export import load_npz, save_npz

    save_npz(HeatmapNet(input_scale=2), tmp_path / "narrow.npz")
    common = _one_step_args(tmp_path)
    out = tmp_path / "wide"
    assert main(["train", "--out", str(out), "--init", str(tmp_path / "narrow.npz"),
                 "--widths", "32,48,96,160", *common]) == 0
    assert load_npz(out / "weights.npz").enc4[0][0].out_channels == 160
    with np.load(out / "weights.npz") as z:
        assert architecture({k: torch.from_numpy(z[k]) for k in z.files})[0] == (32, 48, 96, 160)
    det = HeatmapDetector(out / "model.onnx", threads=1)
    assert det.detect(np.zeros((60, 80, 3), np.uint8)).shape == (7, 60, 80)
    assert "(32, 48, 96, 160)" in det.info.description
    capsys.readouterr()
    narrower = tmp_path / "narrower"
    assert main(["train", "--out", str(narrower), "--init", str(out / "weights.npz"),
                 "--widths", "32,48,64,100", *common]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "narrower" in err[0]
    assert not narrower.exists()
    for bad in ("32,48,x,112", "32,48,64", "32,0,64,112"):
        with pytest.raises(SystemExit) as e:
            main(["train", "--out", str(narrower), "--widths", bad, *common])
        assert e.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert "--widths" in err[-1] and "Traceback" not in "\n".join(err)
    assert not narrower.exists()


def test_train_adds_a_fine_branch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--fine on --init weights without a branch adds one (the exported model runs and
    says so); asking those weights for another branch width, or for none, is one clear
    error (exit 2, nothing written)."""
    from turbinefit.train.export import load_npz, save_npz

    save_npz(HeatmapNet(input_scale=2), tmp_path / "plain.npz")
    common = _one_step_args(tmp_path)
    out = tmp_path / "fine"
    assert main(["train", "--out", str(out), "--init", str(tmp_path / "plain.npz"),
                 "--fine", "8", *common]) == 0
    assert fine_width(load_npz(out / "weights.npz").state_dict()) == 8
    det = HeatmapDetector(out / "model.onnx", threads=1)
    assert det.detect(np.zeros((60, 80, 3), np.uint8)).shape == (7, 60, 80)
    assert "fine 8" in det.info.description
    capsys.readouterr()
    for fine in ("4", "0"):
        bad = tmp_path / f"bad{fine}"
        assert main(["train", "--out", str(bad), "--init", str(out / "weights.npz"),
                     "--fine", fine, *common]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "fine branch of 8 channels" in err[0]
        assert not bad.exists()


@pytest.mark.parametrize("bad", ["missing", "unknown_name", "weights"])
def test_train_bad_labels(tmp_path: Path, bad: str, capsys: pytest.CaptureFixture[str]) -> None:
    write_png(tmp_path / "a.png", np.zeros((120, 160, 3), np.uint8))
    doc = {"images": [{"id": 1, "file_name": "a.png" if bad != "missing" else "b.png",
                       "width": 160, "height": 120}],
           "annotations": [],
           "categories": [{"id": 1, "name": "turbine",
                           "keypoints": ["base", "hub", "blade_tip" if bad == "unknown_name"
                                         else "tower_top"]}]}
    (tmp_path / "l.json").write_text(json.dumps(doc))
    if bad == "weights":
        (tmp_path / "w.npz").write_bytes(b"not an npz")
    args = ["train", "--out", str(tmp_path / "o"), "--images", "8", "--val-images", "0",
            "--epochs", "1", "--workers", "1", "--quiet", "--data", str(tmp_path / "data"),
            "--labels", str(tmp_path / "l.json"), "--images-dir", str(tmp_path)]
    if bad == "weights":
        args += ["--init", str(tmp_path / "w.npz")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("turbinefit: error: ") and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o" / "model.onnx").exists()
    assert read_image(tmp_path / "a.png").shape == (120, 160, 3)


def test_train_adds_renders_of_earlier_runs(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """--add-data trains on a finished training set of another run as well; a folder that
    is no dataset, is unfinished, is of another input scale or is the run's own set is one
    clear error (exit 2) before anything is written."""
    earlier = tmp_path / "earlier" / "train-n8-s5-x2"
    build_dataset(earlier, DatasetSpec(8, 5, image_scale=2), workers=1, progress=False)
    args = ["train", "--images", "4", "--val-images", "0", "--epochs", "1", "--batch", "4",
            "--workers", "1", "--quiet", "--max-steps", "1", "--data", str(tmp_path / "data")]
    assert main([*args, "--out", str(tmp_path / "m"), "--add-data", str(earlier)]) == 0
    assert "12 training images" in capsys.readouterr().out
    assert (tmp_path / "m" / "model.onnx").is_file()

    small = tmp_path / "small" / "train-n2-s0-x1"
    build_dataset(small, DatasetSpec(2, 0, image_scale=1), workers=1, progress=False)
    unfinished = tmp_path / "unfinished"
    build_dataset(unfinished, DatasetSpec(2, 1, image_scale=2), workers=1, progress=False)
    done = np.load(unfinished / "done.npy", mmap_mode="r+")
    done[1] = False
    done.flush()
    del done
    (tmp_path / "empty").mkdir()
    for folder, why in ((tmp_path / "empty", "not a dataset folder"),
                        (small, "another kind"), (unfinished, "unfinished"),
                        (tmp_path / "data" / "train-n4-s0-x2", "own training set")):
        out = tmp_path / f"bad-{folder.name}"
        assert main([*args, "--out", str(out), "--add-data", str(folder)]) == 2
        err = capsys.readouterr().err
        assert why in err and str(folder) in err and len(err.strip().splitlines()) == 1
        assert not out.exists()
