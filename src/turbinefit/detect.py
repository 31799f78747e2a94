"""Heat-maps from photos: the CNN's inference with onnxruntime.

:class:`HeatmapDetector` runs an ONNX heat-map model (by default the one shipped in the
package, :func:`default_model_path`) on RGB photos of any size (:class:`DetectorPool`
runs one single-threaded detector per core on as many photos at once: the same maps,
faster for many photos):

1. the photo is resized (bilinear, antialiased; :func:`turbinefit.io.images.resize_image`)
   to fit the model's 4:3 input (``input_width`` x ``input_height`` of the model's
   metadata, 320 x 240 for the shipped model) keeping its aspect ratio
   (:func:`model_input_size`), set in the middle of that input with the margins filled by
   reflection (:func:`letterbox`: a square, 3:2, 16:9 or portrait photo is seen in the
   frame the net was trained on, with no border artefacts; the maps are cut back to the
   photo), then padded by edge replication to a multiple of the model's stride;
2. the model gives seven heat-maps in [0, 1] (a sigmoid ends the graph), channel order of
   :data:`turbinefit.heatmaps.CHANNEL_NAMES`, at ``1 / output_scale`` of its input size
   (the shipped model: 160 x 120 maps of a 320 x 240 input); for a model whose metadata
   says ``flip`` (the shipped one and those ``turbinefit train`` writes), the maps are the
   mean of those of the photo and of its mirror image mirrored back (test-time
   augmentation: the seven channels are symmetric under a left-right flip; twice the
   work, tips and lines found more often and more precisely, and the model's thresholds
   are calibrated on such means);
3. for a model whose metadata has a ``tip_shift_px`` (the shipped one and those
   ``turbinefit train`` writes), the blade-tip channel is moved that far outward from the
   detected hub (:func:`shift_tips`). The net puts tip blobs on average a little inboard
   of the true tips (a tapered blade's last metres are thinner than a pixel: the net
   sees the blade end before the tip), and a fit over many keyframes adds such a bias up
   into the turbine's size and the drone's track; the shift is calibrated at export on
   held-out renders (:class:`turbinefit.eval.detection.DetectionStats`,
   ``tip_shift_px``) and is skipped where no hub is detected;
4. for a model whose metadata says ``zoom`` (the shipped one and those ``turbinefit
   train`` writes): test-time zoom of small turbines' blade tips. The pixels of the seven
   maps above the model's threshold, widened by :data:`ZOOM_MARGIN_PX` on each side, are
   the turbine's box; if it fits in the photo shrunk 1.4 times (:data:`ZOOM_MIN`), a crop
   of the *photo* (at the photo's own resolution) of the photo's aspect, centred on that
   box and enlarged as much as the box allows (at most 2x, :data:`ZOOM_MAX`), is run
   through the net once more (one pass, without the mirror image; tip shift as in step 3
   with that pass's own hub), and inside the crop the tip channel becomes the larger of
   the two passes' values. Far turbines' blade tips are a pixel or two across at the
   input width; enlarged, the net finds more of them (held-out renders: recall +3 points
   at about the same precision; docs/cnn.md). A larger of two passes only adds
   tips: taking the zoomed pass's alone loses some that the first pass found. The other
   six channels stay those of the first pass (zoomed lines are narrower ridges, hub,
   tower top and base gain under 0.1 px); zoomed tip blobs are narrower, ``sigma_px / z``.
   Nearby turbines in the photo widen the box, and then no zoom is made. It costs one
   more single pass of the net for each photo it zooms (a quarter of the held-out renders,
   13-17 % of a simulated flight's photos);
5. with ``refine`` (:class:`DetectOptions`; off by default): coarse to fine. A photo at
   least :data:`REFINE_MIN` times the model's input size (640 px wide for the shipped
   model) is looked at again around each point the first pass found in
   :data:`REFINE_CHANNELS` (the tower top's and the hub's maxima, each blade-tip local
   maximum above the tip threshold): a crop of the photo 1 / z of its size, z that
   multiple rounded down and at most :data:`REFINE_MAX` (4: a 1280 x 960 photo's crops
   are 320 x 240, read at the photo's own resolution), centred on the point (clamped
   inside the photo), goes through the net (flip-averaged as in step 2, without tip
   shift). Where the crop finds the same point within :data:`REFINE_GATE` map pixels, the
   first pass's blob (the map within :data:`REFINE_RADIUS` pixels of the point) is moved
   there unchanged (cubic resampling): the maps keep their size, their blobs' shape and
   height, and what was found; only where the points are changes, never by more than the
   gate nor outside the crop. On held-out renders at 1280 x 960 the hub's median error
   falls from 5.2 to 2.7 photo px and the tower top's from 3.6 to 3.1, the tips' mean
   offset along the blade from 1.0 px outward to 0.0 (the crop's tips need no tip
   shift), for 1.7 points of tip precision; fits from 1280 x 960 photos end 4 % nearer
   the truth on average (docs/benchmarks.md). One more flip-averaged pass of the net
   per point (3-6 per photo: about twice the detection time); the base and the line
   channels are the first pass's. ``fit``, ``track`` and ``init`` refine photos by
   default, ``detect`` and ``evaluate`` only when asked;
6. the padding is cut off and the maps are resized back to the photo's own size
   (bilinear, pixel centres aligned), float32 (7, H, W). Enlarging runs on onnxruntime
   (a one-node graph shipped as :data:`RESIZE_MODEL`, written by
   :func:`turbinefit.train.export.export_resize_onnx`: the same filter as Pillow's, on
   all cores, a tenth of the time per photo at 320 x 240); shrinking (photos narrower
   than the heat-maps) uses Pillow's antialiased filter
   (:func:`turbinefit.heatmaps.resize.resize_maps`).

So a heat-map pixel ``[c, i, j]`` is photo pixel ``u = j, v = i`` whatever the size; blobs
and ridges are ``sigma_px`` (metadata, 3 for the shipped model) wide at the input width,
i.e. ``sigma_px * W / input_width`` in the photo.

Model files: ONNX with one input ``(batch, 3, height, width)`` float32 RGB in [0, 1] and one
output ``(batch, 7, height / output_scale, width / output_scale)`` float32 in [0, 1],
height and width dynamic; turbinefit writes its settings into the ONNX metadata
(``turbinefit.*`` keys, see :class:`turbinefit.heatmaps.model_info.ModelInfo`; a model
without ``output_scale`` has 1).
A file that is not such a model is an :class:`~turbinefit.errors.InputError`.
"""

from __future__ import annotations

import dataclasses
import math
import os
import queue
from collections import deque
from collections.abc import Callable, Generator, Iterable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from turbinefit.errors import InputError, interrupt_within
from turbinefit.heatmaps import CHANNEL_NAMES, NUM_CHANNELS
from turbinefit.heatmaps.model_info import TIP_SHIFT_TAPER_PX, ModelInfo, valid_tip_shift
from turbinefit.heatmaps.peaks import peak, peaks
from turbinefit.heatmaps.resize import resize_maps
from turbinefit.io.atomic import StrPath
from turbinefit.io.images import resize_image
from turbinefit.io.limits import MAX_MODEL_BYTES, check_input_file

if TYPE_CHECKING:
    import onnxruntime as ort

F32Array = NDArray[np.float32]
T = TypeVar("T")
R = TypeVar("R")

#: File name of the shipped model inside the package's ``models`` folder.
DEFAULT_MODEL = "heatmap_cnn.onnx"
#: File name of the bilinear resize graph (heat-maps to photo size) in the same folder.
RESIZE_MODEL = "resize_maps.onnx"

HUB, TIP = CHANNEL_NAMES.index("point_hub"), CHANNEL_NAMES.index("point_blade_tip")
TOWER_TOP = CHANNEL_NAMES.index("point_tower_top")

#: Test-time zoom (step 4 of the module docstring): a photo is zoomed when the box of its
#: heat-map pixels above the model's threshold, widened by ``ZOOM_MARGIN_PX`` [px at the
#: model's input width] on each side, fits in the photo shrunk ``ZOOM_MIN`` times; the
#: enlargement is the largest that fits, at most ``ZOOM_MAX``.
ZOOM_MIN, ZOOM_MAX, ZOOM_MARGIN_PX = 1.4, 2.0, 8.0

#: Coarse to fine (step 5 of the module docstring): a photo at least ``REFINE_MIN`` times
#: the model's input size is looked at again on crops 1 / z of its size, z = that multiple
#: rounded down, at most ``REFINE_MAX``, centred on the points of ``REFINE_CHANNELS``; a
#: point moves if the crop finds it within ``REFINE_GATE`` [map px], and with it its blob,
#: the map within ``REFINE_RADIUS`` [map px] of it.
REFINE_MIN, REFINE_MAX = 2, 4
REFINE_CHANNELS = (TOWER_TOP, HUB, TIP)
REFINE_GATE, REFINE_RADIUS = 1.0, 4


#: Overlay colour (RGB) of each channel.
CHANNEL_COLOURS = np.array([
    (255, 40, 40),    # point_base: red
    (255, 150, 0),    # point_tower_top: orange
    (255, 255, 0),    # point_hub: yellow
    (255, 0, 255),    # point_blade_tip: magenta
    (0, 230, 255),    # line_tower: cyan
    (0, 255, 60),     # line_nacelle: green
    (60, 110, 255),   # line_blade: blue
], dtype=np.float32)


def _onnxruntime() -> Any:
    """The ``onnxruntime`` module, imported on first use. A signal handled during that
    import stops the command like any other: onnxruntime's C++ module would turn it into
    ``ImportError: initialization failed``."""
    try:
        import onnxruntime
    except ImportError as e:
        interrupt = interrupt_within(e)
        if interrupt is None:
            raise
        raise interrupt from None
    return onnxruntime


def _session_options(threads: int, spinning: bool) -> ort.SessionOptions:
    """onnxruntime options: ``threads`` intra-op threads, quiet; with ``spinning`` False,
    idle threads sleep instead of spinning (other work needs the cores)."""
    ort = _onnxruntime()
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads
    opts.inter_op_num_threads = 1
    opts.log_severity_level = 3
    if not spinning:
        opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return opts


def default_model_path() -> Path:
    """The model shipped inside the package."""
    return Path(str(resources.files("turbinefit") / "models" / DEFAULT_MODEL))


def model_input_size(width: int, height: int, info: ModelInfo) -> tuple[int, int]:
    """(width, height) a ``width`` x ``height`` photo is resized to for the model: the
    largest that fits in the model's 4:3 input (``input_width`` x ``input_height``, 320 x
    240 for the shipped model) keeping the photo's aspect ratio, both sides multiples of
    ``output_scale`` (:func:`letterbox` pads it to the whole input)."""
    cw, ch, s = info.input_width, info.input_height, info.output_scale
    if width * ch >= height * cw:  # as wide as the input, or wider
        return cw, min(ch, s * max(1, round(cw * height / width / s)))
    return min(cw, s * max(1, round(ch * width / height / s))), ch


def letterbox(small: NDArray[np.uint8], info: ModelInfo) -> tuple[NDArray[np.uint8], int, int]:
    """(input, left, top): a photo resized by :func:`model_input_size` placed in the
    middle of the model's 4:3 input (``left`` and ``top`` [px] multiples of
    ``output_scale``), the margins filled by reflecting the photo, then padded on the
    right and bottom by edge replication to multiples of the model's stride.

    The net was trained on 4:3 renders of its input size only; a photo of another shape
    fed at its own shape (a square one as 320 x 320) made its line channels answer along
    the bottom edge of every photo (real square photos: the bottom rows' mean 4-7 times
    the whole map's; docs/cnn.md). A 4:3 photo is not changed by this."""
    h, w = small.shape[:2]
    s, st = info.output_scale, info.stride
    cw, ch = max(w, info.input_width), max(h, info.input_height)
    left, top = (cw - w) // 2 // s * s, (ch - h) // 2 // s * s
    pad = [(top, ch - h - top), (left, cw - w - left), (0, 0)]
    canvas = np.pad(small, pad, mode="reflect") if (cw, ch) != (w, h) else small
    stride_pad = ((0, -ch % st), (0, -cw % st), (0, 0))
    return np.pad(canvas, stride_pad, mode="edge"), left, top


@dataclass(frozen=True)
class DetectOptions:
    """How a :class:`HeatmapDetector` treats its model's maps, as one value the jobs
    and the CLI pass along; each None = as the model's metadata says.

    Attributes:
        flip: average the maps of the photo and of its mirror image
            (:attr:`ModelInfo.flip`).
        tip_shift: px at the model's input width the tip channel is moved outward from
            the hub (:attr:`ModelInfo.tip_shift_px`; 0 = none).
        zoom: test-time zoom of small turbines' blade tips (:attr:`ModelInfo.zoom`).
        input_scale: run the net at this multiple of its input size (None = 1).
        refine: coarse to fine, a second look at each point on a crop of the photo at its
            own resolution (step 5 of the module docstring); None = as the job decides
            (on for ``fit``, ``track`` and ``init`` from photos; off for ``detect`` and
            ``evaluate``).
    """

    flip: bool | None = None
    tip_shift: float | None = None
    zoom: bool | None = None
    input_scale: float | None = None
    refine: bool | None = None

    def detector(self, model: StrPath | None = None, threads: int | None = None, *,
                 spinning: bool = True) -> HeatmapDetector:
        """A :class:`HeatmapDetector` of ``model`` (None = the shipped one) with these
        options."""
        return HeatmapDetector(model, threads, spinning=spinning, flip=self.flip,
                               tip_shift=self.tip_shift, zoom=self.zoom,
                               input_scale=self.input_scale, refine=bool(self.refine))

    def pool(self, model: StrPath | None = None, workers: int | None = None) -> DetectorPool:
        """A :class:`DetectorPool` of ``workers`` detectors (None = one per core) of
        ``model`` (None = the shipped one) with these options."""
        return DetectorPool(model, workers, self)


class HeatmapDetector:
    """An ONNX heat-map model ready to run (see the module docstring).

    Args:
        model: ONNX file; None = the shipped model.
        threads: onnxruntime intra-op threads; None = all cores.
        spinning: let idle inference threads spin-wait for the next photo (fastest when
            detection is all the machine does); False when other work, such as the
            tracker's solver, shares the cores.
        flip: average the maps of the photo and of its mirror image; None = as the
            model's metadata says (:attr:`ModelInfo.flip`). False halves the work at some
            cost in accuracy (the thresholds of a ``flip`` model were calibrated with it).
        tip_shift: px at the model's input width the tip channel is moved outward from
            the hub (:func:`shift_tips`); None = the model's calibrated
            :attr:`ModelInfo.tip_shift_px`; 0 = the net's own tip channel.
        zoom: test-time zoom of small turbines' blade tips (step 4 of the module
            docstring); None = as the model's metadata says (:attr:`ModelInfo.zoom`).
        input_scale: run the net at this multiple of its input size (test-time scale:
            photos resized to ``input_scale`` times ``input_width``, maps that many times
            larger, :attr:`info` changed to match; None = 1). The shipped net was trained
            at 320 px: at 2 (640 px) fits from simulated 1280 x 960 photos gain nothing
            (``benchmarks/bench_resolution.py --photos``) and real photos are read much
            worse (``benchmarks/bench_real.py --input-scale 2``;
            docs/benchmarks.md).
        refine: coarse to fine on photos at least :data:`REFINE_MIN` times the model's
            input size (step 5 of the module docstring); off by default.

    Raises:
        InputError: naming the file if it is missing, not ONNX, of an unsupported opset or
            of the wrong input/output shape.
    """

    def __init__(self, model: StrPath | None = None, threads: int | None = None, *,
                 spinning: bool = True, flip: bool | None = None,
                 tip_shift: float | None = None, zoom: bool | None = None,
                 input_scale: float | None = None, refine: bool = False) -> None:
        ort = _onnxruntime()

        self.path = Path(model) if model is not None else default_model_path()
        # a regular file of a sane size (not a FIFO onnxruntime would wait on)
        check_input_file(self.path, MAX_MODEL_BYTES, missing="model file not found")
        n_threads = (os.cpu_count() or 1) if threads is None else int(threads)
        if n_threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        try:
            self.session = ort.InferenceSession(str(self.path),
                                                _session_options(n_threads, spinning),
                                                providers=["CPUExecutionProvider"])
        except Exception as e:  # onnxruntime raises its own (untyped) exceptions
            msg = str(e).splitlines()[0] if str(e) else type(e).__name__
            raise InputError(f"not a usable ONNX model: {msg}", path=self.path) from None
        meta = dict(self.session.get_modelmeta().custom_metadata_map)
        self.info = ModelInfo.from_metadata(meta, self.path)
        if input_scale is not None and input_scale != 1.0:
            if not 0.25 <= input_scale <= 8.0:
                raise ValueError(f"input scale {input_scale} is outside [0.25, 8]")
            q = self.info.output_scale
            self.info = dataclasses.replace(
                self.info, input_width=q * round(self.info.input_width * input_scale / q),
                input_height=q * round(self.info.input_height * input_scale / q))
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if len(inputs) != 1 or len(outputs) != 1:
            raise InputError(f"model has {len(inputs)} inputs and {len(outputs)} outputs, "
                             f"expected 1 and 1", path=self.path)
        ishape, oshape = inputs[0].shape, outputs[0].shape
        if len(ishape) != 4 or ishape[1] != 3:
            raise InputError(f"model input has shape {ishape}, expected (batch, 3, height, "
                             f"width)", path=self.path)
        if len(oshape) != 4 or oshape[1] != NUM_CHANNELS:
            raise InputError(f"model output has shape {oshape}, expected (batch, "
                             f"{NUM_CHANNELS}, height, width)", path=self.path)
        if any(isinstance(d, int) for d in (*ishape[2:], *oshape[2:])):
            raise InputError(f"model has a fixed image size {ishape[2:]}; turbinefit needs "
                             f"dynamic height and width", path=self.path)
        self._input = inputs[0].name
        self.flip = self.info.flip if flip is None else bool(flip)
        self.tip_shift = self.info.tip_shift_px if tip_shift is None else float(tip_shift)
        self.zoom = self.info.zoom if zoom is None else bool(zoom)
        self.refine = bool(refine)
        if not valid_tip_shift(self.tip_shift):
            raise ValueError(f"tip shift {self.tip_shift} px is outside "
                             f"(-{TIP_SHIFT_TAPER_PX:g}, {TIP_SHIFT_TAPER_PX:g})")
        # the resize's threads must not spin after a run: they would take the net's cores
        resize = default_model_path().with_name(RESIZE_MODEL)
        self._resize = ort.InferenceSession(str(resize), _session_options(n_threads, False),
                                            providers=["CPUExecutionProvider"])

    def _maps(self, image: NDArray[np.uint8], flip: bool,
              box: tuple[float, float, float, float] | None = None,
              shift: bool = True) -> F32Array:
        """Heat-maps (7, h, w) at the model's output size of one RGB uint8 photo, or of
        its part ``box`` (left, top, right, bottom; px, pixel edges) enlarged to the
        photo's model input size: flip-averaged if ``flip``, the tip channel moved out by
        :attr:`tip_shift` from this pass's own hub if ``shift`` (steps 1-3 of the module
        docstring)."""
        h, w = image.shape[:2]
        mw, mh = model_input_size(w, h, self.info)
        small = resize_image(image, mw, mh, box)
        views = [small, small[:, ::-1]] if flip else [small]  # padded after mirroring
        boxed = [letterbox(v, self.info) for v in views]
        batch = np.stack([b[0] for b in boxed])
        x = batch.transpose(0, 3, 1, 2).astype(np.float32) * np.float32(1.0 / 255.0)
        s = self.info.output_scale
        j0, i0 = boxed[0][1] // s, boxed[0][2] // s
        out = self.session.run(None, {self._input: x})[0][:, :, i0:i0 + mh // s, j0:j0 + mw // s]
        maps = np.ascontiguousarray(0.5 * (out[0] + out[1][:, :, ::-1]) if flip else out[0],
                                    dtype=np.float32)
        if self.tip_shift and shift:
            hub = np.unravel_index(int(np.argmax(maps[HUB])), maps[HUB].shape)
            if maps[HUB][hub] > self.info.threshold:
                maps[TIP] = shift_tips(maps[TIP], (float(hub[1]), float(hub[0])),
                                       self.tip_shift / s, TIP_SHIFT_TAPER_PX / s)
        return maps

    def zoom_box(self, maps: F32Array) -> tuple[float, float, float] | None:
        """(left, top, enlargement z) [heat-map px] of the test-time zoom of a photo
        whose maps (7, h, w) are ``maps``: the crop is ``w / z`` x ``h / z`` (the maps'
        own aspect), centred on the pixels above the model's threshold widened by
        :data:`ZOOM_MARGIN_PX`, clamped inside the maps; None when those are absent or
        too spread out to zoom at least :data:`ZOOM_MIN` times."""
        on = maps.max(axis=0) > self.info.threshold
        rows, cols = np.flatnonzero(on.any(axis=1)), np.flatnonzero(on.any(axis=0))
        if len(rows) == 0:
            return None
        h, w = on.shape
        m = ZOOM_MARGIN_PX / self.info.output_scale
        i0, i1, j0, j1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
        z = min(w / (j1 - j0 + 2 * m), h / (i1 - i0 + 2 * m), ZOOM_MAX)
        if z < ZOOM_MIN:
            return None
        left = min(max(0.5 * (j0 + j1 - w / z), 0.0), w - w / z)
        top = min(max(0.5 * (i0 + i1 - h / z), 0.0), h - h / z)
        return left, top, z

    def _zoom_tips(self, image: NDArray[np.uint8], maps: F32Array) -> None:
        """Step 4 of the module docstring: inside :meth:`zoom_box`, the tip channel of
        ``maps`` becomes, in place, the larger of its own value and that of a pass of the
        net on the enlarged crop (bilinear back to the maps' pixels)."""
        zb = self.zoom_box(maps)
        if zb is None:
            return
        left, top, z = zb
        h, w = maps.shape[1:]
        bw, bh = w / z, h / z
        sx, sy = image.shape[1] / w, image.shape[0] / h  # photo px per heat-map px
        # the crop, of the photo's aspect, at the photo's model input size: its maps are
        # (h, w) over the crop, z of them per heat-map pixel of the photo
        crop = self._maps(image, False, (left * sx, top * sy, (left + bw) * sx,
                                         (top + bh) * sy))[TIP]
        i0, j0 = int(top), int(left)
        i1, j1 = min(math.ceil(top + bh), h), min(math.ceil(left + bw), w)
        gi, gj = np.mgrid[i0:i1, j0:j1].astype(np.float32)
        v = (gi + np.float32(0.5 - top)) * np.float32(z) - np.float32(0.5)
        u = (gj + np.float32(0.5 - left)) * np.float32(z) - np.float32(0.5)
        inside = (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)
        box = maps[TIP, i0:i1, j0:j1]
        zv = ndimage.map_coordinates(crop, [v[inside], u[inside]], order=1, mode="nearest")
        box[inside] = np.maximum(box[inside], zv)

    def refine_zoom(self, width: int, height: int) -> int:
        """z: the crops of a ``width`` x ``height`` photo's refinement are ``1 / z`` of its
        size, read z times finer than the first pass (step 5 of the module docstring); 1 =
        not refined (:attr:`refine` off, or a photo under :data:`REFINE_MIN` times the
        model's input size)."""
        if not self.refine:
            return 1
        mw, mh = model_input_size(width, height, self.info)
        z = min(int(width // mw), int(height // mh), REFINE_MAX)
        return z if z >= REFINE_MIN else 1

    def _points(self, channel: F32Array, c: int) -> NDArray[np.float64]:
        """(n, 2) positions (u, v) [map px, sub-pixel] of the points a channel of
        :data:`REFINE_CHANNELS` detects: each 3 x 3 local maximum above the tip threshold
        for the tips, the maximum if above the threshold for the others."""
        if c == TIP:
            return peaks(channel, self.info.tip_threshold, 3)
        u, v, value = peak(channel)
        return np.array([(u, v)] if value > self.info.threshold else []).reshape(-1, 2)

    def _refine(self, image: NDArray[np.uint8], maps: F32Array) -> None:
        """Step 5 of the module docstring, in place: each point the first pass detects in
        :data:`REFINE_CHANNELS` is looked at again on a crop of the photo centred on it,
        at the photo's own resolution; its blob is moved, unchanged, to where the crop
        puts the point, when that is within :data:`REFINE_GATE` map px."""
        h, w = maps.shape[1:]
        H, W = image.shape[:2]
        z = self.refine_zoom(W, H)
        if z == 1:
            return
        bw, bh = W / z, H / z  # a crop [photo px]
        first = maps.copy()
        r = REFINE_RADIUS
        for c in REFINE_CHANNELS:
            for u, v in self._points(first[c], c):
                left = min(max((u + 0.5) * W / w - bw / 2, 0.0), W - bw)
                top = min(max((v + 0.5) * H / h - bh / 2, 0.0), H - bh)
                crop = self._maps(image, self.flip, (left, top, left + bw, top + bh),
                                  shift=False)[c]
                ch, cw = crop.shape
                found = self._points(crop, c)
                # crop map px -> photo px (edges) -> first-pass map px
                fu = (left + (found[:, 0] + 0.5) * bw / cw) * w / W - 0.5
                fv = (top + (found[:, 1] + 0.5) * bh / ch) * h / H - 0.5
                d = np.hypot(fu - u, fv - v)
                if len(d) == 0 or d.min() > REFINE_GATE:
                    continue
                k = int(np.argmin(d))
                i0, i1 = max(int(v) - r, 0), min(int(v) + r + 2, h)
                j0, j1 = max(int(u) - r, 0), min(int(u) + r + 2, w)
                a0, a1, b0, b1 = max(i0 - 2, 0), min(i1 + 2, h), max(j0 - 2, 0), min(j1 + 2, w)
                moved = ndimage.shift(first[c, a0:a1, b0:b1], (fv[k] - v, fu[k] - u), order=3,
                                      mode="nearest")  # cubic: the peak keeps its height
                maps[c, i0:i1, j0:j1] = np.clip(moved[i0 - a0:i1 - a0, j0 - b0:j1 - b0], 0, 1)

    def map_size(self, width: int, height: int) -> tuple[int, int]:
        """(width, height) of the maps the net makes for a ``width`` x ``height`` photo
        (:meth:`detect_small`: its model input size divided by ``output_scale``; 160 x
        120 for a 4:3 photo and the shipped model). Pixel ``(j, i)`` of these maps is
        photo pixel ``u = (j + 0.5) width / w - 0.5``, ``v = (i + 0.5) height / h - 0.5``
        (the photo's camera :meth:`~turbinefit.geometry.camera.PinholeCamera.resized` to
        them)."""
        mw, mh = model_input_size(width, height, self.info)
        s = self.info.output_scale
        return mw // s, mh // s

    @property
    def photo_width(self) -> int:
        """The widest a photo needs to be for this detector [px]: the model's input width,
        times :data:`ZOOM_MAX` with test-time zoom (its crops see the photo enlarged up
        to that) or :data:`REFINE_MAX` with ``refine``. Wider photos can be decoded at
        this width (:func:`turbinefit.io.images.read_image`'s ``reduce_to``) without
        losing anything the net sees but rounding."""
        return math.ceil(self.info.input_width * max(ZOOM_MAX if self.zoom else 1.0,
                                                     REFINE_MAX if self.refine else 1.0))

    def detect_small(self, image: NDArray[np.uint8]) -> F32Array:
        """Heat-maps (7, h, w) at the model's output size of one RGB uint8 photo (the
        input size divided by ``output_scale``): flip-averaged if :attr:`flip`, the tip
        channel moved out by :attr:`tip_shift`, small turbines' tips zoomed if
        :attr:`zoom`, refined coarse to fine if :attr:`refine` (steps 2-5 of the module
        docstring)."""
        maps = self._maps(image, self.flip)
        if self.zoom:
            self._zoom_tips(image, maps)
        if self.refine:
            self._refine(image, maps)
        return maps

    def detect(self, image: NDArray[np.uint8], size: tuple[int, int] | None = None) -> F32Array:
        """Heat-maps (7, H, W) float32 in [0, 1] of one RGB uint8 photo (H, W, 3).

        ``size`` = (width, height) of the output; default the photo's own size.
        """
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"expected an RGB uint8 (H, W, 3) image, got {image.dtype} "
                             f"{image.shape}")
        h, w = image.shape[:2]
        ow, oh = size or (w, h)
        small = self.detect_small(image)
        if (oh, ow) == small.shape[1:]:
            maps = small
        elif ow >= small.shape[2] and oh >= small.shape[1]:  # enlarge: onnxruntime
            sizes = np.array([1, NUM_CHANNELS, oh, ow], dtype=np.int64)
            maps = self._resize.run(None, {"x": small[None], "sizes": sizes})[0][0]
        else:  # shrink: antialiased
            maps = resize_maps(small, ow, oh)
        np.clip(maps, 0.0, 1.0, out=maps)
        return maps


class DetectorPool:
    """``workers`` :class:`HeatmapDetector` s of one model, each on one onnxruntime
    thread, detecting that many photos at once: the way to run many photos.

    On this 2-core machine, two single-threaded detectors working on two photos make
    68-70 photos/s at 320 x 240 (zoom on; docs/benchmarks.md), one detector
    on two threads 46-62: much of a photo's work (resizing, padding, the zoom's box and crop,
    the maps' mirror average) runs on one thread while the net's second thread waits.
    A detector's maps do not depend on how many threads it has, so the pool's maps are
    bit for bit those of one :class:`HeatmapDetector` of the same options.

    Args:
        model: ONNX file; None = the shipped model.
        workers: photos detected at once, each on one thread; None = one per core.
        options: how the detectors treat the model's maps (:class:`DetectOptions`;
            None = as the model's metadata says).

    Raises:
        InputError: as :class:`HeatmapDetector`.
    """

    def __init__(self, model: StrPath | None = None, workers: int | None = None,
                 options: DetectOptions | None = None) -> None:
        n = (os.cpu_count() or 1) if workers is None else int(workers)
        if n < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        #: The options the pool's detectors were made with.
        self.options = options or DetectOptions()
        self.detectors = [self.options.detector(model, 1) for _ in range(n)]

    @property
    def detector(self) -> HeatmapDetector:
        """The first of the pool's detectors: its model, metadata and options are all
        the pool's (for work of one photo at a time, or the settings in a report)."""
        return self.detectors[0]

    @property
    def workers(self) -> int:
        return len(self.detectors)

    def map(self, fn: Callable[[HeatmapDetector, T], R],
            items: Iterable[T]) -> Generator[R, None, None]:
        """``fn(detector, item)`` for each of ``items``, run on the pool's threads with
        a detector used by one call at a time, yielded in the order of ``items`` (at most
        twice :attr:`workers` items are worked on ahead of the one yielded).

        ``fn`` runs on another thread, so it should do all of one photo's work that can
        run there (decoding it, writing its outputs: most of it releases Python's lock)
        and return what the caller gathers in order. The first exception ``fn`` raises,
        in the order of ``items``, is raised here once the calls already running have
        ended; no call is started after it. With one worker, everything runs on the
        calling thread.
        """
        if len(self.detectors) == 1:
            for item in items:
                yield fn(self.detectors[0], item)
            return
        free: queue.SimpleQueue[HeatmapDetector] = queue.SimpleQueue()
        for d in self.detectors:
            free.put(d)

        def run(item: T) -> R:
            d = free.get()  # never waits: one thread per detector
            try:
                return fn(d, item)
            finally:
                free.put(d)

        pending: deque[Future[R]] = deque()
        with ThreadPoolExecutor(len(self.detectors),
                                thread_name_prefix="turbinefit-detect") as ex:
            try:
                for item in items:
                    pending.append(ex.submit(run, item))
                    if len(pending) >= 2 * len(self.detectors):
                        yield pending.popleft().result()
                while pending:
                    yield pending.popleft().result()
            finally:  # an error, or the caller stopped early: start nothing more
                for f in pending:
                    f.cancel()


def shift_tips(tip: F32Array, hub_uv: tuple[float, float], shift: float, taper: float
               ) -> F32Array:
    """The blade-tip channel (h, w) with its content moved ``shift`` px outward, radially
    from the hub at pixel ``hub_uv`` = (u, v) (inward if negative): a blob at distance r
    from the hub moves to r + shift, so each tip moves along its blade's image direction.
    Within ``taper`` px of the hub the displacement falls linearly to zero (r' = r (1 +
    shift / taper) there; continuous and one-to-one for ``|shift| < taper``).

    Cubic-spline resampling (bilinear would flatten a 1.5 px blob's peak by ~7 % at a
    half-pixel shift), clipped to [0, 1], over the box around the channel's values above
    0.01 (the rest, below that, is kept as it is: moving it would change it by less than
    that): a fraction of a millisecond for a 160 x 120 map.
    """
    out = tip.copy()
    if shift == 0:
        return out
    ii, jj = np.nonzero(tip > 1e-2)
    if len(ii) == 0:
        return out
    h, w = tip.shape
    m = math.ceil(abs(shift)) + 3
    i0, i1 = max(int(ii.min()) - m, 0), min(int(ii.max()) + m + 1, h)
    j0, j1 = max(int(jj.min()) - m, 0), min(int(jj.max()) + m + 1, w)
    ry, rx = np.mgrid[i0:i1, j0:j1].astype(np.float32)
    rx -= np.float32(hub_uv[0])
    ry -= np.float32(hub_uv[1])
    r = np.hypot(rx, ry)
    # the source of the pixel at r is at r - shift min(1, r / taper): a factor on (rx, ry)
    f = 1.0 - np.float32(shift) * np.minimum(np.float32(1.0 / taper), 1.0 / np.maximum(r, 1e-6))
    coords = np.stack([np.float32(hub_uv[1] - i0) + ry * f, np.float32(hub_uv[0] - j0) + rx * f])
    box = ndimage.map_coordinates(tip[i0:i1, j0:j1], coords, order=3, mode="constant", cval=0.0)
    out[i0:i1, j0:j1] = np.clip(box, 0.0, 1.0)
    return out


def overlay(image: NDArray[np.uint8], maps: F32Array) -> NDArray[np.uint8]:
    """The photo (H, W, 3), darkened, with heat-maps (7, h, w) blended in their
    :data:`CHANNEL_COLOURS`: the line channels first (each pixel in the colour of its
    strongest line channel), then the point channels over them.

    The blend is ``photo * m + a`` with a factor ``m`` and a colour ``a`` computed at the
    maps' pixels and enlarged to the photo's (bilinear, pixel centres aligned), so maps
    smaller than the photo cost their own size, not the photo's; at the photo's size it
    is the per-pixel blend itself."""
    h, w = maps.shape[1:]
    mult = np.full((h, w), 0.6, dtype=np.float32)
    add = np.zeros((3, h, w), dtype=np.float32)
    for chans in ((4, 5, 6), (0, 1, 2, 3)):
        sub = maps[list(chans)]
        alpha = np.clip(np.max(sub, axis=0), 0.0, 1.0)
        colour = CHANNEL_COLOURS[np.asarray(chans)[np.argmax(sub, axis=0)]].transpose(2, 0, 1)
        mult *= 1.0 - alpha
        add = add * (1.0 - alpha) + colour * alpha
    factors = resize_maps(np.concatenate([mult[None], add]), image.shape[1], image.shape[0])
    out = image.astype(np.float32) * factors[0][..., None] + factors[1:].transpose(1, 2, 0)
    return np.clip(out, 0, 255).astype(np.uint8)


def unique_stems(paths: Sequence[Path]) -> None:
    """Raise InputError if two images would write the same ``<stem>.npy``."""
    seen: dict[str, Path] = {}
    for p in paths:
        if p.stem in seen:
            raise InputError(f"two images share the name {p.stem!r} ({seen[p.stem]} and {p}); "
                             f"outputs are named by stem", path=p)
        seen[p.stem] = p
