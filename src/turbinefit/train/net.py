"""The heat-map CNN: a compact U-Net-like encoder-decoder with a strided stem (PyTorch).

Input: an RGB image batch (B, 3, s H, s W), float32 in [0, 1], s = ``input_scale`` (1 or
2), H and W multiples of :data:`STRIDE` (the caller pads). Output: logits (B, 7, H, W),
one channel per heat-map of :data:`turbinefit.heatmaps.CHANNEL_NAMES`;
``sigmoid(logits)`` are the heat-maps. The shipped model has s = 2: it sees 320 x 240
photos and gives 160 x 120 heat-maps.

Shape of the net (channels at each scale, heat-maps 160 x 120):

* pre (s = 2 only): a 3x3 stride-2 convolution (16 channels) from the 320 x 240 photo to
  160 x 120, so the net sees what the full resolution shows (a blade tip 1-2 px wide, a
  far turbine 10 px tall) for a few per cent more work;
* stem: 3x3 stride-2 convolution to 1/2 resolution (80 x 60), so that the expensive
  layers never run at full resolution;
* encoder: double 3x3 conv blocks at 1/2, 1/4, 1/8 and 1/16 resolution, the last one with
  dilated convolutions for context (a blade and the tower look alike up close; what tells
  them apart is the rest of the turbine);
* decoder: bilinear up-sampling, concatenation with the encoder's features (U-Net skips),
  3x3 conv blocks back to 1/2;
* head: a 1x1 conv to 4 x 7 channels at 1/2 resolution and a pixel shuffle (depth to
  space) to full resolution, so each half-resolution cell places its 2 x 2 full-resolution
  values itself (sub-pixel placement of thin ridges) without any full-resolution
  convolution.
* fine branch (optional, ``fine`` channels, input scale 2 only): one 3x3 conv block at
  heat-map resolution over the ``pre`` features (what the full-resolution photo shows at
  that grid: a blade tip 1-2 px wide) and the head's logits, then a 1x1 conv whose output
  is *added* to the logits: the head decides from 1/2-resolution features where the
  turbine is, the branch can correct thin ends (blade tips) from what the pixels show.
  Its output layer starts at zero (:func:`add_fine` gives trained weights one that
  changes nothing until trained). Measured (src/turbinefit/models/README.md): 16 channels on the shipped net
  raised tips recall / precision by ~2 points each for ~20 % more inference time; the
  shipped model has none.

Every convolution is followed by batch norm and ReLU (batch norm folds into the
convolutions at ONNX export). About 0.63 M parameters with the default :data:`WIDTHS`;
:func:`widen` turns trained weights into a wider net's that starts out computing the same
heat-maps, and :func:`architecture` reads the widths off any weights. Measured on the machine that
trained the first model (one thread, channels-last, batch 16 of 160 x 128): ~60 training
samples/s, and a full-resolution head (3x3 convs at 160 x 128) halved that, for no
visible gain in peak placement. On this project's current 2-core machine the same net
trains at ~12 samples/s on one thread and ~19 on two, and s = 2 costs ~10 % more than
s = 1.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from turbinefit.heatmaps import NUM_CHANNELS

#: Total down-sampling factor: H and W of the input must be multiples of it.
STRIDE = 16
#: Channel widths at 1/2, 1/4, 1/8, 1/16 resolution.
WIDTHS = (32, 48, 64, 112)
#: Channels of the full-resolution layer ``pre`` (input scale 2).
PRE = 16


def _conv(cin: int, cout: int, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride=stride, padding=dilation, dilation=dilation, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class HeatmapNet(nn.Module):
    """Image (B, 3, H, W) in [0, 1] -> heat-map logits (B, 7, H, W)."""

    def __init__(self, widths: tuple[int, int, int, int] = WIDTHS, stem: int = 24,
                 input_scale: int = 1, fine: int = 0) -> None:
        super().__init__()
        if input_scale not in (1, 2):
            raise ValueError(f"input_scale must be 1 or 2, got {input_scale}")
        if fine < 0 or (fine and input_scale != 2):
            raise ValueError(f"a fine branch ({fine} channels) needs input_scale 2")
        w1, w2, w3, w4 = widths
        self.input_scale = input_scale
        self.pre: nn.Module = _conv(3, PRE, stride=2) if input_scale == 2 else nn.Identity()
        self.stem = _conv(PRE if input_scale == 2 else 3, stem, stride=2)
        self.enc1 = _conv(stem, w1)
        self.enc2 = nn.Sequential(_conv(w1, w2, stride=2), _conv(w2, w2))
        self.enc3 = nn.Sequential(_conv(w2, w3, stride=2), _conv(w3, w3))
        self.enc4 = nn.Sequential(_conv(w3, w4, stride=2), _conv(w4, w4, dilation=2),
                                  _conv(w4, w4, dilation=4))
        self.dec3 = nn.Sequential(_conv(w4 + w3, w3), _conv(w3, w3))
        self.dec2 = nn.Sequential(_conv(w3 + w2, w2), _conv(w2, w2))
        self.dec1 = _conv(w2 + w1, w1)
        self.head = nn.Conv2d(w1, 4 * NUM_CHANNELS, 1)
        # Start from "nothing detected" (sigmoid(-4) = 0.018): the targets are mostly 0.
        assert self.head.bias is not None
        nn.init.constant_(self.head.bias, -4.0)
        self.fine: nn.Sequential | None = None
        if fine:
            self.fine = nn.Sequential(_conv(PRE + NUM_CHANNELS, fine),
                                      nn.Conv2d(fine, NUM_CHANNELS, 1))
            zero_fine_output(self.fine)

    @staticmethod
    def _up(x: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
        return F.interpolate(x, size=like.shape[-2:], mode="bilinear", align_corners=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        p = self.pre(x)
        e1 = self.enc1(self.stem(p))
        e2 = self.enc2(e1)
        e3 = self.enc3(e2)
        e4 = self.enc4(e3)
        d3 = self.dec3(torch.cat([self._up(e4, e3), e3], 1))
        d2 = self.dec2(torch.cat([self._up(d3, e2), e2], 1))
        d1 = self.dec1(torch.cat([self._up(d2, e1), e1], 1))
        out = F.pixel_shuffle(self.head(d1), 2)
        if self.fine is not None:  # a correction at heat-map resolution
            out = out + self.fine(torch.cat([p, out], 1))
        return out


def zero_fine_output(fine: nn.Sequential) -> None:
    """Zero the last (1x1) convolution of a fine branch: the branch then adds nothing."""
    last = fine[-1]
    assert isinstance(last, nn.Conv2d) and last.bias is not None
    nn.init.zeros_(last.weight)
    nn.init.zeros_(last.bias)


def num_parameters(net: nn.Module) -> int:
    return sum(p.numel() for p in net.parameters())


Widths = tuple[int, int, int, int]


def architecture(state: dict[str, torch.Tensor]) -> tuple[Widths, int, int]:
    """``(widths, stem, input_scale)`` of the net whose ``state_dict`` is ``state``, read
    off the weights' shapes (a net of input scale 2 has the full-resolution ``pre``)."""
    def out(key: str) -> int:
        return int(state[key].shape[0])
    widths = (out("enc1.0.weight"), out("enc2.1.0.weight"), out("enc3.1.0.weight"),
              out("enc4.1.0.weight"))
    return widths, out("stem.0.weight"), 2 if "pre.0.weight" in state else 1


def fine_width(state: dict[str, torch.Tensor]) -> int:
    """Channels of the fine branch of the net whose ``state_dict`` is ``state`` (0: none)."""
    w = state.get("fine.0.0.weight")
    return 0 if w is None else int(w.shape[0])


def add_fine(state: dict[str, torch.Tensor], fine: int, seed: int = 0
             ) -> dict[str, torch.Tensor]:
    """Weights of the same net with a fine branch of ``fine`` channels that computes
    exactly what ``state`` computes: the branch's output layer starts at zero (its
    gradients are not zero), its hidden layer as a fresh net's."""
    widths, stem, scale = architecture(state)
    if fine_width(state):
        raise ValueError(f"weights already have a fine branch of {fine_width(state)} channels")
    torch.manual_seed(seed)
    new = HeatmapNet(widths, stem, input_scale=scale, fine=fine).state_dict()
    return {**new, **{k: v.clone() for k, v in state.items()}}


def _input_segments(name: str, old: Widths, new: Widths, stem_old: int, stem_new: int,
                    cin_old: int, cin_new: int) -> list[tuple[int, int, int]]:
    """(old start, new start, length) of the old input channels of conv ``name`` in its
    new input: the U-Net concatenations [up-sampled deeper features, skip] move the skip's
    channels when the deeper block is widened."""
    w_old, w_new = (0, *old), (0, *new)
    concat = {"dec3.0.0": 4, "dec2.0.0": 3, "dec1.0": 2}  # deeper block of the concatenation
    if name in concat:
        k = concat[name]
        return [(0, 0, w_old[k]), (w_old[k], w_new[k], w_old[k - 1])]
    if name == "enc1.0":
        return [(0, 0, stem_old)]
    return [(0, 0, min(cin_old, cin_new))]


def widen(state: dict[str, torch.Tensor], widths: Widths, stem: int | None = None,
          seed: int = 0) -> dict[str, torch.Tensor]:
    """Weights of a wider net that computes exactly what ``state`` computes (in eval mode).

    Each convolution keeps its old weights; its new output channels start random (as a
    fresh net's) and every old output channel reads the new input channels with weight
    zero, so the new channels change nothing until training moves those zeros (their
    gradients are not zero). This is the function-preserving widening of Net2Net (Chen et
    al., 2016) with zero instead of copied channels: fine-tuning starts from the trained
    net's heat-maps and spends its steps on what the extra capacity adds.
    """
    old_w, old_stem, scale = architecture(state)
    fine = fine_width(state)
    stem = old_stem if stem is None else stem
    if any(n < o for n, o in zip(widths, old_w, strict=True)) or stem < old_stem:
        raise ValueError(f"cannot narrow a net: weights of widths {old_w} (stem {old_stem}) "
                         f"cannot start a narrower one {widths} (stem {stem})")
    torch.manual_seed(seed)
    fresh = HeatmapNet(widths, stem, input_scale=scale, fine=fine).state_dict()
    new = {k: v.clone() for k, v in fresh.items()}
    for key, v_old in state.items():
        v = new[key]
        if v.shape == v_old.shape:
            new[key] = v_old.clone()
        elif v.dim() == 4:  # convolution weight (out, in, kh, kw)
            co = v_old.shape[0]
            v[:co] = 0.0
            for a, b, n in _input_segments(key.rsplit(".", 1)[0], old_w, widths, old_stem, stem,
                                           v_old.shape[1], v.shape[1]):
                v[:co, b:b + n] = v_old[:, a:a + n]
        elif v.dim() == 1:  # batch-norm statistics / affine, head bias
            v[:v_old.shape[0]] = v_old
        else:
            new[key] = v_old.clone()
    return new


def lift_to_input_scale_2(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Weights of an input-scale-1 net (160 x 120 photos) as an input-scale-2 net (320 x
    240 photos) that starts out computing nearly the same heat-maps.

    The new full-resolution layer ``pre`` passes R, G, B on as a 2x blur-downsample (a
    [1, 2, 1] / 4 tent, which is close to the antialiased bilinear resize the old net was
    fed; its batch norm is set to the identity on typical image statistics) in its first
    three channels, and its other channels start small and random; the stem reads those
    three channels with the old stem's weights and the others with zeros. Everything else
    is copied. Fine-tuning then learns what the full resolution adds (thin blade tips,
    small far turbines) without starting from scratch.
    """
    net = HeatmapNet(input_scale=2)
    new = {k: v.clone() for k, v in net.state_dict().items()}
    for k, v in state.items():
        if k == "stem.0.weight":
            w = torch.zeros_like(new[k])
            w[:, :3] = v
            new[k] = w
        elif k in new:
            new[k] = v.clone()
    tent = torch.tensor([0.25, 0.5, 0.25])
    w = 0.1 * new["pre.0.weight"]
    w[:3] = 0.0
    for c in range(3):
        w[c, c] = tent[:, None] * tent[None, :]
    new["pre.0.weight"] = w
    # batch norm ~ identity for pixel values of mean 0.45 and standard deviation 0.25
    new["pre.1.weight"][:3] = 0.25
    new["pre.1.bias"][:3] = 0.45
    new["pre.1.running_mean"][:3] = 0.45
    new["pre.1.running_var"][:3] = 0.0625
    return new
