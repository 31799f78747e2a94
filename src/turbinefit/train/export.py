"""A trained net's files: the ONNX model, the resize graph and the NumPy weights.

* :func:`export_onnx` writes the net (+ sigmoid) as the ONNX model
  :class:`turbinefit.detect.HeatmapDetector` runs, with its
  :class:`~turbinefit.heatmaps.model_info.ModelInfo` in the file's metadata;
* :func:`export_resize_onnx` writes the graph the detector enlarges heat-maps with;
* :func:`save_npz` / :func:`load_npz` write and read the weights as NumPy arrays
  (``weights.npz``: PyTorch-free, what ``--init`` starts a run from).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import torch

from turbinefit.errors import InputError
from turbinefit.heatmaps import NUM_CHANNELS
from turbinefit.heatmaps.model_info import ModelInfo
from turbinefit.io.atomic import write_bytes_atomic
from turbinefit.train.net import (
    WIDTHS,
    HeatmapNet,
    Widths,
    add_fine,
    architecture,
    fine_width,
    lift_to_input_scale_2,
    widen,
)

#: ONNX opset of the exported models.
OPSET = 17


def load_npz(path: Path, input_scale: int | None = None,
             widths: Widths | None = None, fine: int | None = None) -> HeatmapNet:
    """The net of a ``weights.npz``, of ``input_scale``, ``widths`` and ``fine`` branch
    (default: those of the weights, read off their shapes by
    :func:`~turbinefit.train.net.architecture` and :func:`~turbinefit.train.net.fine_width`).
    Weights of input scale 1 are lifted to 2 by
    :func:`~turbinefit.train.net.lift_to_input_scale_2` (2 cannot go back to 1), weights
    of a narrower net are widened by :func:`~turbinefit.train.net.widen`, and weights
    without a fine branch get one by :func:`~turbinefit.train.net.add_fine`; a fine branch
    cannot be removed or resized."""
    try:
        with np.load(path) as z:
            state = {k: torch.from_numpy(z[k]) for k in z.files}
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read weights: {e}", path=path) from e
    try:
        have_widths, stem, have = architecture(state)
        have_fine = fine_width(state)
    except KeyError as e:
        raise InputError(f"not weights of a HeatmapNet (no {e})", path=path) from None
    scale = input_scale or have
    if have == 2 and scale == 1:
        raise InputError("weights are of a net of input scale 2; they cannot start one of "
                         "input scale 1", path=path)
    if have < scale:
        if have_widths != WIDTHS:
            raise InputError("only weights of the default widths can be lifted to input "
                             "scale 2", path=path)
        state = lift_to_input_scale_2(state)
    widths = widths or have_widths
    if widths != have_widths:
        try:
            state = widen(state, widths)
        except ValueError as e:  # narrower than the weights
            raise InputError(str(e), path=path) from None
    fine = have_fine if fine is None else fine
    if fine != have_fine:
        if have_fine:
            raise InputError(f"weights have a fine branch of {have_fine} channels; they "
                             f"cannot start a net with {fine}", path=path)
        try:
            state = add_fine(state, fine)
        except ValueError as e:  # the net's own check: a fine branch needs input scale 2
            raise InputError(str(e), path=path) from None
    net = HeatmapNet(widths, stem, input_scale=scale, fine=fine)
    try:
        net.load_state_dict(state)
    except RuntimeError as e:
        raise InputError(f"weights do not fit the net: {str(e).splitlines()[0]}", path=path) from e
    return net


def averaging_partner(path: Path, net: HeatmapNet) -> dict[str, torch.Tensor]:
    """The weights of the ``weights.npz`` at ``path``, to average ``net``'s with
    (:func:`average_weights`), checked to be of ``net``'s architecture.

    Raises:
        InputError: ``path`` unreadable, or not the same architecture.
    """
    other = load_npz(path).state_dict()
    mine = net.state_dict()
    if other.keys() != mine.keys() or any(other[k].shape != mine[k].shape for k in mine):
        raise InputError("not the weights of a net of the same architecture as the one "
                         "trained", path=path)
    return other


def average_weights(net: HeatmapNet, other: dict[str, torch.Tensor], weight: float) -> None:
    """Replace ``net``'s weights by ``weight`` times them plus ``1 - weight`` times
    ``other`` (:func:`averaging_partner`; a "model soup": a net fine-tuned from another,
    averaged with it, often keeps what each does best). Integer buffers (batch norm's
    counters) are ``net``'s."""
    net.load_state_dict({k: (weight * v.double() + (1.0 - weight) * other[k].double()).to(v.dtype)
                         if v.is_floating_point() else v for k, v in net.state_dict().items()})


def save_npz(net: torch.nn.Module, path: Path) -> None:
    buf = io.BytesIO()
    np.savez(buf, **{k: v.detach().cpu().numpy() for k, v in net.state_dict().items()})
    write_bytes_atomic(path, buf.getvalue())


class _Sigmoid(torch.nn.Module):
    def __init__(self, net: torch.nn.Module) -> None:
        super().__init__()
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(self.net(x))


def export_onnx(net: HeatmapNet, path: Path, info: ModelInfo) -> Path:
    """Export ``net`` (+ sigmoid) as ONNX with dynamic batch and image size and
    ``info`` in its metadata, atomically.

    Uses PyTorch's TorchScript exporter (``dynamo=False``): it needs only the ``onnx``
    package (the torch.export-based one also needs onnxscript) and writes a plain graph of
    the requested opset that onnxruntime folds (batch norm into the convolutions).
    """
    import warnings

    import onnx

    was_training = net.training
    net.eval()
    buf = io.BytesIO()
    dummy = torch.rand(1, 3, info.input_height + (-info.input_height) % info.stride,
                       info.input_width)
    dyn = {0: "batch", 2: "height", 3: "width"}
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.onnx.export(_Sigmoid(net), (dummy,), buf,  # type: ignore[arg-type]
                          dynamo=False, opset_version=info.opset,
                          input_names=["image"], output_names=["heatmaps"],
                          dynamic_axes={"image": dyn, "heatmaps": dyn})
    model = onnx.load_from_string(buf.getvalue())
    for k, v in info.to_metadata().items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, v
    net.train(was_training)
    return write_bytes_atomic(path, model.SerializeToString())


def export_resize_onnx(path: Path, opset: int = 13) -> Path:
    """Write the ONNX graph that :class:`~turbinefit.detect.HeatmapDetector` enlarges
    heat-maps with (:data:`~turbinefit.detect.RESIZE_MODEL`, shipped in the package):
    one ``Resize`` node, bilinear with pixel centres aligned (``half_pixel``), input ``x``
    (1, 7, h, w) float32 and ``sizes`` (4,) int64, output ``y``. For enlargement this is
    the bilinear filter of :func:`turbinefit.heatmaps.resize.resize_maps` (Pillow), run on
    onnxruntime's threads instead of one channel at a time."""
    from onnx import TensorProto, helper

    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, NUM_CHANNELS, "h", "w"])
    sizes = helper.make_tensor_value_info("sizes", TensorProto.INT64, [4])
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, NUM_CHANNELS, "H", "W"])
    node = helper.make_node("Resize", ["x", "", "", "sizes"], ["y"], mode="linear",
                            coordinate_transformation_mode="half_pixel")
    graph = helper.make_graph([node], "turbinefit_resize_maps", [x, sizes], [y])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)],
                              producer_name="turbinefit")
    return write_bytes_atomic(path, model.SerializeToString())
