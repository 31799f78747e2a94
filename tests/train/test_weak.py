"""Training from boxes and turbine-free photos (turbinefit.train.weak): the losses, the
views, the held-out photos left out, a few steps of the trainer.

Needs the optional extra ``turbinefit[train]``; skipped without PyTorch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")
from turbinefit.eval.holdout import is_held_out  # noqa: E402
from turbinefit.eval.regions import LINE_CHANNELS  # noqa: E402
from turbinefit.io.images import write_png  # noqa: E402
from turbinefit.train.weak import (  # noqa: E402
    MIN_MARGIN_PX,
    WeakPhoto,
    WeakPhotos,
    attached_lines,
    load_weak_photos,
    weak_loss,
)

torch.set_num_threads(1)
H, W = 12, 16  # a small map


def _known_box(x0: int, y0: int, x1: int, y1: int) -> torch.Tensor:
    known = torch.ones(1, 1, H, W)
    known[..., y0:y1, x0:x1] = 0.0
    return known


def test_zero_maps_cost_nothing_outside_and_anything_else_costs() -> None:
    known = _known_box(4, 2, 10, 9)
    strips = torch.full((1, 1, 4), -1, dtype=torch.long)
    zero = torch.full((1, 7, H, W), -30.0)
    loss, outside, mil, peak = weak_loss(zero, known, strips)
    assert float(loss) < 1e-10 and outside < 1e-10 and mil == 0.0 and peak < 1e-10
    lit = zero.clone()
    lit[0, 4, 0, 0] = 3.0  # a line outside the box
    assert float(weak_loss(lit, known, strips)[0]) > 1e-6
    point = zero.clone()
    point[0, 2, 11, 15] = 3.0  # a point outside the box
    assert float(weak_loss(point, known, strips)[0]) > 1e-6


def test_nothing_inside_the_box_is_punished() -> None:
    """Inside the grown box (unknown) no pixel of any channel is pushed down, and without
    a strip none is pushed at all."""
    known = _known_box(4, 2, 10, 9)
    torch.manual_seed(0)
    logits = torch.randn(1, 7, H, W).requires_grad_(True)
    strips = torch.full((1, 1, 4), -1, dtype=torch.long)
    (g,) = torch.autograd.grad(weak_loss(logits, known, strips)[0], logits)
    assert float(g[..., 2:9, 4:10].abs().max()) == 0.0
    assert float(g[..., 0, 0].min()) > 0.0  # outside: pushed down
    strips = torch.tensor([[[5, 3, 9, 8]]])
    (g,) = torch.autograd.grad(weak_loss(logits, known, strips)[0], logits)
    inside = g[0, :, 2:9, 4:10]
    assert float(inside.max()) <= 0.0  # at most pushed up
    assert int((inside < 0).sum()) == 1  # one pixel: the strip's largest line logit
    c, i, j = (int(v) for v in torch.nonzero(inside < 0)[0])
    assert c in LINE_CHANNELS
    line = logits.detach()[0, list(LINE_CHANNELS), 3:8, 5:9].amax(dim=0)
    assert float(logits.detach()[0, c, 2 + i, 4 + j]) == float(line.max())


def test_the_multiple_instance_term_rewards_line_inside_the_box() -> None:
    known = _known_box(4, 2, 10, 9)
    strips = torch.tensor([[[4, 2, 7, 9], [7, 2, 10, 9]]])
    empty = torch.full((1, 7, H, W), -5.0)
    one_strip = empty.clone()
    one_strip[0, 6, 5, 5] = 4.0  # a blade line in the first strip only
    both = one_strip.clone()
    both[0, 4, 5, 8] = 4.0  # and a tower line in the second
    losses = [weak_loss(m, known, strips, mil_weight=1.0) for m in (empty, one_strip, both)]
    assert losses[0][2] > losses[1][2] > losses[2][2]
    assert losses[0][3] == losses[1][3] == losses[2][3]  # nothing changed outside
    assert float(losses[2][0]) < float(losses[1][0]) < float(losses[0][0])
    # points inside the box do not count as line
    points = empty.clone()
    points[0, :4, 5, 5] = 4.0
    assert weak_loss(points, known, strips)[2] == pytest.approx(losses[0][2])


def test_a_single_peak_outside_is_punished_beyond_its_pixel_share() -> None:
    """The negative bag: one false peak among zeros costs far more than its 1 / (h w)
    share of the per-pixel term, and the gradient goes to that peak alone."""
    known = _known_box(4, 2, 10, 9)
    strips = torch.full((1, 1, 4), -1, dtype=torch.long)
    logits = torch.full((1, 7, H, W), -8.0)
    logits[0, 4, 0, 0] = 1.0
    logits.requires_grad_(True)
    loss, outside, _, peak = weak_loss(logits, known, strips, mil_weight=1.0)
    assert peak > 10 * outside
    (g,) = torch.autograd.grad(loss, logits)
    assert float(g[0, 4, 0, 0]) > 100 * float(g[0, 4, 11, 15])


def test_channel_weights_weigh_the_outside() -> None:
    known = torch.ones(1, 1, H, W)
    strips = torch.full((1, 1, 4), -1, dtype=torch.long)
    logits = torch.zeros(1, 7, H, W)
    base = float(weak_loss(logits, known, strips)[0])
    doubled = float(weak_loss(logits, known, strips, (2.0,) * 7)[0])
    assert doubled == pytest.approx(2 * base)


def _photo(w: int = 200, h: int = 200) -> np.ndarray:
    rng = np.random.default_rng(1)
    return rng.integers(0, 255, (h, w, 3), dtype=np.uint8)


def test_views_zero_outside_the_grown_box_and_ask_for_line_inside() -> None:
    box = (60.0, 20.0, 100.0, 180.0)  # a tall box in a 200 x 200 photo
    ds = WeakPhotos([WeakPhoto(_photo(), (box,), "a.jpg")], (320, 240), 2, margin=0.1,
                    strips=3)
    photo = ds.photos[0]
    canvas, xform, area = ds.view(photo, True, np.zeros(3))
    assert canvas.shape == (240, 320, 3)
    assert area == (40, 0, 280, 240)  # the square photo letterboxed into 4:3
    known, strips = ds.targets(photo, xform, area)
    # the box in map px: x 56..80, y 12..108 (photo px x 0.6, + the 20 px margin), grown
    # by 10 % of its size: x 53.6..82.4
    assert known[:, :20].sum() == 0 and known[:, 141:].sum() == 0  # reflected margins
    assert known[60, 30] == 1 and known[60, 100] == 1  # outside the grown box
    assert 0.1 * 24 > MIN_MARGIN_PX
    assert known[60, 53] == 1 and known[60, 54] == 0 and known[60, 81] == 0
    assert known[60, 82] == 1 and known[60, 60] == 0
    ok = strips[strips[:, 0] >= 0]
    assert len(ok) == 3  # three strips down the box's long (vertical) side
    assert (ok[:, 0] == 56).all() and (ok[:, 2] == 80).all()
    assert ok[0, 1] == 12 and ok[-1, 3] == 108 and (ok[1:, 1] == ok[:-1, 3]).all()
    # a negative photo is known (zero) everywhere, its margins too, and asks nothing
    neg = WeakPhoto(_photo(), (), "n.jpg")
    known, strips = ds.targets(neg, *ds.view(neg, True, np.zeros(3))[1:])
    assert known.all() and (strips == -1).all()


def test_a_box_mostly_out_of_the_view_asks_for_nothing() -> None:
    box = (0.0, 0.0, 30.0, 30.0)  # the top-left corner of a 200 x 200 photo
    ds = WeakPhotos([WeakPhoto(_photo(), (box,), "a.jpg")], (320, 240), 2)
    photo = ds.photos[0]
    # the smallest window at the bottom-right corner: the box is not in it
    _, xform, area = ds.view(photo, False, np.array([0.0, 1.0 - 1e-9, 1.0 - 1e-9]))
    known, strips = ds.targets(photo, xform, area)
    assert known.all() and (strips == -1).all()


def test_mirrored_items_keep_strips_in_the_unknown_part() -> None:
    box = (20.0, 60.0, 90.0, 110.0)
    ds = WeakPhotos([WeakPhoto(_photo(), (box,), "a.jpg")], (320, 240), 2)
    torch.manual_seed(0)
    for _ in range(12):
        x, known, strips = ds[0]
        assert x.shape == (3, 240, 320) and known.shape == (1, 120, 160)
        for x0, y0, x1, y1 in strips.tolist():
            if x0 >= 0:
                assert 0 <= x0 < x1 <= 160 and 0 <= y0 < y1 <= 120
                assert float(known[0, y0:y1, x0:x1].max()) == 0.0


def test_lines_running_into_a_box_are_left_unknown() -> None:
    photo = WeakPhoto(_photo(), ((80.0, 20.0, 120.0, 100.0),), "a.jpg")

    def maps(_: np.ndarray) -> np.ndarray:
        m = np.zeros((7, 100, 100), dtype=np.float32)  # a 100 x 100 grid over the photo
        m[4, 45:95, 50] = 0.9  # a tower line running down from inside the box
        m[6, 10:90, 5] = 0.9  # a line far from it (a road)
        return m

    (out,) = attached_lines([photo], maps, margin=0.1)
    assert out.attached is not None
    assert out.attached[45:95, 50].all() and not out.attached[10:90, 5].any()
    ds = WeakPhotos([out], (320, 240), 2)
    known, _ = ds.targets(out, *ds.view(out, True, np.zeros(3))[1:])
    # the tower's bottom (photo y 180, x 100) is unknown, the road (x 10) is zero
    assert known[int((180 * 1.2) / 2), int((100 * 1.2 + 40) / 2)] == 0
    assert known[60, int((10 * 1.2 + 40) / 2)] == 1


def test_false_colour_keeps_the_shape_and_spans_the_palette() -> None:
    from turbinefit.train.weak import THERMAL_PALETTES, false_colour

    ramp = np.repeat(np.linspace(0, 255, 64, dtype=np.uint8)[None, :, None], 3, axis=2)
    outs = [false_colour(ramp, (k + 0.5) / (2 * len(THERMAL_PALETTES)))
            for k in range(2 * len(THERMAL_PALETTES))]
    for out in outs:
        assert out.shape == ramp.shape and out.dtype == np.uint8
        assert (out[0, 0] != out[0, -1]).any()
    n = len(THERMAL_PALETTES)
    assert (outs[0][0, 0] == outs[n][0, -1]).all()  # the second half reverses the scale


def _names(n: int, held: bool) -> list[str]:
    return [f"P_{k:04d}.png" for k in range(400) if is_held_out(f"P_{k:04d}.png") == held][:n]


def test_held_out_photos_and_their_copies_are_left_out(tmp_path: Path) -> None:
    img = tmp_path / "images"
    (img / "turbine").mkdir(parents=True)
    neg = tmp_path / "neg"
    neg.mkdir()
    train, held = _names(2, False), _names(2, True)
    rows = []
    for name in train + held:
        for file in (name, "transformed" + name):
            write_png(img / "turbine" / file, _photo(64, 48))
            rows.append(f"{file},64,48,turbine,10,5,30,40\n")
    for name in _names(4, False)[2:] + _names(3, True)[2:]:
        write_png(neg / name, _photo(64, 48))
    (tmp_path / "boxes.csv").write_text("".join(rows))
    photos, left_out = load_weak_photos([tmp_path / "boxes.csv"], img, [neg], 0.4)
    assert sorted(p.name for p in photos if p.boxes) == sorted(
        train + ["transformed" + n for n in train])
    assert len([p for p in photos if not p.boxes]) == 2
    assert left_out == 5
    assert photos[0].boxes[0] == (10.0, 5.0, 30.0, 40.0)
    everything, none = load_weak_photos([tmp_path / "boxes.csv"], img, [neg], 0.0)
    assert len(everything) == 11 and none == 0


def test_training_with_boxes_and_negatives_runs(tmp_path: Path) -> None:
    from turbinefit.train.trainer import TrainConfig, train

    img = tmp_path / "images"
    img.mkdir()
    names = _names(3, False)
    for name in names:
        write_png(img / name, _photo(160, 120))
    (tmp_path / "boxes.csv").write_text(
        "".join(f"{n},160,120,turbine,50,10,110,118\n" for n in names[:2]))
    neg = tmp_path / "neg"
    neg.mkdir()
    write_png(neg / names[2], _photo(160, 120))
    logs: list[str] = []
    cfg = TrainConfig(out_dir=tmp_path / "out", data_dir=tmp_path / "data", n_images=4,
                      val_images=2, epochs=1, batch=2, real_batch=2, max_steps=2, workers=1,
                      boxes=(tmp_path / "boxes.csv",), boxes_images=img, negatives=(neg,))
    res = train(cfg, progress=False, log=logs.append)
    assert res.model.is_file()
    assert any("2 real photos with boxes, 1 turbine-free" in line for line in logs)
    hist = (tmp_path / "out" / "history.csv").read_text()
    assert "real_mil_loss" in hist and "real_outside_loss" in hist


def test_averaged_weights_are_the_mean_and_other_nets_are_refused(tmp_path: Path) -> None:
    """``train --average-with``: the exported weights are the stated mix of the trained ones
    (the checkpoint's) and the other net's; a net of another architecture is refused before
    any training."""
    import torch

    from turbinefit.errors import InputError
    from turbinefit.train.export import load_npz, save_npz
    from turbinefit.train.net import HeatmapNet
    from turbinefit.train.trainer import TrainConfig, train

    other = tmp_path / "other.npz"
    torch.manual_seed(3)
    save_npz(HeatmapNet((8, 8, 8, 8), input_scale=1), other)
    cfg = TrainConfig(out_dir=tmp_path / "out", data_dir=tmp_path / "data", n_images=4,
                      val_images=2, epochs=1, batch=2, max_steps=1, workers=1,
                      widths=(8, 8, 8, 8), input_scale=1, average_with=other,
                      average_weight=0.25, tip_threshold=0.4)
    res = train(cfg, progress=False, log=lambda _: None)
    trained = torch.load(tmp_path / "out" / "checkpoint.pt", map_location="cpu",
                         weights_only=False)["model"]
    mixed = load_npz(tmp_path / "out" / "weights.npz").state_dict()
    theirs = load_npz(other).state_dict()
    for k, v in mixed.items():
        if v.is_floating_point():
            want = 0.25 * trained[k].double() + 0.75 * theirs[k].double()
            assert torch.allclose(v.double(), want, atol=1e-6), k
    assert any(not torch.allclose(v.double(), trained[k].double())
               for k, v in mixed.items() if v.is_floating_point())
    from turbinefit.detect import HeatmapDetector

    assert HeatmapDetector(res.model).info.tip_threshold == pytest.approx(0.4)

    wider = tmp_path / "wider.npz"
    save_npz(HeatmapNet((8, 8, 8, 16), input_scale=1), wider)
    bad = TrainConfig(out_dir=tmp_path / "out2", data_dir=tmp_path / "data", n_images=4,
                      val_images=2, epochs=1, batch=2, max_steps=1, workers=1,
                      widths=(8, 8, 8, 8), input_scale=1, average_with=wider)
    with pytest.raises(InputError, match="same architecture"):
        train(bad, progress=False, log=lambda _: None)
    assert not (tmp_path / "out2" / "model.onnx").exists()
