"""Inference (turbinefit.detect, onnxruntime): the shipped model on rendered photos, photo
sizes, tip shifts, zoom, the detector pool."""

from __future__ import annotations

import sys
import threading

import numpy as np
import pytest

from turbinefit.detect import (
    REFINE_CHANNELS,
    REFINE_GATE,
    REFINE_RADIUS,
    TIP,
    ZOOM_MAX,
    DetectOptions,
    DetectorPool,
    HeatmapDetector,
    default_model_path,
    letterbox,
    model_input_size,
    shift_tips,
)
from turbinefit.eval.detection import local_maxima, peak, refine
from turbinefit.heatmaps.model_info import TIP_SHIFT_TAPER_PX, ModelInfo


def test_shipped_model_is_in_the_package() -> None:
    p = default_model_path()
    assert p.is_file() and p.stat().st_size < 8e6
    assert p.with_suffix(".npz").is_file()


def test_shipped_model_finds_the_hub(detector: HeatmapDetector, held_out_samples: list) -> None:
    errs = []
    for s in held_out_samples:
        maps = detector.detect(s.image)
        assert maps.shape == (7, 240, 320) and maps.dtype == np.float32
        assert np.isfinite(maps).all() and maps.min() >= 0 and maps.max() <= 1
        u, v, _ = peak(maps[2])
        hub = (s.points[2] + 0.5) * 2 - 0.5  # points are in 160 x 120 target pixels
        errs.append(np.hypot(u - hub[0], v - hub[1]))
    assert np.median(errs) < 3.0, errs  # [px at 320 x 240]


def test_input_scale_runs_the_net_larger_and_finds_the_same_hub(
        held_out_samples: list) -> None:
    """At twice its input size the net makes maps twice as large (320 x 240 of a 4:3 photo)
    whose hub lies where the 1x maps' hub does, in photo pixels."""
    one = HeatmapDetector(threads=1, zoom=False)
    two = DetectOptions(zoom=False, input_scale=2.0).detector(threads=1)
    assert two.info.input_width == 640 and two.map_size(1280, 960) == (320, 240)
    assert two.photo_width == 640
    errs = []
    for s in held_out_samples[:3]:
        small, large = one.detect_small(s.image), two.detect_small(s.image)
        assert large.shape == (7, 240, 320)
        (u1, v1, _), (u2, v2, _) = peak(small[2]), peak(large[2])
        errs.append(np.hypot(2 * u1 + 0.5 - u2, 2 * v1 + 0.5 - v2))  # at 320 px
    assert np.median(errs) < 3.0, errs
    with pytest.raises(ValueError, match="input scale 20"):
        HeatmapDetector(threads=1, input_scale=20)


def test_shipped_model_sees_320_px_photos(detector: HeatmapDetector) -> None:
    info = detector.info
    assert (info.input_width, info.output_scale, info.stride) == (320, 2, 32)
    assert model_input_size(4000, 3000, info) == (320, 240)
    assert model_input_size(3000, 2000, info) == (320, 214)  # 3:2, height even


def test_model_input_size_keeps_the_aspect_and_the_output_scale() -> None:
    one = ModelInfo(input_width=160)
    two = ModelInfo(input_width=320, input_height=240, stride=32, output_scale=2)
    assert model_input_size(4000, 3000, one) == (160, 120)
    assert model_input_size(3000, 2000, one) == (160, 107)
    assert model_input_size(4000, 3000, two) == (320, 240)
    assert model_input_size(3000, 2000, two) == (320, 214)  # height a multiple of 2
    assert model_input_size(4000, 10, two) == (320, 2)
    # taller than 4:3: as high as the input (letterboxed into it)
    assert model_input_size(1024, 1024, two) == (240, 240)
    assert model_input_size(3000, 4000, two) == (180, 240)
    assert model_input_size(1024, 1024, one) == (120, 120)


def test_letterbox_centres_the_photo_in_the_4_3_input() -> None:
    info = ModelInfo(input_width=320, input_height=240, stride=32, output_scale=2)
    photo = np.random.default_rng(0).integers(0, 255, (240, 320, 3), dtype=np.uint8)
    x, left, top = letterbox(photo, info)  # a 4:3 photo: only padded to the stride
    assert (left, top) == (0, 0) and x.shape == (256, 320, 3)
    assert np.array_equal(x[:240], photo) and np.array_equal(x[240:], np.repeat(photo[-1:], 16, 0))
    square = photo[:, :240]
    x, left, top = letterbox(square, info)
    assert (left, top) == (40, 0) and x.shape == (256, 320, 3)
    assert np.array_equal(x[:240, 40:280], square)
    assert np.array_equal(x[:240, 39], square[:, 1])  # reflected, not repeated
    wide = photo[:180]
    x, left, top = letterbox(wide, info)
    assert (left, top) == (0, 30) and np.array_equal(x[30:210], wide)


@pytest.mark.parametrize("size", [(160, 160), (160, 106), (160, 90), (120, 160)])
def test_maps_of_any_shape_have_no_border_artefact(detector: HeatmapDetector,
                                                   size: tuple[int, int]) -> None:
    """Renders that are square, 3:2, 16:9 and portrait: the line channels answer on the
    turbine (most of their mass on its lines) and not along the bottom edge (a square
    photo fed at its own shape had the bottom rows answer at 8x the whole map's mean)."""
    from scipy import ndimage

    from turbinefit.eval.regions import bottom_rows, line_mass_inside
    from turbinefit.sim.dataset import DatasetSpec, render_sample

    w, h = size
    spec = DatasetSpec(3, seed=777, width=w, height=h)
    inside, bottom, whole = [], [], []
    for k in range(3):
        s = render_sample(spec, k)
        maps = detector.detect(s.image, (w, h))
        assert maps.shape == (7, h, w)
        region = ndimage.binary_dilation(s.target[4:].max(axis=0) > 0.05, iterations=2)
        inside.append(line_mass_inside(maps, region))
        b, a = bottom_rows(maps, max(1, round(h / 25)))
        bottom.append(b)
        whole.append(a)
    assert np.mean(inside) > 0.85
    assert np.mean(bottom) < 2.0 * np.mean(whole)


def test_detect_output_has_the_photo_size(detector: HeatmapDetector, held_out_samples: list) -> None:
    """A 2x photo gives 2x heat-maps whose hub peak lands at 2x the position."""
    s = held_out_samples[0]
    big = np.repeat(np.repeat(s.image, 2, axis=0), 2, axis=1)
    small = detector.detect(s.image)
    maps = detector.detect(big)
    assert maps.shape == (7, 480, 640)
    u1, v1, _ = peak(small[2])
    u2, v2, _ = peak(maps[2])
    assert abs((u2 + 0.5) / 2 - 0.5 - u1) < 1.0 and abs((v2 + 0.5) / 2 - 0.5 - v1) < 1.0
    assert detector.detect(np.zeros((37, 301, 3), np.uint8)).shape == (7, 37, 301)
    assert detector.detect_small(s.image).shape == (7, 120, 160)


def test_maps_are_resized_as_pillow_resizes_them(detector: HeatmapDetector,
                                                held_out_samples: list) -> None:
    """Enlarging on onnxruntime (the shipped resize graph) gives Pillow's bilinear maps;
    shrinking (a photo narrower than the heat-maps) and mixed sizes use Pillow itself."""
    from turbinefit.heatmaps.resize import resize_maps

    small = detector.detect_small(held_out_samples[1].image)
    for w, h in ((320, 240), (640, 480), (401, 133), (100, 75), (200, 90)):
        got = detector.detect(held_out_samples[1].image, size=(w, h))
        want = np.clip(resize_maps(small, w, h), 0.0, 1.0)
        assert got.shape == (7, h, w) and got.dtype == np.float32
        np.testing.assert_allclose(got, want, atol=1e-5)  # float32 rounding
    # the comparison can fail: nearest-neighbour enlargement is not what detect gives
    near = np.repeat(np.repeat(small, 2, axis=1), 2, axis=2)
    assert float(np.abs(detector.detect(held_out_samples[1].image) - near).max()) > 0.01


def test_shift_tips_moves_each_blob_along_its_blade() -> None:
    from turbinefit.heatmaps.targets import render_keypoint_heatmaps

    hub = np.array([60.0, 50.0])
    dirs = np.array([[0.0, -1.0], [0.8, 0.6], [-0.6, 0.8]])
    tips = hub + 30.3 * dirs
    uv = np.concatenate([np.zeros((2, 2)), hub[None], tips])
    tip = render_keypoint_heatmaps(120, 160, [uv], [np.array([False] * 3 + [True] * 3)],
                                   sigma_px=1.5)[3].astype(np.float32)
    for shift in (0.7, -0.4):
        out = shift_tips(tip, (hub[0], hub[1]), shift, 10.0)
        assert out.dtype == np.float32 and out.min() >= 0 and out.max() <= 1
        for t, d in zip(tips, dirs, strict=True):
            win = np.zeros_like(out)
            i, j = int(np.rint(t[1])), int(np.rint(t[0]))
            win[i - 4:i + 5, j - 4:j + 5] = out[i - 4:i + 5, j - 4:j + 5]
            u, v, val = peak(win)
            np.testing.assert_allclose([u, v], t + shift * d, atol=0.03)
            assert val > 0.95  # cubic resampling keeps the peak
    np.testing.assert_array_equal(shift_tips(tip, (60.0, 50.0), 0.0, 10.0), tip)
    # a blob on the hub stays there (the shift tapers to 0 at the hub)
    blob = render_keypoint_heatmaps(120, 160, [np.tile(hub, (6, 1))],
                                    [np.array([False] * 3 + [True] + [False] * 2)],
                                    sigma_px=1.5)[3].astype(np.float32)
    u, v, _ = peak(shift_tips(blob, (60.0, 50.0), 0.7, 10.0))
    assert abs(u - 60.0) < 0.01 and abs(v - 50.0) < 0.01
    assert shift_tips(np.zeros((8, 8), np.float32), (4.0, 4.0), 0.7, 10.0).max() == 0.0


def test_detector_shifts_the_tip_channel_by_the_calibrated_amount(
        detector: HeatmapDetector, held_out_samples: list) -> None:
    info = detector.info
    assert detector.tip_shift == info.tip_shift_px and 0 < info.tip_shift_px < 2
    shifted = HeatmapDetector(threads=1, zoom=False)
    plain = HeatmapDetector(threads=1, tip_shift=0, zoom=False)
    for s in held_out_samples[:3]:
        a, b = shifted.detect_small(s.image), plain.detect_small(s.image)
        others = [0, 1, 2, 4, 5, 6]
        np.testing.assert_array_equal(a[others], b[others])
        i, j = np.unravel_index(int(np.argmax(b[2])), b[2].shape)
        want = shift_tips(b[3], (float(j), float(i)), info.tip_shift_px / info.output_scale,
                          TIP_SHIFT_TAPER_PX / info.output_scale)
        np.testing.assert_allclose(a[3], want, atol=1e-6)
        assert np.abs(a[3] - b[3]).max() > 1e-3
    with pytest.raises(ValueError, match="tip shift"):
        HeatmapDetector(threads=1, tip_shift=TIP_SHIFT_TAPER_PX)


class _PoolNet:
    """A stand-in for an output-scale-2 net that sees red dots: its blade channel is the
    input's red channel, 2x2 mean-pooled; its tip channel is 1 where that is above 0.75,
    i.e. it finds a tip only where the dot fills a heat-map pixel."""

    def run(self, _: object, feeds: dict) -> list:
        x = next(iter(feeds.values()))
        n, _, h, w = x.shape
        out = np.zeros((n, 7, h // 2, w // 2), np.float32)
        out[:, 6] = x[:, 0].reshape(n, h // 2, 2, w // 2, 2).mean(axis=(2, 4))
        out[:, TIP] = out[:, 6] > 0.75
        return [out]


@pytest.mark.parametrize("size", [(320, 240), (800, 600)])
def test_zoom_finds_small_tips_again_where_they_are(size: tuple[int, int]) -> None:
    w, h = size
    dets = {z: DetectOptions(flip=False, tip_shift=0, zoom=z).detector(threads=1)
            for z in (False, True)}
    for d in dets.values():
        d.session = _PoolNet()  # type: ignore[assignment]
    img = np.zeros((h, w, 3), np.uint8)
    img[:, :, 1] = 90  # a green sky: no channel but the tip sees it
    k = w / 320  # photo px per input px
    # a red dot of 2 x 3 input px, astride two heat-map pixels: 0.5 in the first pass
    x0, y0, dw, dh = round(151 * k), round(97 * k), round(2 * k), round(3 * k)
    img[y0:y0 + dh, x0:x0 + dw, 0] = 255
    plain, zoomed = dets[False].detect_small(img), dets[True].detect_small(img)
    others = [0, 1, 2, 4, 5, 6]
    np.testing.assert_array_equal(zoomed[others], plain[others])
    assert plain[TIP].max() == 0 and zoomed[TIP].max() > 0.3  # found in the zoom only
    assert (zoomed[TIP] >= plain[TIP]).all()  # the larger of the two passes
    box = dets[True].zoom_box(plain)
    assert box is not None and box[2] == ZOOM_MAX
    left, top, z = box
    assert left <= x0 / k / 2 and left + 160 / z >= (x0 + dw) / k / 2  # the dot is in
    assert top <= y0 / k / 2 and top + 120 / z >= (y0 + dh) / k / 2
    # both passes put the dot where it is (heat-map px: centre (u + 0.5) / 2 - 0.5)
    centre = ((x0 + dw / 2) / k / 2 - 0.5, (y0 + dh / 2) / k / 2 - 0.5)
    def centroid(m: np.ndarray) -> tuple[float, float]:
        i, j = np.mgrid[:m.shape[0], :m.shape[1]]
        return float((j * m).sum() / m.sum()), float((i * m).sum() / m.sum())

    np.testing.assert_allclose(centroid(plain[6]), centre, atol=0.1)
    np.testing.assert_allclose(centroid(zoomed[TIP]), centre, atol=0.3)
    # a turbine across the photo is not zoomed: the maps are the first pass's
    img[10:20, 10:20, 0] = 255
    img[220 * h // 240:230 * h // 240, 300 * w // 320:310 * w // 320, 0] = 255
    again = dets[True].detect_small(img)
    assert dets[True].zoom_box(again) is None
    np.testing.assert_array_equal(again, dets[False].detect_small(img))
    # nothing above the threshold: nothing to zoom
    assert dets[True].zoom_box(np.zeros((7, 120, 160), np.float32)) is None


def test_pool_gives_one_detectors_maps_in_order(detector: HeatmapDetector,
                                                 held_out_samples: list) -> None:
    from turbinefit.io.images import resize_image

    fars = [np.pad(resize_image(s.image, 160, 120), ((60, 60), (80, 80), (0, 0)), mode="edge")
            for s in held_out_samples]  # zoomed: the second pass runs on the pool's threads too
    far = next(f for f in fars if detector.zoom_box(detector.detect_small(f)) is not None)
    images = [s.image for s in held_out_samples] + [far, held_out_samples[1].image[:, ::-1].copy()]
    pool = DetectOptions().pool(workers=2)
    assert pool.workers == 2 and pool.detector.zoom and pool.detector.flip
    assert detector.zoom_box(detector.detect_small(far)) is not None
    threads: set[str] = set()

    def detect(det: HeatmapDetector, im: np.ndarray) -> np.ndarray:
        threads.add(threading.current_thread().name)
        return det.detect(im)

    got = list(pool.map(detect, images))
    assert len(got) == len(images) and len(threads) == 2
    for im, maps in zip(images, got, strict=True):
        np.testing.assert_array_equal(maps, detector.detect(im))  # bit for bit, in order
    # one worker: the calling thread, the same maps
    one = DetectorPool(workers=1, options=DetectOptions(zoom=False))
    assert list(one.map(lambda d, i: threading.current_thread().name, [0])) == [
        threading.current_thread().name]
    np.testing.assert_array_equal(next(one.map(lambda d, im: d.detect(im), images[:1])),
                                  HeatmapDetector(threads=1, zoom=False).detect(images[0]))
    for bad in (0, -1):
        with pytest.raises(ValueError, match="at least 1"):
            DetectorPool(workers=bad)
        with pytest.raises(ValueError, match="at least 1"):
            HeatmapDetector(threads=bad)


def test_pool_raises_the_first_error_in_order_and_starts_nothing_after_it() -> None:
    pool = DetectorPool(workers=2, options=DetectOptions(zoom=False))
    started: list[int] = []
    lock = threading.Lock()
    release = threading.Event()

    def work(det: HeatmapDetector, i: int) -> int:
        with lock:
            started.append(i)
        if i == 3:
            raise KeyError("photo 3")
        if i == 4:  # a later failure, while 3's is pending: 3's is the one raised
            release.wait(5)
            raise ValueError("photo 4")
        return 10 * i

    results = []
    with pytest.raises(KeyError, match="photo 3"):
        for r in pool.map(work, range(100)):
            results.append(r)
            if r == 20:
                release.set()
    assert results == [0, 10, 20]
    # at most 2 x 2 items are worked on ahead of the one yielded
    assert max(started) <= 3 + 2 * pool.workers and len(started) < 100
    # stopping early starts nothing more
    started.clear()
    it = pool.map(work, range(5, 100))
    assert next(it) == 50
    it.close()
    assert len(started) <= 1 + 2 * pool.workers


@pytest.fixture(scope="module")
def large_renders() -> list:
    """Four held-out renders at 1280 x 960 (a seed never used for training) with the hub in
    view; their points in photo pixels."""
    from turbinefit.sim.dataset import DatasetSpec, render_sample

    spec = DatasetSpec(1, seed=987_654, width=640, height=480, closeup_fraction=0.0)
    out, i = [], 0
    while len(out) < 4:
        s = render_sample(spec, i)
        if s.visible[2] and s.visible[1]:
            out.append((s.image, (s.points + 0.5) * 2 - 0.5, s.visible))
        i += 1
    return out


def test_refine_places_points_nearer_the_truth(large_renders: list) -> None:
    """Coarse to fine on 1280 x 960 renders: the refined maps' blade tips and hub lie
    nearer the rendered truth than the first pass's, the tips within a fraction of a
    first-pass heat-map pixel (8 photo px)."""
    plain = HeatmapDetector(threads=1)
    fine = HeatmapDetector(threads=1, refine=True)
    assert fine.refine_zoom(1280, 960) == 4 and fine.photo_width == 1280
    hub: list[list[float]] = [[], []]
    tips: list[list[float]] = [[], []]
    for image, pts, visible in large_renders:
        for k, det in enumerate((plain, fine)):
            maps = det.detect_small(image)
            f = 1280 / maps.shape[2]  # photo px per map px
            u, v, _ = peak(maps[2])
            hub[k].append(float(np.hypot((u + 0.5) * f - 0.5 - pts[2, 0],
                                         (v + 0.5) * f - 0.5 - pts[2, 1])))
            found = [refine(maps[TIP], int(i), int(j))[:2]
                     for j, i in local_maxima(maps[TIP], det.info.tip_threshold)]
            uv = (np.array(found).reshape(-1, 2) + 0.5) * f - 0.5
            tips[k] += [float(np.hypot(*(uv - pts[t]).T).min())
                        for t in (3, 4, 5) if visible[t] and len(uv)]
    first = [e for e in tips[0] if e < 16]
    refined = [e for e in tips[1] if e < 16]
    assert len(first) >= 4 and len(refined) >= len(first) - 1, (tips[0], tips[1])
    assert np.median(refined) < 0.6 * np.median(first), (first, refined)
    assert np.median(refined) < 3.0, refined  # photo px: under half a first-pass map pixel
    assert np.median(hub[1]) < np.median(hub[0]), hub


def test_refine_moves_only_its_points_near_where_they_were(large_renders: list) -> None:
    """The refined maps agree with the first pass: the other channels are the same, and a
    refined channel changes only around the first pass's points (so never outside the
    crops), whose peaks move by at most the gate, keeping their height."""
    plain = HeatmapDetector(threads=1)
    fine = HeatmapDetector(threads=1, refine=True)
    moved = 0
    for image, _, _ in large_renders[:2]:
        a, b = plain.detect_small(image), fine.detect_small(image)
        others = [c for c in range(7) if c not in REFINE_CHANNELS]
        np.testing.assert_array_equal(a[others], b[others])
        assert np.isfinite(b).all() and b.min() >= 0 and b.max() <= 1
        for c in REFINE_CHANNELS:
            thr = plain.info.tip_threshold if c == TIP else plain.info.threshold
            before = ([refine(a[c], int(v), int(u))[:2] for u, v in local_maxima(a[c], thr)]
                      if c == TIP else [peak(a[c])[:2]])
            near = np.zeros(a[c].shape, bool)
            for u, v in before:
                near[max(int(v) - REFINE_RADIUS, 0):int(v) + REFINE_RADIUS + 2,
                     max(int(u) - REFINE_RADIUS, 0):int(u) + REFINE_RADIUS + 2] = True
            assert not (a[c] != b[c])[~near].any(), c  # nothing changes away from a point
            for u, v in before:
                if a[c][int(v), int(u)] <= thr:
                    continue
                p0 = refine(a[c], int(v), int(u))
                i, j = np.unravel_index(np.argmax(np.where(near, b[c], 0)
                                                  * (np.hypot(*np.mgrid[:120, :160][::-1]
                                                              - np.array([u, v])[:, None, None])
                                                     <= 2)), b[c].shape)
                p1 = refine(b[c], int(i), int(j))
                d = np.hypot(p1[0] - p0[0], p1[1] - p0[1])
                assert d <= REFINE_GATE + 0.1, (c, p0, p1)
                # the blob keeps its height (its samples' maximum moves with the phase)
                assert 0.8 * p0[2] < p1[2] < 1.3 * p0[2], (c, p0, p1)
                moved += d > 0.05
    assert moved >= 2


@pytest.mark.parametrize("size", [(160, 120), (320, 240), (600, 450)])
def test_refine_leaves_photos_under_twice_the_input_alone(size: tuple[int, int],
                                                          held_out_samples: list) -> None:
    from turbinefit.io.images import resize_image

    plain = HeatmapDetector(threads=1)
    fine = DetectOptions(refine=True).detector(threads=1)
    assert fine.refine_zoom(*size) == 1
    image = resize_image(held_out_samples[0].image, *size)
    np.testing.assert_array_equal(plain.detect(image), fine.detect(image))


def test_a_signal_while_onnxruntime_imports_is_the_signal(monkeypatch: pytest.MonkeyPatch) -> None:
    # onnxruntime's C++ module turns an exception raised during its initialisation (a
    # signal's handler runs there) into "ImportError: initialization failed"
    import builtins
    import signal

    from turbinefit import detect
    from turbinefit.errors import Interrupted

    real_import = builtins.__import__

    def failing(name: str, *args: object, **kwargs: object) -> object:
        if name == "onnxruntime":
            raise ImportError("initialization failed") from Interrupted(signal.SIGTERM)
        return real_import(name, *args, **kwargs)

    monkeypatch.delitem(sys.modules, "onnxruntime", raising=False)
    monkeypatch.setattr(builtins, "__import__", failing)
    with pytest.raises(Interrupted) as caught:
        detect._onnxruntime()
    assert caught.value.signum == signal.SIGTERM

    def missing(name: str, *args: object, **kwargs: object) -> object:
        if name == "onnxruntime":
            raise ImportError("No module named 'onnxruntime'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", missing)
    with pytest.raises(ImportError, match="No module named"):
        detect._onnxruntime()
