"""ONNX export (turbinefit.train.export): the shipped resize graph, ONNX outputs equal to
PyTorch's.

Needs the optional extra ``turbinefit[train]``; skipped without PyTorch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")
from turbinefit.detect import HeatmapDetector, letterbox  # noqa: E402
from turbinefit.heatmaps.model_info import ModelInfo  # noqa: E402
from turbinefit.io.images import resize_image  # noqa: E402
from turbinefit.train.export import export_onnx  # noqa: E402
from turbinefit.train.net import HeatmapNet  # noqa: E402
from turbinefit.train.trainer import forward  # noqa: E402

torch.set_num_threads(1)


def test_shipped_resize_graph_is_the_exported_one(tmp_path: Path) -> None:
    """The package's resize graph is what export_resize_onnx writes (regenerate it with
    that function if this fails)."""
    from turbinefit.detect import RESIZE_MODEL, default_model_path
    from turbinefit.train.export import export_resize_onnx

    fresh = export_resize_onnx(tmp_path / RESIZE_MODEL)
    shipped = default_model_path().with_name(RESIZE_MODEL)
    assert fresh.read_bytes() == shipped.read_bytes()


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
    # a 4:3 photo fills the input; others are letterboxed into it (maps cut back)
    for h, w, mh, mw in ((120, 160, 120, 160), (96, 160, 96, 160), (160, 160, 120, 120)):
        img = rng.integers(0, 256, size=(h * scale, w * scale, 3), dtype=np.uint8)
        got = det.detect_small(img)

        def net_maps(photo: np.ndarray, mh: int = mh, mw: int = mw) -> np.ndarray:
            x_in, left, top = letterbox(resize_image(photo, mw * scale, mh * scale), info)
            x = torch.from_numpy(x_in.transpose(2, 0, 1).copy()).float()[None] / 255
            with torch.no_grad():
                out = torch.sigmoid(forward(net, x))[0].numpy()
            return out[:, top // scale:top // scale + mh, left // scale:left // scale + mw]

        ref = net_maps(img)
        mirrored = net_maps(img[:, ::-1])[:, :, ::-1]
        if flip:  # the mean with the mirror image's maps mirrored back
            assert np.abs(mirrored - ref).max() > 1e-3  # the net itself is not symmetric
            ref = 0.5 * (ref + mirrored)
        assert got.shape == ref.shape == (7, mh, mw)
        np.testing.assert_allclose(got, ref, atol=2e-5)
        # at the photo's own size: the maps resized back
        assert det.detect(img).shape == (7, h * scale, w * scale)
