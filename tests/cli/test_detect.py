"""``turbinefit detect``: heat-maps of photos and folders with the shipped model and its
options, and bad input (photos, models, folders)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from support import one_line_error

from turbinefit.cli import main
from turbinefit.detect import HeatmapDetector
from turbinefit.io.images import read_image, write_png

onnx = pytest.importorskip("onnx")

#: The shipped net's maps of a 4:3 photo.
NET = (160, 120)


#: float16 files hold the maps to within this (values in [0, 1]).
HALF = 2.5e-4


def test_detect_cli(tmp_path: Path, held_out_samples: list, detector: HeatmapDetector,
                    capsys: pytest.CaptureFixture[str]) -> None:
    photos = tmp_path / "photos"
    photos.mkdir()
    for k, s in enumerate(held_out_samples[:3]):
        write_png(photos / f"img{k}.png", s.image)
    from PIL import Image

    Image.fromarray(held_out_samples[3].image).save(photos / "img3.jpg", quality=90)
    out = tmp_path / "det"
    assert main(["detect", str(photos), "--out", str(out), "--quiet", "--threads", "1"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted([f"img{k}.{e}" for k in range(4) for e in ("npy", "png")])
    maps = np.load(out / "img0.npy")  # at the net's resolution: half the 320 x 240 photo
    assert maps.shape == (7, 120, 160) and maps.dtype == np.float16  # half the bytes
    assert np.load(out / "img3.npy").shape == (7, 120, 160)
    assert read_image(out / "img0.png").shape == (240, 320, 3)
    # again without --overwrite: refused; with it: replaced
    assert main(["detect", str(photos), "--out", str(out), "--quiet"]) == 2
    assert main(["detect", str(photos / "img0.png"), "--out", str(out), "--quiet",
                 "--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["img0.npy", "img0.png"]
    # --no-flip: the net once per photo, as HeatmapDetector(flip=False); by default the
    # shipped model's metadata asks for flip averaging, which gives other maps
    plain = tmp_path / "plain"
    assert main(["detect", str(photos / "img0.png"), "--out", str(plain), "--quiet",
                 "--no-flip"]) == 0
    img = read_image(photos / "img0.png")
    assert detector.flip
    np.testing.assert_allclose(np.load(plain / "img0.npy"),
                               HeatmapDetector(threads=1, flip=False).detect(img, NET),
                               atol=HALF)
    np.testing.assert_allclose(np.load(out / "img0.npy"), detector.detect(img, NET), atol=HALF)
    assert np.abs(np.load(plain / "img0.npy") - np.load(out / "img0.npy")).max() > 1e-3
    # --tip-shift 0: the net's own tip channel, as HeatmapDetector(tip_shift=0)
    own = tmp_path / "own"
    assert main(["detect", str(photos / "img0.png"), "--out", str(own), "--quiet",
                 "--tip-shift", "0"]) == 0
    np.testing.assert_allclose(np.load(own / "img0.npy"),
                               HeatmapDetector(threads=1, tip_shift=0).detect(img, NET),
                               atol=HALF)
    assert np.abs(np.load(own / "img0.npy")[3] - np.load(out / "img0.npy")[3]).max() > 1e-3
    # --no-zoom: no second pass on small turbines, as HeatmapDetector(zoom=False); a far
    # view (a render shrunk to half size amid its own sky) is zoomed by default
    from turbinefit.io.images import resize_image

    unzoomed = HeatmapDetector(threads=1, zoom=False)
    fars = [np.pad(resize_image(s.image, 160, 120), ((60, 60), (80, 80), (0, 0)), mode="edge")
            for s in held_out_samples]
    # the first whose turbine alone answers (a pylon or neighbour in view spreads the box)
    far = next(f for f in fars if detector.zoom_box(unzoomed.detect_small(f)) is not None)
    assert detector.zoom
    write_png(photos / "far.png", far)
    for flag, det in (([], detector), (["--no-zoom"], unzoomed)):
        d = tmp_path / f"far{len(flag)}"
        assert main(["detect", str(photos / "far.png"), "--out", str(d), "--quiet",
                     *flag]) == 0
        np.testing.assert_allclose(np.load(d / "far.npy"), det.detect(far, NET), atol=HALF)
    assert np.abs(np.load(tmp_path / "far0" / "far.npy")[3]
                  - np.load(tmp_path / "far1" / "far.npy")[3]).max() > 1e-3


def _tiny_model(path: Path, out_channels: int = 7, opset: int = 17,
                meta: dict[str, str] | None = None, fixed: bool = False) -> Path:
    from onnx import TensorProto, helper, numpy_helper

    w = numpy_helper.from_array(np.zeros((out_channels, 3, 1, 1), np.float32), "w")
    dims = [1, 3, 128, 160] if fixed else ["b", 3, "h", "w"]
    odims = [1, out_channels, 128, 160] if fixed else ["b", out_channels, "h", "w"]
    graph = helper.make_graph(
        [helper.make_node("Conv", ["image", "w"], ["c"]), helper.make_node("Sigmoid", ["c"], ["y"])],
        "g", [helper.make_tensor_value_info("image", TensorProto.FLOAT, dims)],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, odims)], [w])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)])
    model.ir_version = 8
    for key, value in (meta or {}).items():
        e = model.metadata_props.add()
        e.key, e.value = key, value
    path.write_bytes(model.SerializeToString())
    return path


def test_detect_bad_input(tmp_path: Path, held_out_samples: list, capsys: pytest.CaptureFixture[str]) -> None:
    good = tmp_path / "good.png"
    write_png(good, held_out_samples[0].image)
    out = tmp_path / "out"
    # a non-image file, a truncated PNG
    (tmp_path / "notes.png").write_text("hello")
    assert main(["detect", str(good), str(tmp_path / "notes.png"), "--out", str(out)]) == 2
    one_line_error(capsys, "notes.png", "not an image")
    assert not out.exists()
    trunc = tmp_path / "trunc.png"
    trunc.write_bytes(good.read_bytes()[:200])
    assert main(["detect", str(trunc), "--out", str(out)]) == 2
    one_line_error(capsys, "trunc.png")
    assert not out.exists()
    # found by a worker of the pool amid good photos: the same one error, nothing written
    for k in range(3):
        shutil.copy(good, tmp_path / f"good{k}.png")
    assert main(["detect", *(str(tmp_path / f"good{k}.png") for k in range(3)), str(trunc),
                 "--out", str(out), "--threads", "2"]) == 2
    one_line_error(capsys, "trunc.png")
    assert not out.exists()
    # an empty folder, a missing file
    (tmp_path / "empty").mkdir()
    assert main(["detect", str(tmp_path / "empty"), "--out", str(out)]) == 2
    one_line_error(capsys, "empty", "no image files")
    assert main(["detect", str(tmp_path / "nope.jpg"), "--out", str(out)]) == 2
    one_line_error(capsys, "nope.jpg")
    # two photos with the same stem
    (tmp_path / "b").mkdir()
    shutil.copy(good, tmp_path / "b" / "good.png")
    assert main(["detect", str(good), str(tmp_path / "b"), "--out", str(out)]) == 2
    one_line_error(capsys, "share the name")
    # models: not ONNX, wrong output shape, unsupported opset (file and metadata), a
    # metadata flag that is not one, fixed size
    (tmp_path / "junk.onnx").write_bytes(b"\x00\x01junk")
    cases = {
        "junk.onnx": "not a usable ONNX model",
        _tiny_model(tmp_path / "c5.onnx", out_channels=5).name: "output has shape",
        _tiny_model(tmp_path / "op99.onnx", opset=99).name: "not a usable ONNX model",
        _tiny_model(tmp_path / "meta.onnx", meta={"turbinefit.opset": "99"}).name: "opset 99",
        _tiny_model(tmp_path / "flip.onnx", meta={"turbinefit.flip": "yes"}).name:
            "turbinefit.flip='yes' is not a valid flag",
        _tiny_model(tmp_path / "fixed.onnx", fixed=True).name: "fixed image size",
        _tiny_model(tmp_path / "shift.onnx", meta={"turbinefit.tip_shift_px": "25"}).name:
            "out of range",
        _tiny_model(tmp_path / "shiftx.onnx", meta={"turbinefit.tip_shift_px": "far"}).name:
            "turbinefit.tip_shift_px='far' is not a valid float",
        "missing.onnx": "model file not found",
    }
    for name, words in cases.items():
        assert main(["detect", str(good), "--out", str(out), "--model", str(tmp_path / name)]) == 2
        one_line_error(capsys, name, words)
        assert not out.exists()
    # the tiny 7-channel model is a valid (if useless) model
    assert main(["detect", str(good), "--out", str(out), "--quiet",
                 "--model", str(_tiny_model(tmp_path / "ok.onnx"))]) == 0


def test_detect_large_jpeg_writes_small_maps_at_the_full_size_peaks(
        tmp_path: Path, held_out_samples: list, detector: HeatmapDetector) -> None:
    from PIL import Image

    from turbinefit.io.images import resize_image

    W, H = 2000, 1500
    sample = next(s for s in held_out_samples if s.in_sight[:3].all())  # base, top, hub
    big = resize_image(sample.image, W, H)
    Image.fromarray(big).save(tmp_path / "big.jpg", quality=92)
    out = tmp_path / "det"
    assert main(["detect", str(tmp_path / "big.jpg"), "--out", str(out), "--quiet",
                 "--threads", "1"]) == 0
    maps = np.load(out / "big.npy")
    assert maps.shape == (7, 120, 160)
    assert read_image(out / "big.png").shape == (480, 640, 3)  # the overlay, 640 wide
    # the full-size maps of the fully decoded photo: their peaks are the small maps' peaks
    # mapped to the photo, u = (j + 0.5) W / w - 0.5, to within the scale (12.5 px)
    full = detector.detect(read_image(tmp_path / "big.jpg"))
    assert full.shape == (7, H, W)
    sx, sy = W / 160, H / 120
    for c in range(3):  # base, tower top, hub
        assert maps[c].max() > 0.5
        i, j = np.unravel_index(np.argmax(maps[c]), maps[c].shape)
        fi, fj = np.unravel_index(np.argmax(full[c]), full[c].shape)
        assert abs((j + 0.5) * sx - 0.5 - fj) <= sx and abs((i + 0.5) * sy - 0.5 - fi) <= sy
    # --max-size: wider maps of the same photo
    assert main(["detect", str(tmp_path / "big.jpg"), "--out", str(tmp_path / "wide"),
                 "--quiet", "--max-size", "400"]) == 0
    assert np.load(tmp_path / "wide" / "big.npy").shape == (7, 300, 400)
    # --refine: maps of the same size, the first pass's except near its own responses
    assert main(["detect", str(tmp_path / "big.jpg"), "--out", str(tmp_path / "fine"),
                 "--quiet", "--threads", "1", "--refine"]) == 0
    fine = np.load(tmp_path / "fine" / "big.npy")
    assert fine.shape == maps.shape and np.isfinite(fine).all()
    assert not np.array_equal(fine, maps)
    # the base and the lines are the first pass's (of the photo decoded at 1280 px, not 640)
    assert np.abs(fine[[0, 4, 5, 6]] - maps[[0, 4, 5, 6]]).max() < 0.1
