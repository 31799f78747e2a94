"""The heat-map CNN (turbinefit.train.net): shape and size, lifting to 320-px input,
widening and a fine branch that start by computing the same heat-maps.

Needs the optional extra ``turbinefit[train]``; skipped without PyTorch."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")
from turbinefit.io.images import resize_image  # noqa: E402
from turbinefit.sim.dataset import DatasetSpec, render_sample  # noqa: E402
from turbinefit.train.net import (  # noqa: E402
    HeatmapNet,
    add_fine,
    architecture,
    fine_width,
    lift_to_input_scale_2,
    num_parameters,
    widen,
)
from turbinefit.train.trainer import forward, heatmap_loss  # noqa: E402

torch.set_num_threads(1)


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
