"""Training the heat-map CNN (PyTorch): the net, its loss, ONNX export, checkpoints, labels.

Needs the optional extra ``turbinefit[train]`` (``make test`` installs it); the whole
module is skipped without PyTorch.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")

from turbinefit.cli import main  # noqa: E402
from turbinefit.detect import HeatmapDetector  # noqa: E402
from turbinefit.errors import InputError  # noqa: E402
from turbinefit.heatmaps.model_info import ModelInfo  # noqa: E402
from turbinefit.io.coco import LabelledImage, TurbineKeypoints, write_coco_keypoints  # noqa: E402
from turbinefit.io.images import read_image, resize_image, write_png  # noqa: E402
from turbinefit.sim.dataset import DatasetSpec, build_dataset, render_sample  # noqa: E402
from turbinefit.train.export import export_onnx  # noqa: E402
from turbinefit.train.labels import labelled_sample  # noqa: E402
from turbinefit.train.net import (  # noqa: E402
    HeatmapNet,
    add_fine,
    architecture,
    fine_width,
    lift_to_input_scale_2,
    num_parameters,
    widen,
)
from turbinefit.train.trainer import (  # noqa: E402
    TrainConfig,
    _jitter,
    evaluate,
    forward,
    heatmap_loss,
)

torch.set_num_threads(1)


def _photo_px(uv: np.ndarray, scale: int) -> np.ndarray:
    """Heat-map pixel coordinates -> photo pixel coordinates (pixel centres aligned)."""
    return (np.asarray(uv, dtype=np.float64) + 0.5) * scale - 0.5


@pytest.mark.parametrize("scale", [1, 2])
def test_net_shape_and_size(scale: int) -> None:
    net = HeatmapNet(input_scale=scale)
    assert 4e5 < num_parameters(net) < 8e5
    # 120 s is padded to a multiple of 16 s and the output cropped back to 120 x 160
    out = forward(net, torch.rand(2, 3, 120 * scale, 160 * scale))
    assert out.shape == (2, 7, 120, 160)
    assert torch.isfinite(out).all()


def test_net_refuses_other_scales() -> None:
    with pytest.raises(ValueError, match="input_scale"):
        HeatmapNet(input_scale=3)


def test_lifted_net_sees_320_px_photos_as_the_old_one_saw_160_px() -> None:
    """A 160-px net lifted to 320-px input gives nearly its old heat-maps on the same
    photo: the old net on the photo resized to 160 px, the lifted one on the photo."""
    torch.manual_seed(3)
    photos = np.stack([render_sample(DatasetSpec(1, seed=2), i).image for i in range(3)])
    old = HeatmapNet(input_scale=1)
    small = np.stack([resize_image(p, 160, 120) for p in photos])
    x1 = torch.from_numpy(small.transpose(0, 3, 1, 2).copy()).float() / 255
    x2 = torch.from_numpy(photos.transpose(0, 3, 1, 2).copy()).float() / 255
    old.train()
    for _ in range(3):  # batch-norm statistics of real photos
        old(torch.nn.functional.pad(x1, (0, 0, 0, 8), mode="replicate"))
    old.eval()
    new = HeatmapNet(input_scale=2)
    new.load_state_dict(lift_to_input_scale_2(old.state_dict()))
    new.eval()
    with torch.no_grad():
        a, b = forward(old, x1), forward(new, x2)
    assert a.shape == b.shape == (3, 7, 120, 160)

    def rel(p: torch.Tensor, q: torch.Tensor) -> float:  # error relative to p's spread
        return float((p - q).std() / p.std())

    assert rel(a, b) < 0.05  # measured 0.013
    # and a net that was not lifted (fresh full-resolution layers) does not
    fresh = HeatmapNet(input_scale=2)
    state = fresh.state_dict()
    state.update({k: v for k, v in old.state_dict().items() if k != "stem.0.weight"})
    fresh.load_state_dict(state)
    fresh.eval()
    with torch.no_grad():
        c = forward(fresh, x2)
    assert rel(a, c) > 0.15  # measured 0.28


def test_widened_net_computes_the_same_heatmaps_and_can_learn() -> None:
    """widen(): a wider net (every block, the stem and the U-Net concatenations) gives the
    old net's heat-maps exactly, and the zero weights from its new channels get gradients."""
    torch.manual_seed(5)
    old = HeatmapNet(input_scale=2)
    x = torch.rand(2, 3, 240, 320)
    old.train()
    with torch.no_grad():
        for _ in range(3):  # batch-norm statistics that are not the initial ones
            old(x)
        for p in old.parameters():  # and weights that are not a fresh net's
            p.add_(0.05 * torch.randn_like(p))
    old.eval()
    widths = (40, 64, 96, 160)
    state = widen(old.state_dict(), widths, stem=32)
    assert architecture(state) == (widths, 32, 2)
    new = HeatmapNet(widths, 32, input_scale=2)
    new.load_state_dict(state)
    new.eval()
    with torch.no_grad():
        a, b = forward(old, x), forward(new, x)
    assert float((a - b).abs().max()) < 1e-4 * float(a.abs().max())
    # a fresh net of the new widths does not (the test can fail)
    fresh = HeatmapNet(widths, 32, input_scale=2).eval()
    with torch.no_grad():
        assert float((a - forward(fresh, x)).abs().max()) > 0.1
    new.train()
    heatmap_loss(forward(new, x), torch.rand(2, 7, 120, 160), 2.0).backward()
    g = new.dec2[0][0].weight.grad  # old outputs reading the new 1/8-resolution channels
    assert g is not None and float(g[:48, 64:96].abs().max()) > 0
    with pytest.raises(ValueError, match="narrow"):
        widen(state, (32, 48, 64, 112))


def test_fine_branch_starts_adding_nothing_and_can_learn() -> None:
    """add_fine(): the net with a fine branch gives the old heat-maps exactly, its branch
    learns (gradients reach its zeroed output layer), widening keeps it, and it needs input
    scale 2."""
    torch.manual_seed(6)
    old = HeatmapNet(input_scale=2)
    x = torch.rand(2, 3, 240, 320)
    with torch.no_grad():
        for p in old.parameters():
            p.add_(0.05 * torch.randn_like(p))
    old.eval()
    state = add_fine(old.state_dict(), 12)
    assert fine_width(state) == 12 and fine_width(old.state_dict()) == 0
    new = HeatmapNet(input_scale=2, fine=12)
    new.load_state_dict(state)
    new.eval()
    assert new.fine is not None
    last = new.fine[-1]
    assert isinstance(last, torch.nn.Conv2d)
    with torch.no_grad():
        a, b = forward(old, x), forward(new, x)
        assert torch.equal(a, b)
        # a branch whose output layer is not zero changes the maps (the test can fail)
        last.weight.add_(0.1)
        assert float((forward(new, x) - a).abs().max()) > 0.01
        last.weight.zero_()
    new.train()
    heatmap_loss(forward(new, x), torch.rand(2, 7, 120, 160), 2.0).backward()
    g = last.weight.grad
    assert g is not None and float(g.abs().max()) > 0
    wide = widen(state, (40, 64, 96, 160))
    assert fine_width(wide) == 12
    assert torch.equal(wide["fine.0.0.weight"], state["fine.0.0.weight"])
    with pytest.raises(ValueError, match="already"):
        add_fine(state, 8)
    with pytest.raises(ValueError, match="input_scale 2"):
        HeatmapNet(input_scale=1, fine=8)


def test_shipped_resize_graph_is_the_exported_one(tmp_path: Path) -> None:
    """The package's resize graph is what export_resize_onnx writes (regenerate it with
    that function if this fails)."""
    from turbinefit.detect import RESIZE_MODEL, default_model_path
    from turbinefit.train.export import export_resize_onnx

    fresh = export_resize_onnx(tmp_path / RESIZE_MODEL)
    shipped = default_model_path().with_name(RESIZE_MODEL)
    assert fresh.read_bytes() == shipped.read_bytes()


def test_loss_optimum_is_the_target() -> None:
    target = torch.tensor([0.0, 0.2, 0.7, 1.0])
    logits = torch.logit(target.clamp(1e-4, 1 - 1e-4)).requires_grad_(True)
    loss = heatmap_loss(logits.view(1, 1, 1, 4), target.view(1, 1, 1, 4), pos_weight=10.0)
    (g,) = torch.autograd.grad(loss, logits)
    assert float(g.abs().max()) < 1e-3


def test_channel_weights_scale_each_channel_and_keep_its_optimum() -> None:
    target = torch.rand(1, 7, 3, 4)
    logits = torch.randn(1, 7, 3, 4)
    w = (1.0, 0.0, 1.0, 3.0, 1.0, 2.0, 1.0)
    per_channel = [float(heatmap_loss(logits[:, c:c + 1], target[:, c:c + 1], 2.0)) for c in range(7)]
    want = sum(wc * lc for wc, lc in zip(w, per_channel, strict=True)) / 7
    assert float(heatmap_loss(logits, target, 2.0, w)) == pytest.approx(want, rel=1e-5)
    at_target = torch.logit(target.clamp(1e-4, 1 - 1e-4)).requires_grad_(True)
    (g,) = torch.autograd.grad(heatmap_loss(at_target, target, 2.0, w), at_target)
    assert float(g.abs().max()) < 1e-3


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
    assert not (tmp_path / "m").exists()


def test_a_few_steps_reduce_the_loss(tmp_path: Path) -> None:
    data = build_dataset(tmp_path / "d", DatasetSpec(8, seed=5), workers=1, progress=False)
    x = torch.from_numpy(np.array(data.images).transpose(0, 3, 1, 2).copy()).float() / 255
    y = torch.from_numpy(np.array(data.targets)).float() / 255
    assert x.shape[-2:] == (240, 320) and y.shape[-2:] == (120, 160)
    torch.manual_seed(0)
    net = HeatmapNet(input_scale=data.spec.image_scale)
    opt = torch.optim.AdamW(net.parameters(), lr=2e-3)
    losses = []
    for _ in range(25):
        loss = heatmap_loss(forward(net, x), y, 10.0)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < 0.5 * losses[0]


@pytest.mark.parametrize(("scale", "flip"), [(1, False), (2, False), (2, True)])
def test_onnx_output_equals_pytorch(tmp_path: Path, scale: int, flip: bool) -> None:
    torch.manual_seed(1)
    net = HeatmapNet(input_scale=scale)
    net.train()
    for _ in range(3):  # non-trivial batch-norm statistics
        net(torch.rand(4, 3, 128 * scale, 160 * scale))
    net.eval()
    info = ModelInfo(threshold=0.42, input_width=160 * scale, input_height=120 * scale,
                     stride=16 * scale, output_scale=scale, flip=flip)
    path = export_onnx(net, tmp_path / "m.onnx", info)
    det = HeatmapDetector(path, threads=1)
    assert det.info == info
    rng = np.random.default_rng(0)
    for h, w in ((120, 160), (96, 160), (160, 160)):  # height follows the photo's aspect
        img = rng.integers(0, 256, size=(h * scale, w * scale, 3), dtype=np.uint8)
        got = det.detect_small(img)
        x = torch.from_numpy(img.transpose(2, 0, 1).copy()).float()[None] / 255
        with torch.no_grad():
            ref = torch.sigmoid(forward(net, x))[0].numpy()
            mirrored = torch.sigmoid(forward(net, x.flip(-1))).flip(-1)[0].numpy()
        if flip:  # the mean with the mirror image's maps mirrored back
            assert np.abs(mirrored - ref).max() > 1e-3  # the net itself is not symmetric
            ref = 0.5 * (ref + mirrored)
        assert got.shape == ref.shape == (7, h, w)
        np.testing.assert_allclose(got, ref, atol=2e-5)
        # at the photo's own size: the maps resized back
        assert det.detect(img).shape == (7, h * scale, w * scale)


def test_evaluate_calibrates_the_tip_shift_in_input_pixels() -> None:
    """A stand-in net of input scale 2 whose tip blobs sit 3 heat-map px inboard: the
    calibrated shift is +6 px of its input (what ModelInfo.tip_shift_px holds), though the
    other distances stay in heat-map pixels."""
    from turbinefit.heatmaps.targets import render_keypoint_heatmaps

    uv = np.array([[80, 100], [80, 40], [84, 40], [84, 26], [72, 47], [96, 47]], float)
    moved = uv.copy()
    for i in (3, 4, 5):
        d = uv[2] - uv[i]
        moved[i] += 3.0 * d / np.hypot(*d)
    vis = np.ones(6, bool)
    target = render_keypoint_heatmaps(120, 160, [uv], [vis], sigma_px=1.5)
    pred = render_keypoint_heatmaps(120, 160, [moved], [vis], sigma_px=1.5)
    logit = torch.logit(torch.from_numpy(pred).float().clamp(1e-4, 1 - 1e-4))

    class StandIn(torch.nn.Module):
        input_scale = 2

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            out = torch.full((len(x), 7, x.shape[-2] // 2, x.shape[-1] // 2), -9.0)
            out[:, :, :120, :160] = logit
            return out

    n = 8
    _, summaries = evaluate(StandIn(), np.zeros((n, 240, 320, 3), np.uint8),  # type: ignore[arg-type]
                            np.repeat((target * 255).astype(np.uint8)[None], n, axis=0),
                            np.repeat(uv[None], n, axis=0), np.repeat(vis[None], n, axis=0),
                            2.0, (0.5,), flip=False)
    m = summaries[0.5]
    assert m["tip_shift_px"] == pytest.approx(6.0, abs=0.2)
    assert m["tip_bias_px"] == pytest.approx(-3.0, abs=0.1)  # heat-map px


def test_jitter_keeps_range() -> None:
    x = torch.rand(4, 3, 8, 8)
    y = _jitter(x)
    assert y.shape == x.shape and float(y.min()) >= 0 and float(y.max()) <= 1


def test_coco_labels_give_the_rendered_targets(tmp_path: Path) -> None:
    """A rendered sample exported as a COCO file and imported again gives its own targets."""
    spec = DatasetSpec(1, seed=0)
    s_ = spec.image_scale
    images = []
    for i in range(12):
        s = render_sample(spec, i)
        if s.visible.sum() >= 5:
            images.append((i, s))
        if len(images) == 2:
            break
    assert images, "no view with the turbine in view"
    labelled = []
    for i, s in images:
        write_png(tmp_path / f"{i}.png", s.image)
        labelled.append(LabelledImage(tmp_path / f"{i}.png", spec.width * s_, spec.height * s_, (
            TurbineKeypoints(_photo_px(s.points, s_), np.where(s.visible, 2, 0).astype(np.int8)),)))
    write_coco_keypoints(labelled, tmp_path / "labels.json", tmp_path)
    from turbinefit.io.coco import read_coco_keypoints

    back = read_coco_keypoints(tmp_path / "labels.json", tmp_path)
    for (_, s), item in zip(images, back, strict=True):
        img, tgt = labelled_sample(item, spec.width, spec.height, spec.sigma_px, s_)
        np.testing.assert_array_equal(img, s.image)
        vis = s.visible
        # points: identical blobs for the labelled (visible) points
        for c in (0, 1, 2):
            if vis[c]:
                np.testing.assert_allclose(tgt[c] / 255.0, s.target[c], atol=0.01)
        # lines between two visible points: the same ridge
        for a, b, c in ((0, 1, 4), (1, 2, 5)):
            if vis[a] and vis[b]:
                np.testing.assert_allclose(tgt[c] / 255.0, s.target[c], atol=0.02)


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
        TurbineKeypoints(_photo_px(s.points, 2), np.where(s.visible, 2, 0).astype(np.int8)),))],
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


def test_train_refuses_an_old_dataset_before_writing(tmp_path: Path) -> None:
    """A --data folder rendered by an older data version: one clear error, no --out."""
    from dataclasses import asdict, replace

    from turbinefit.sim.dataset import DATA_VERSION
    from turbinefit.train.trainer import train

    old = tmp_path / "data" / "train-n4-s0-x2"
    old.mkdir(parents=True)
    spec = replace(DatasetSpec(4, 0, image_scale=2), version=DATA_VERSION - 1)
    (old / "spec.json").write_text(json.dumps(asdict(spec)))
    cfg = TrainConfig(out_dir=tmp_path / "out", data_dir=tmp_path / "data", n_images=4,
                      val_images=2, max_steps=1)
    with pytest.raises(InputError, match="data version"):
        train(cfg, progress=False, log=lambda _: None)
    assert not (tmp_path / "out").exists()
    assert not (tmp_path / "data" / "val-n2-s0-x2").exists()


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
