"""Training (turbinefit.train.trainer): the loss and its channel weights, a few steps,
evaluation, jitter, refusing old datasets.

Needs the optional extra ``turbinefit[train]``; skipped without PyTorch."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")
from turbinefit.errors import InputError  # noqa: E402
from turbinefit.sim.dataset import DatasetSpec, build_dataset  # noqa: E402
from turbinefit.train.net import HeatmapNet  # noqa: E402
from turbinefit.train.trainer import TrainConfig, _jitter, evaluate, forward, heatmap_loss  # noqa: E402

torch.set_num_threads(1)


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
