"""A heat-map model's settings: the metadata an ONNX heat-map model carries.

``turbinefit train`` writes a :class:`ModelInfo` into the model file's metadata
(:meth:`ModelInfo.to_metadata`, keys ``turbinefit.<field>``); :mod:`turbinefit.detect`
reads it back (:meth:`ModelInfo.from_metadata`) and resizes, pads, thresholds, flips,
shifts and zooms as it says. Opening the file is the reader's business (onnxruntime,
onnx); this module holds only the data type, the key names and their validation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from turbinefit.errors import InputError

#: Prefix of turbinefit's keys in a model file's metadata (``turbinefit.threshold`` ...).
METADATA_PREFIX = "turbinefit."
#: Oldest and newest ONNX opsets turbinefit's models are exported with / accepted at.
MIN_OPSET, MAX_OPSET = 13, 21
#: Radius [px at the model's input width] around the hub within which
#: :func:`turbinefit.detect.shift_tips` tapers the tip shift to zero (tips that close to
#: the hub are of far, tiny turbines, where the net's blobs of hub and tips merge).
TIP_SHIFT_TAPER_PX = 20.0


def valid_tip_shift(px: float) -> bool:
    """Whether ``px`` can be a tip shift: finite and within the taper radius, where
    :func:`turbinefit.detect.shift_tips` stays one-to-one."""
    return math.isfinite(px) and abs(px) < TIP_SHIFT_TAPER_PX


@dataclass(frozen=True)
class ModelInfo:
    """A heat-map model's settings (metadata keys :data:`METADATA_PREFIX` + field name).

    Attributes:
        input_width: width [px] photos are resized to.
        input_height: height [px] of a 4:3 photo at that width (for reference).
        stride: the padded input's sides are multiples of it.
        output_scale: the heat-maps are this many times smaller than the input (1 or 2).
        sigma_px: blob / ridge standard deviation of the training targets [px at the
            input width].
        threshold: peak value above which a point channel (base, tower top, hub) counts
            as a detection (calibrated on held-out renders: false peaks where the point is
            out of view in at most 5 % of them).
        tip_threshold: the same for local maxima of the blade-tip channel (calibrated for
            the best F1 of tip recall and precision within 5 px).
        flip: detect on the photo and its mirror image and average the maps (the
            thresholds were calibrated so); False for models written before this field.
        tip_shift_px: distance [px at the input width] the tip channel is moved outward
            from the detected hub (:func:`turbinefit.detect.shift_tips`; calibrated on held-out renders:
            minus the mean offset of the net's tip peaks along the blade); 0 (no shift)
            for models written before this field.
        zoom: find the blade tips of small turbines again in a second pass of the net
            on an enlarged crop (test-time zoom, step 4 of :mod:`turbinefit.detect`); False
            for models written before this field.
        opset: ONNX opset of the file.
        description: how it was trained.
    """

    input_width: int = 160
    input_height: int = 120
    stride: int = 16
    output_scale: int = 1
    sigma_px: float = 1.5
    threshold: float = 0.3
    tip_threshold: float = 0.3
    flip: bool = False
    tip_shift_px: float = 0.0
    zoom: bool = False
    opset: int = 17
    description: str = ""

    def to_metadata(self) -> dict[str, str]:
        """The metadata entries (key: text) of these settings, as a model file holds them."""
        return {f"{METADATA_PREFIX}{k}": str(v) for k, v in self.__dict__.items()}

    @staticmethod
    def from_metadata(meta: dict[str, str], path: Path) -> ModelInfo:
        """The settings in a model file's metadata ``meta`` (keys not of turbinefit are
        ignored; a missing key has its default).

        Raises:
            InputError: naming ``path`` for a value that does not parse or is out of
                range, or an unsupported opset.
        """
        kw: dict[str, object] = {}
        for name, typ in (("input_width", int), ("input_height", int), ("stride", int),
                          ("output_scale", int), ("sigma_px", float), ("threshold", float),
                          ("tip_threshold", float), ("flip", _flag),
                          ("tip_shift_px", float), ("zoom", _flag), ("opset", int),
                          ("description", str)):
            key = f"{METADATA_PREFIX}{name}"
            if key not in meta:
                continue
            try:
                kw[name] = typ(meta[key])
            except ValueError:
                raise InputError(f"model metadata {key}={meta[key]!r} is not a valid "
                                 f"{'flag (True or False)' if typ is _flag else typ.__name__}",
                                 path=path) from None
        info = ModelInfo(**kw)  # type: ignore[arg-type]
        if (info.input_width < 16 or info.stride < 1 or not info.sigma_px > 0
                or not valid_tip_shift(info.tip_shift_px)
                or info.output_scale not in (1, 2) or info.stride % info.output_scale
                or info.input_width % info.output_scale):
            raise InputError(f"model metadata out of range: {info}", path=path)
        if not MIN_OPSET <= info.opset <= MAX_OPSET:
            raise InputError(f"model opset {info.opset} is not supported (need "
                             f"{MIN_OPSET}..{MAX_OPSET})", path=path)
        return info


def _flag(text: str) -> bool:
    if text not in ("True", "False"):
        raise ValueError(text)
    return text == "True"
