"""Train the heat-map CNN on rendered photos (and optionally labelled real photos, real
photos labelled with boxes and turbine-free real photos).

:func:`train` renders (or reuses) a dataset (:mod:`turbinefit.sim.dataset`), trains
:class:`~turbinefit.train.net.HeatmapNet` with AdamW and a one-cycle learning rate,
evaluates on held-out renders after every epoch, checkpoints after every epoch (atomically;
an interrupted run resumes from its last checkpoint), calibrates the detection threshold
and exports ONNX (:mod:`turbinefit.train.export`).

Output folder::

    <out>/checkpoint.pt   model, optimiser, schedule, epoch, history (resume state)
    <out>/history.csv     one row per epoch: losses and held-out metrics
    <out>/model.onnx      the model for :class:`turbinefit.detect.HeatmapDetector`
    <out>/weights.npz     the weights as NumPy arrays (PyTorch-free; ``--init`` reads it)
    <out>/data/...        rendered datasets (unless ``--data`` points elsewhere)

Loss: binary cross-entropy between the sigmoid of the logits and the soft Gaussian targets,
each pixel weighted ``1 + pos_weight * target``; the per-pixel optimum stays at
prediction = target where the target is certain (the weight depends on the target only),
and the few pixels on the turbine count more than the many on the background. Where the
net is unsure, the weight inflates its answer (a pixel on the target with probability q
comes out above 0.5 once q > 1 / (1 + pos_weight)): the default 2 paints lines about as
wide as their targets, where 10 painted a third too much. ``channel_weights`` multiply
each channel's loss (both its positive and its background pixels, so each channel's
per-pixel optimum is unchanged): they only share the net's effort differently. The shipped
model's last fine-tunings weighted the tip channel 3, the nacelle 5 and the blade line 2.

Real photos with boxes (``boxes``) and turbine-free photos (``negatives``) have no
per-pixel targets: their loss is :func:`turbinefit.train.weak.weak_loss` (zero outside
each box grown by ``box_margin``, some line along each box), on ``real_batch`` of them
beside each step's ``batch`` renders, added to the renders' loss; photos the benchmark
holds out (:func:`turbinefit.eval.holdout.is_held_out` at ``hold_out``) are left out.

Augmentation: horizontal flips (a mirrored turbine is still a turbine) and mild
brightness / contrast / colour jitter; the renderer provides the rest of the variety.

Threads: one training process per machine is the best use of a small machine; a second
busy process on the cores PyTorch uses can slow it by an order of magnitude (measured
here: two threads with another process on the second core fell from 122 to 7 samples/s,
one thread held 56), so ``threads`` defaults to 1 while the data are rendered by the other
cores and may be raised on an otherwise idle machine.
"""

from __future__ import annotations

import csv
import io
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch.nn import functional as F
from tqdm import tqdm

from turbinefit.errors import InputError
from turbinefit.eval.detection import DetectionStats
from turbinefit.eval.holdout import HELD_OUT_FRACTION
from turbinefit.heatmaps import NUM_CHANNELS
from turbinefit.heatmaps.model_info import ModelInfo
from turbinefit.heatmaps.targets import TARGET_SIGMA_PX
from turbinefit.io.atomic import write_bytes_atomic, write_text_atomic
from turbinefit.sim.dataset import (
    CLOSEUP_FRACTION,
    IMAGE_SCALE,
    MODEL_HEIGHT,
    MODEL_WIDTH,
    Dataset,
    DatasetSpec,
    build_dataset,
    check_dataset_folder,
    read_spec,
)
from turbinefit.train.export import (
    OPSET,
    average_weights,
    averaging_partner,
    export_onnx,
    load_npz,
    save_npz,
)
from turbinefit.train.net import (
    STRIDE,
    WIDTHS,
    HeatmapNet,
    Widths,
    architecture,
    fine_width,
    num_parameters,
)
from turbinefit.train.weak import (
    WeakPhoto,
    WeakPhotos,
    attached_lines,
    load_weak_photos,
    weak_loss,
)

#: Seed offset of the held-out renders (independent of the training renders).
VAL_SEED_OFFSET = 1_000_003
#: Exported models ask for flip averaging (ModelInfo.flip), and their thresholds are
#: calibrated on flip-averaged maps (evaluate's default).
FLIP = True
#: Exported models ask for test-time zoom of small turbines' blade tips (ModelInfo.zoom,
#: step 4 of turbinefit.detect). Thresholds and tip shift are calibrated on the first
#: pass alone; on the shipped model the best-F1 tip threshold is the same with zoom.
ZOOM = True
#: TrainConfig fields that must match when a run is resumed from its checkpoint.
_RESUME_KEYS = ("n_images", "val_images", "epochs", "batch", "lr", "seed", "labels",
                "input_scale", "pos_weight", "channel_weights", "widths", "fine", "add_data",
                "closeup_fraction", "boxes", "boxes_images", "negatives", "hold_out",
                "real_batch", "box_margin", "mil_weight", "mil_strips", "zero_attached")


@dataclass
class TrainConfig:
    """Settings of :func:`train` (all but ``out_dir`` have defaults).

    Attributes:
        out_dir: output folder (see the module docstring).
        n_images: rendered training images.
        val_images: rendered held-out images.
        epochs: passes over the training set.
        batch: images per step.
        lr: peak learning rate (one-cycle).
        weight_decay: AdamW weight decay.
        pos_weight: extra weight of pixels on the turbine (see the module docstring).
        channel_weights: loss weight of each of the 7 channels, in the order of
            :data:`turbinefit.heatmaps.CHANNEL_NAMES` (see the module docstring).
        seed: seed of the renders and of the training order.
        threads: PyTorch threads.
        workers: processes rendering the dataset (default: all cores).
        data_dir: where datasets are rendered / reused (default ``out_dir/data``).
        add_data: finished training sets rendered before (dataset folders such as
            ``OTHER/data/train-n16384-s9-x2``, of this data version and input scale) to
            train on together with this run's: more renders without rendering them again.
        labels: COCO keypoint file of real labelled photos to train on as well.
        images_dir: folder the COCO file's ``file_name`` are relative to.
        init: ``weights.npz`` to start from (fine-tuning); default for ``labels`` is the
            shipped model's weights.
        max_steps: stop after this many steps in all (tests); None = no limit.
        input_scale: the net's input photos are this many times its 160 x 120 heat-maps
            (2: 320 x 240 photos, the shipped model; 1: 160 x 120). ``init`` weights of
            input scale 1 are lifted to 2 (:func:`~turbinefit.train.net.lift_to_input_scale_2`);
            fine-tuning the shipped model on labels keeps its scale.
        widths: channel widths of the net at 1/2, 1/4, 1/8 and 1/16 of the heat-map
            resolution (:data:`~turbinefit.train.net.WIDTHS` by default); ``init``
            weights of a narrower net are widened first
            (:func:`~turbinefit.train.net.widen`: the wider net starts out computing the
            same heat-maps). None: those of ``init`` (or the default).
        fine: channels of the net's fine branch at heat-map resolution (input scale 2
            only; 0: none); ``init`` weights without one get one that starts out adding
            nothing (:func:`~turbinefit.train.net.add_fine`). None: as ``init`` (or 0).
        closeup_fraction: share of the rendered training and validation views that are
            close-ups of one blade or the tower (:class:`~turbinefit.sim.dataset.DatasetSpec`).
        boxes: box files (CSV or COCO, :mod:`turbinefit.io.regions`) of real photos to
            train on with the weak losses (:mod:`turbinefit.train.weak`).
        boxes_images: folder the box files' photos are in.
        negatives: folders of turbine-free real photos (every channel zero).
        hold_out: photos :func:`~turbinefit.eval.holdout.is_held_out` at this fraction are
            left out of ``boxes`` and ``negatives`` (0: none).
        real_batch: real photos of ``boxes`` and ``negatives`` per step, beside ``batch``
            renders.
        box_margin: a box is grown by this share of its size on each side (at least
            :data:`~turbinefit.train.weak.MIN_MARGIN_PX` map px) before the outside is zero.
        mil_weight: weight of the multiple-instance term (some line in each strip of a box).
        mil_strips: strips each box is cut into across its long side.
        zero_attached: also zero the starting net's lines that run into a box from
            outside it (by default they are unknown:
            :func:`~turbinefit.train.weak.attached_lines`).
        average_with: ``weights.npz`` of a net of the same architecture (typically the
            one fine-tuned from) that the trained weights are averaged with before they
            are calibrated and exported (:func:`~turbinefit.train.export.average_weights`;
            the checkpoint keeps the trained weights).
        average_weight: the trained weights' share of that average.
        tip_threshold: the blade tips' threshold, instead of the one of the best F1 on
            the validation renders (the tip shift is still measured at the best F1's).
    """

    out_dir: Path
    n_images: int = 20000
    val_images: int = 400
    epochs: int = 10
    batch: int = 16
    lr: float = 2e-3
    weight_decay: float = 1e-4
    pos_weight: float = 2.0
    channel_weights: tuple[float, ...] = (1.0,) * NUM_CHANNELS
    seed: int = 0
    threads: int = 1
    workers: int | None = None
    data_dir: Path | None = None
    add_data: tuple[Path, ...] = ()
    labels: Path | None = None
    images_dir: Path | None = None
    init: Path | None = None
    max_steps: int | None = None
    input_scale: int = IMAGE_SCALE
    widths: Widths | None = None
    fine: int | None = None
    closeup_fraction: float = CLOSEUP_FRACTION
    boxes: tuple[Path, ...] = ()
    boxes_images: Path | None = None
    negatives: tuple[Path, ...] = ()
    hold_out: float = HELD_OUT_FRACTION
    real_batch: int = 8
    box_margin: float = 0.1
    mil_weight: float = 0.05
    mil_strips: int = 3
    zero_attached: bool = False
    average_with: Path | None = None
    average_weight: float = 0.5
    tip_threshold: float | None = None

    def __post_init__(self) -> None:
        for name in ("n_images", "epochs", "batch", "threads"):
            if getattr(self, name) < 1:
                raise InputError(f"must be at least 1, got {getattr(self, name)}", field=name)
        if self.val_images < 0:
            raise InputError(f"must be >= 0, got {self.val_images}", field="val_images")
        if not (self.lr > 0 and math.isfinite(self.lr)):
            raise InputError(f"must be positive, got {self.lr}", field="lr")
        if not (self.pos_weight >= 0 and math.isfinite(self.pos_weight)):
            raise InputError(f"must be >= 0, got {self.pos_weight}", field="pos_weight")
        if self.input_scale not in (1, 2):
            raise InputError(f"must be 1 or 2, got {self.input_scale}", field="input_scale")
        if self.widths is not None and (len(self.widths) != 4
                                        or not all(w >= 1 for w in self.widths)):
            raise InputError(f"must be 4 channel counts >= 1, got {self.widths}",
                             field="widths")
        if self.fine is not None and self.fine < 0:
            raise InputError(f"must be >= 0, got {self.fine}", field="fine")
        if self.fine and self.input_scale != 2:
            raise InputError("a fine branch needs input scale 2", field="fine")
        cw = self.channel_weights
        if len(cw) != NUM_CHANNELS or not all(w >= 0 and math.isfinite(w) for w in cw) \
                or not any(w > 0 for w in cw):
            raise InputError(f"must be {NUM_CHANNELS} weights >= 0, not all 0, got "
                             f"{','.join(str(w) for w in cw)}", field="channel_weights")
        if (self.labels is None) != (self.images_dir is None):
            raise InputError("--labels and --images-dir go together", field="labels")
        if bool(self.boxes) != (self.boxes_images is not None):
            raise InputError("--boxes and --boxes-images go together", field="boxes")
        for name in ("real_batch", "mil_strips"):
            if getattr(self, name) < 1:
                raise InputError(f"must be at least 1, got {getattr(self, name)}", field=name)
        for name in ("hold_out", "box_margin"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise InputError(f"must be in [0, 1], got {getattr(self, name)}", field=name)
        if not (self.mil_weight >= 0 and math.isfinite(self.mil_weight)):
            raise InputError(f"must be >= 0, got {self.mil_weight}", field="mil_weight")


class _Arrays(torch.utils.data.Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """Images + uint8 targets as tensors (optionally flipped at random)."""

    def __init__(self, images: NDArray[np.uint8], targets: NDArray[np.uint8],
                 augment: bool) -> None:
        self.images, self.targets, self.augment = images, targets, augment

    def __len__(self) -> int:
        return len(self.images)

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        img = np.array(self.images[i])  # a copy: memory maps are read-only
        tgt = np.array(self.targets[i])
        if self.augment and torch.rand(()) < 0.5:
            img, tgt = img[:, ::-1], tgt[:, :, ::-1]
        x = torch.from_numpy(np.ascontiguousarray(img.transpose(2, 0, 1))).float() / 255.0
        y = torch.from_numpy(np.ascontiguousarray(tgt)).float() / 255.0
        return x, y


def _jitter(x: torch.Tensor) -> torch.Tensor:
    """Per-image brightness, contrast and colour jitter of a batch (B, 3, H, W) in [0, 1]."""
    b = x.shape[0]
    gain = 1.0 + 0.25 * (torch.rand(b, 1, 1, 1) - 0.5)
    colour = 1.0 + 0.1 * (torch.rand(b, 3, 1, 1) - 0.5)
    mean = x.mean(dim=(1, 2, 3), keepdim=True)
    contrast = 1.0 + 0.3 * (torch.rand(b, 1, 1, 1) - 0.5)
    return ((x - mean) * contrast + mean).mul(gain * colour).clamp(0.0, 1.0)


def forward(net: HeatmapNet, x: torch.Tensor) -> torch.Tensor:
    """Logits (B, 7, H / s, W / s) of images (B, 3, H, W), s = ``net.input_scale`` (H and W
    multiples of s; the input is padded to the net's stride by edge replication)."""
    s = net.input_scale
    h, w = x.shape[-2:]
    ph, pw = (-h) % (STRIDE * s), (-w) % (STRIDE * s)
    if ph or pw:
        x = F.pad(x, (0, pw, 0, ph), mode="replicate")
    return net(x.contiguous(memory_format=torch.channels_last))[..., :h // s, :w // s]


def heatmap_loss(logits: torch.Tensor, target: torch.Tensor, pos_weight: float,
                 channel_weights: tuple[float, ...] | None = None) -> torch.Tensor:
    """Target- and channel-weighted binary cross-entropy (see the module docstring)."""
    w = 1.0 + pos_weight * target
    if channel_weights is not None:
        w = w * torch.tensor(channel_weights, dtype=w.dtype).view(1, -1, 1, 1)
    return (F.binary_cross_entropy_with_logits(logits, target, reduction="none") * w).mean()


@dataclass
class EpochRecord:
    epoch: int
    train_loss: float
    val_loss: float
    samples_per_s: float
    metrics: dict[str, float]


def evaluate(net: HeatmapNet, images: NDArray[np.uint8], targets: NDArray[np.uint8],
             points: NDArray[np.floating], visible: NDArray[np.bool_], pos_weight: float,
             thresholds: tuple[float, ...] = (0.3,), batch: int = 32,
             tip_threshold: float | None = None, flip: bool = FLIP
             ) -> tuple[float, dict[float, dict[str, float]]]:
    """Held-out loss and :class:`DetectionStats` summaries, one per threshold (tips at
    the same threshold unless ``tip_threshold``), of the maps as
    :class:`~turbinefit.detect.HeatmapDetector` makes them: with ``flip``, the mean of the
    maps of each image and of its mirror image mirrored back (the loss is of the image's
    own maps). Distances are in pixels of the heat-map grid, except ``tip_shift_px``:
    pixels of the net's input, as
    :attr:`~turbinefit.heatmaps.model_info.ModelInfo.tip_shift_px` (calibrated with the
    input-pixel radius and blade length of :class:`DetectionStats`)."""
    net.eval()
    scale = net.input_scale
    dflt = DetectionStats()
    stats = {t: DetectionStats(threshold=t, tip_threshold=tip_threshold,
                               shift_match_px=dflt.shift_match_px / scale,
                               shift_min_blade_px=dflt.shift_min_blade_px / scale)
             for t in thresholds}
    total, n = 0.0, 0
    with torch.no_grad():
        for k in range(0, len(images), batch):
            x = torch.from_numpy(np.array(images[k:k + batch]).transpose(0, 3, 1, 2).copy())
            y = torch.from_numpy(np.array(targets[k:k + batch])).float() / 255.0
            xf = x.float() / 255.0
            logits = forward(net, xf)
            total += float(heatmap_loss(logits, y, pos_weight)) * len(x)
            n += len(x)
            prob = torch.sigmoid(logits)
            if flip:
                prob = 0.5 * (prob + torch.sigmoid(forward(net, xf.flip(-1))).flip(-1))
            pred = prob.numpy()
            tgt = y.numpy()
            for j in range(len(x)):
                for s in stats.values():
                    s.add(pred[j], tgt[j], points[k + j], visible[k + j])
    net.train()
    out = {t: s.summary() for t, s in stats.items()}
    for m in out.values():
        m["tip_shift_px"] *= scale
    return total / max(n, 1), out


def calibrate_thresholds(summaries: dict[float, dict[str, float]], max_false: float = 0.05
                         ) -> tuple[float, float]:
    """(point threshold, tip threshold) from summaries at a grid of thresholds.

    Points: the lowest threshold at which no point channel peaks above it in more than
    ``max_false`` of the images where its point is out of view. Tips: the threshold of the
    best F1 of recall and precision.
    """
    point = max(summaries)
    for t in sorted(summaries):
        s = summaries[t]
        worst = max((s[f"{p}_false_peak"] for p in ("base", "tower_top", "hub")
                     if not math.isnan(s[f"{p}_false_peak"])), default=0.0)
        if worst <= max_false:
            point = t
            break

    def f1(t: float) -> float:
        r, p = summaries[t]["tips_recall"], summaries[t]["tips_precision"]
        return 0.0 if math.isnan(r) or math.isnan(p) or r + p == 0 else 2 * r * p / (r + p)

    tip = max(sorted(summaries), key=f1)
    return point, tip


def _save_checkpoint(path: Path, state: dict[str, Any]) -> None:
    buf = io.BytesIO()
    torch.save(state, buf)
    write_bytes_atomic(path, buf.getvalue())


def _write_history(path: Path, history: list[EpochRecord]) -> None:
    keys = sorted({k for r in history for k in r.metrics})
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["epoch", "train_loss", "val_loss", "samples_per_s", *keys])
    for r in history:
        w.writerow([r.epoch, f"{r.train_loss:.5f}", f"{r.val_loss:.5f}", f"{r.samples_per_s:.1f}",
                    *(f"{r.metrics.get(k, float('nan')):.4f}" for k in keys)])
    write_text_atomic(path, out.getvalue())


def _calibrated_metrics(net: HeatmapNet, val: Dataset, pos_weight: float,
                        grid: tuple[float, ...], tip_threshold: float | None = None
                        ) -> tuple[float, dict[str, float], tuple[float, float, float]]:
    """Held-out loss, metrics at the calibrated thresholds, and those thresholds with the
    tip shift (:attr:`~turbinefit.heatmaps.model_info.ModelInfo.tip_shift_px`). The tip
    threshold is the one of the best F1, or ``tip_threshold`` if given (the grid's
    nearest); the tip shift is always measured at the best F1's (on the benchmark flights,
    the shift measured at a lower threshold made the fits' model points 4 % worse)."""
    loss, summaries = evaluate(net, val.images, val.targets, val.points, val.visible,
                               pos_weight, grid)
    point, best = calibrate_thresholds(summaries)
    tip = best if tip_threshold is None else min(summaries, key=lambda t: abs(t - tip_threshold))
    tips = summaries[tip]
    shift = summaries[best]["tip_shift_px"]  # always where recall and precision balance best
    metrics = dict(summaries[point], tips_recall=tips["tips_recall"],
                   tips_precision=tips["tips_precision"], tip_shift_px=shift,
                   threshold=point, tip_threshold=tip)
    return loss, metrics, (point, tip, shift)


def format_metrics(m: dict[str, float]) -> str:
    return (f"hub {m['hub_median_px']:.2f}px top {m['tower_top_median_px']:.2f}px "
            f"base {m['base_median_px']:.2f}px | tips R {m['tips_recall']:.2f} "
            f"P {m['tips_precision']:.2f} | IoU tower {m['iou_tower']:.2f} "
            f"nacelle {m['iou_nacelle']:.2f} blade {m['iou_blade']:.2f} | thresholds "
            f"{m.get('threshold', float('nan')):.2f} / tips {m.get('tip_threshold', float('nan')):.2f}")


@dataclass
class TrainResult:
    out_dir: Path
    model: Path
    history: list[EpochRecord]
    threshold: float
    parameters: int


def _config_dict(cfg: TrainConfig) -> dict[str, Any]:
    d = asdict(cfg)
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in d.items()}


def _labelled_arrays(cfg: TrainConfig, scale: int) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    from turbinefit.io.coco import read_coco_keypoints
    from turbinefit.train.labels import labelled_sample

    assert cfg.labels is not None and cfg.images_dir is not None
    labelled = read_coco_keypoints(cfg.labels, cfg.images_dir)
    if not labelled:
        raise InputError("no images in the label file", path=cfg.labels)
    imgs, tgts = zip(*(labelled_sample(li, MODEL_WIDTH, MODEL_HEIGHT, TARGET_SIGMA_PX, scale)
                       for li in labelled), strict=True)
    return np.stack(imgs), np.stack(tgts)


def _added_dataset(folder: Path, main: tuple[Path, DatasetSpec]) -> Dataset:
    """An ``add_data`` folder: a finished training set of the same kind as this run's
    (data version, image size and scale, target width), not this run's own folder."""
    spec = read_spec(folder)
    like = main[1]
    if replace(spec, n_images=like.n_images, seed=like.seed) != like:
        raise InputError(f"holds renders of another kind ({spec}); this run trains on data "
                         f"version {like.version} at input scale {like.image_scale}",
                         path=folder)
    if folder.resolve() == main[0].resolve():
        raise InputError("is this run's own training set; give other renders", path=folder)
    ds = Dataset(folder)
    if not ds.complete:
        raise InputError(f"is unfinished ({int(ds.done.sum())} of {len(ds)} images rendered); "
                         "finish it with the train command that started it", path=folder)
    return ds


def _photo_maps(net: HeatmapNet, views: WeakPhotos
                ) -> Callable[[NDArray[np.uint8]], NDArray[np.float32]]:
    """The maps (7, h, w) ``net`` makes of a whole photo, letterboxed as
    :class:`~turbinefit.train.weak.WeakPhotos` letterboxes it, cut to the photo."""
    s = net.input_scale

    def maps(image: NDArray[np.uint8]) -> NDArray[np.float32]:
        canvas, _, (a0, b0, a1, b1) = views.view(WeakPhoto(image, (), ""), True, np.zeros(3))
        x = torch.from_numpy(np.ascontiguousarray(canvas.transpose(2, 0, 1)))[None]
        net.eval()
        with torch.no_grad():
            prob = torch.sigmoid(forward(net, x.float() / 255.0))[0].numpy()
        net.train()
        return prob[:, int(b0) // s:int(b1) // s, int(a0) // s:int(a1) // s]
    return maps


def _endless(data: WeakPhotos, batch: int, seed: int
             ) -> Iterator[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
    """Batches of ``data`` in shuffled passes, without end."""
    g = torch.Generator().manual_seed(seed)
    while True:
        yield from torch.utils.data.DataLoader(data, batch_size=batch, shuffle=True,
                                               drop_last=len(data) >= batch, generator=g,
                                               num_workers=0)


def train(cfg: TrainConfig, progress: bool = True,
          log: Callable[[str], None] = print) -> TrainResult:
    """Train (or resume training) as ``cfg`` says; see the module docstring."""
    out = Path(cfg.out_dir)
    ckpt_path = out / "checkpoint.pt"
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)

    # Everything that can be wrong with the inputs is checked before anything is written.
    init = cfg.init
    if init is None and (cfg.labels is not None or cfg.boxes or cfg.negatives):
        from turbinefit.detect import default_model_path
        init = default_model_path().with_suffix(".npz")
    net = (load_npz(Path(init), None if cfg.init is None else cfg.input_scale, cfg.widths,
                    cfg.fine)
           if init is not None
           else HeatmapNet(cfg.widths or WIDTHS, input_scale=cfg.input_scale,
                           fine=cfg.fine or 0))
    net = net.to(memory_format=torch.channels_last)  # type: ignore[call-overload]
    scale = net.input_scale
    # the same architecture, or refused now, not at the end
    partner = None if cfg.average_with is None else averaging_partner(cfg.average_with, net)
    labelled: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None = None
    if cfg.labels is not None:
        labelled = _labelled_arrays(cfg, scale)
        log(f"{len(labelled[0])} labelled photos from {cfg.labels}")
    weak: WeakPhotos | None = None
    if cfg.boxes or cfg.negatives:
        photos, left_out = load_weak_photos(cfg.boxes, cfg.boxes_images, cfg.negatives,
                                            cfg.hold_out)
        if not photos:
            raise InputError("no photos left to train on after the held-out part",
                             field="boxes" if cfg.boxes else "negatives")
        weak = WeakPhotos(photos, (MODEL_WIDTH * scale, MODEL_HEIGHT * scale), scale,
                          cfg.box_margin, cfg.mil_strips)
        if not cfg.zero_attached:
            weak.photos = attached_lines(photos, _photo_maps(net, weak), cfg.box_margin)
        n_boxed = sum(1 for p in photos if p.boxes)
        log(f"{n_boxed} real photos with boxes, {len(photos) - n_boxed} turbine-free; "
            f"{left_out} held out (turbinefit.eval.holdout, fraction {cfg.hold_out:g})")
    resume: dict[str, Any] | None = None
    if ckpt_path.exists():
        try:
            resume = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        except Exception as e:
            raise InputError(f"cannot read checkpoint: {e}", path=ckpt_path) from None
        assert resume is not None
        # a field a checkpoint predates had its default then
        old = {**_config_dict(TrainConfig(out_dir=out)), **resume["config"]}
        for k in _RESUME_KEYS:
            if str(old.get(k)) != str(_config_dict(cfg).get(k)):
                raise InputError(f"checkpoint was trained with {k}={old.get(k)}, not "
                                 f"{_config_dict(cfg).get(k)}; use another --out to start anew",
                                 path=ckpt_path)

    data_dir = cfg.data_dir or (out / "data")
    datasets = [(data_dir / f"train-n{cfg.n_images}-s{cfg.seed}-x{scale}",
                 DatasetSpec(cfg.n_images, cfg.seed, image_scale=scale,
                             closeup_fraction=cfg.closeup_fraction))]
    if cfg.val_images:
        datasets.append((data_dir / f"val-n{cfg.val_images}-s{cfg.seed}-x{scale}",
                         DatasetSpec(cfg.val_images, cfg.seed + VAL_SEED_OFFSET,
                                     image_scale=scale,
                                     closeup_fraction=cfg.closeup_fraction)))
    for folder, spec in datasets:  # a folder of another spec: refused before any writing
        check_dataset_folder(folder, spec)
    extra = [_added_dataset(Path(f), datasets[0]) for f in cfg.add_data]
    out.mkdir(parents=True, exist_ok=True)
    rendered, *vals = (build_dataset(folder, spec, cfg.workers, progress)
                       for folder, spec in datasets)
    val: Dataset | None = vals[0] if vals else None
    parts: list[_Arrays] = [_Arrays(d.images, d.targets, augment=True)
                            for d in (rendered, *extra)]
    if labelled is not None:
        parts.append(_Arrays(labelled[0], labelled[1], augment=True))
    train_set: torch.utils.data.ConcatDataset[tuple[torch.Tensor, torch.Tensor]] = (
        torch.utils.data.ConcatDataset(parts))

    steps_per_epoch = max(1, len(train_set) // cfg.batch)
    total_steps = steps_per_epoch * cfg.epochs
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=total_steps,
                                                pct_start=0.1 if init is None else 0.02)
    history: list[EpochRecord] = []
    start_epoch = 0
    if resume is not None:
        net.load_state_dict(resume["model"])
        opt.load_state_dict(resume["optimizer"])
        sched.load_state_dict(resume["scheduler"])
        history = [EpochRecord(**r) for r in resume["history"]]
        start_epoch = int(resume["epoch"])
        torch.set_rng_state(resume["torch_rng"])
        log(f"resuming from {ckpt_path} after epoch {start_epoch}")
    log(f"net: {num_parameters(net):,} parameters; {len(train_set)} training images, "
        f"{len(val) if val else 0} held-out; {cfg.epochs} epochs of {steps_per_epoch} steps")

    steps_done = start_epoch * steps_per_epoch
    grid = tuple(np.round(np.arange(0.1, 0.95, 0.05), 2).tolist())
    for epoch in range(start_epoch, cfg.epochs):
        if cfg.max_steps is not None and steps_done >= cfg.max_steps:
            break
        g = torch.Generator().manual_seed(cfg.seed * 1000 + epoch)
        loader = torch.utils.data.DataLoader(train_set, batch_size=cfg.batch, shuffle=True,
                                             drop_last=True, generator=g, num_workers=0)
        real = None if weak is None else _endless(weak, cfg.real_batch, cfg.seed * 1000 + epoch)
        net.train()
        t0 = time.perf_counter()
        seen, loss_sum = 0, 0.0
        out_sum, mil_sum, peak_sum = 0.0, 0.0, 0.0
        bar = tqdm(loader, total=steps_per_epoch, desc=f"epoch {epoch + 1}/{cfg.epochs}",
                   unit="step", disable=not progress, leave=False)
        for x, y in bar:
            if real is None:
                logits = forward(net, _jitter(x))
                loss = heatmap_loss(logits, y, cfg.pos_weight, cfg.channel_weights)
            else:  # renders and real photos in one pass
                xr, known, strips = next(real)
                logits = forward(net, _jitter(torch.cat([x, xr])))
                loss = heatmap_loss(logits[:len(x)], y, cfg.pos_weight, cfg.channel_weights)
                wl, o, m, pk = weak_loss(logits[len(x):], known, strips,
                                         cfg.channel_weights, cfg.mil_weight)
                loss = loss + wl
                out_sum, mil_sum = out_sum + o * len(x), mil_sum + m * len(x)
                peak_sum += pk * len(x)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
            seen += len(x)
            loss_sum += float(loss.detach()) * len(x)
            steps_done += 1
            bar.set_postfix(loss=f"{loss_sum / seen:.4f}",
                            img_s=f"{seen / (time.perf_counter() - t0):.0f}")
            if cfg.max_steps is not None and steps_done >= cfg.max_steps:
                break
        bar.close()
        rate = seen / max(time.perf_counter() - t0, 1e-9)
        metrics: dict[str, float] = {}
        val_loss = float("nan")
        if val is not None:
            val_loss, metrics, _ = _calibrated_metrics(net, val, cfg.pos_weight, grid)
        if real is not None:
            metrics.update(real_outside_loss=out_sum / max(seen, 1),
                           real_mil_loss=mil_sum / max(seen, 1),
                           real_peak_loss=peak_sum / max(seen, 1))
        rec = EpochRecord(epoch + 1, loss_sum / max(seen, 1), val_loss, rate, metrics)
        history.append(rec)
        log(f"epoch {epoch + 1}/{cfg.epochs}: loss {rec.train_loss:.4f} held-out "
            f"{val_loss:.4f} ({rate:.0f} img/s)"
            + (f" | {format_metrics(metrics)}" if metrics else ""))
        _save_checkpoint(ckpt_path, {
            "model": net.state_dict(), "optimizer": opt.state_dict(),
            "scheduler": sched.state_dict(), "epoch": epoch + 1,
            "history": [asdict(r) for r in history], "config": _config_dict(cfg),
            "torch_rng": torch.get_rng_state()})
        _write_history(out / "history.csv", history)

    # Thresholds of the final weights (again if a finished run is run again: re-export).
    if partner is not None:
        average_weights(net, partner, cfg.average_weight)
        log(f"weights averaged with {cfg.average_with} ({cfg.average_weight:g} of the "
            "trained ones)")
    threshold = tip_threshold = 0.3 if cfg.tip_threshold is None else cfg.tip_threshold
    tip_shift = 0.0
    if val is not None:
        _, final, (threshold, tip_threshold, tip_shift) = _calibrated_metrics(
            net, val, cfg.pos_weight, grid, cfg.tip_threshold)
        log(f"held-out, final: {format_metrics(final)}")
    state = net.state_dict()
    fine = fine_width(state)
    averaged = ("" if cfg.average_with is None
                else f", averaged with {cfg.average_with.name} ({cfg.average_weight:g})")
    desc = (f"HeatmapNet widths {architecture(state)[0]}"
            f"{f', fine {fine}' if fine else ''}, {num_parameters(net)} params; "
            f"{cfg.n_images} renders seed {cfg.seed}"
            f"{', labels ' + str(cfg.labels) if cfg.labels else ''}"
            f"{', boxes ' + ' '.join(p.name for p in cfg.boxes) if cfg.boxes else ''}"
            f"{', negatives ' + ' '.join(p.name for p in cfg.negatives) if cfg.negatives else ''}"
            f"; {len(history)} epochs"
            f"{' from ' + Path(init).name if init is not None else ''}"
            f"{averaged}")
    info = ModelInfo(input_width=MODEL_WIDTH * scale, input_height=MODEL_HEIGHT * scale,
                     stride=STRIDE * scale, output_scale=scale,
                     sigma_px=TARGET_SIGMA_PX * scale, threshold=threshold,
                     tip_threshold=tip_threshold, flip=FLIP,
                     tip_shift_px=round(tip_shift, 3), zoom=ZOOM, opset=OPSET,
                     description=desc)
    model_path = export_onnx(net, out / "model.onnx", info)
    save_npz(net, out / "weights.npz")
    return TrainResult(out, model_path, history, threshold, num_parameters(net))

