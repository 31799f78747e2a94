"""Heat-map sources of the jobs (turbinefit.jobs.sources): photos detected at the fit width."""

from __future__ import annotations

from pathlib import Path

import pytest

from turbinefit.cli import main


def test_wide_photos_are_detected_at_the_fit_width(tmp_path: Path) -> None:
    from turbinefit.io.flight_folder import read_flight, read_flight_folder
    from turbinefit.jobs.sources import FIT_DETECT_WIDTH, PhotoHeatmaps

    flight = tmp_path / "f"
    assert main(["simulate", str(flight), "--keyframes", "3", "--seed", "1", "--width", "640",
                 "--height", "480", "--images", "--quiet"]) == 0
    folder = read_flight_folder(flight)
    source = PhotoHeatmaps(folder, threads=1)
    f = folder.flight(source.stack(), source.camera)
    assert (f.camera.width, f.camera.height) == (FIT_DETECT_WIDTH, 240)
    assert (f.heatmaps.height, f.heatmaps.width) == (240, FIT_DETECT_WIDTH)
    full = read_flight_folder(flight)
    assert read_flight(flight).camera == f.camera  # the simulated maps are at 320 x 240 too
    assert f.camera.fx == pytest.approx(full.camera.fx / 2)
    assert f.camera.cx == pytest.approx((full.camera.cx + 0.5) / 2 - 0.5)


def test_jpeg_photos_are_decoded_at_the_detector_width(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    import numpy as np
    from PIL import Image

    from turbinefit.errors import InputError
    from turbinefit.io import images
    from turbinefit.io.flight_folder import read_flight_folder
    from turbinefit.jobs import sources
    from turbinefit.jobs.sources import PhotoHeatmaps

    flight = tmp_path / "f"
    assert main(["simulate", str(flight), "--keyframes", "2", "--seed", "2", "--width", "1280",
                 "--height", "960", "--images", "--quiet"]) == 0
    for p in sorted((flight / "images").iterdir()):
        Image.open(p).save(p.with_suffix(".jpg"), quality=93)
        p.unlink()
    asked = []

    def read(path, reduce_to=None):
        asked.append(reduce_to)
        return images.read_image(path, reduce_to)

    monkeypatch.setattr(sources, "read_image", read)
    from turbinefit.detect import DetectOptions

    source = PhotoHeatmaps(read_flight_folder(flight), threads=1,
                           options=DetectOptions(refine=False))
    assert "coarse to fine" not in source.description
    maps = source.keyframe(1)
    assert asked == [(640, 480)] and maps.shape == (7, 240, 320)
    det = source._detector
    assert det is not None and det.photo_width == 640
    # by default coarse to fine: decoded at 1280 px, the points placed on its pixels
    fine = PhotoHeatmaps(read_flight_folder(flight), threads=1)
    assert fine.options.refine and "coarse to fine" in fine.description
    refined = fine.keyframe(1)
    assert asked[-1] == (1280, 960) and fine._detector is not None
    assert fine._detector.photo_width == 1280 and fine._detector.refine_zoom(1280, 960) == 4
    assert "coarse to fine" in fine.description  # as the detector found it
    assert np.abs(refined[[0, 4, 5, 6]] - maps[[0, 4, 5, 6]]).max() < 0.25
    full = det.detect(images.read_image(source.paths[1]), size=(320, 240))
    assert np.abs(maps - full).max() < 0.25  # decoded at 640 px: the same maps but rounding
    hub = [np.unravel_index(np.argmax(m[2]), m[2].shape) for m in (maps, full)]
    assert np.abs(np.subtract(*hub)).max() <= 1
    # a photo of another size than camera.yaml is refused before any detection
    Image.new("RGB", (640, 480)).save(source.paths[0])
    with pytest.raises(InputError, match=r"0\.000000\.jpg: photo is 640x480 but camera.yaml "
                       r"is 1280x960"):
        PhotoHeatmaps(read_flight_folder(flight), threads=1)


def test_fit_from_photos_draws_its_reprojections_over_the_photos(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``fit --from-images``: the reprojection figure is drawn over the keyframes' photos
    (:func:`source_photos`), at most 640 px wide; heat-map files give no photos."""
    import numpy as np

    from turbinefit import plots
    from turbinefit.io.flight_folder import read_flight_folder
    from turbinefit.jobs.sources import FileHeatmaps, PhotoHeatmaps, source_photos

    flight = tmp_path / "f"
    assert main(["simulate", str(flight), "--keyframes", "6", "--seed", "2", "--width", "800",
                 "--height", "600", "--images", "--quiet"]) == 0
    folder = read_flight_folder(flight)
    photo = source_photos(PhotoHeatmaps(folder, threads=1))
    assert photo is not None and photo(2).shape == (480, 640, 3)
    assert source_photos(FileHeatmaps(folder)) is None
    drawn: list[np.ndarray] = []
    real = plots.plot_reprojections

    def spy(*args, **kw):  # type: ignore[no-untyped-def]
        assert kw["photo"] is not None
        drawn.extend(kw["photo"](k) for k in kw["keyframes"])
        return real(*args, **kw)

    monkeypatch.setattr(plots, "plot_reprojections", spy)
    assert main(["fit", str(flight), "--out", str(tmp_path / "fit"), "--from-images"]) in (0, 3)
    assert drawn and all(d.shape == (480, 640, 3) for d in drawn)
    assert (tmp_path / "fit" / "reprojections.png").stat().st_size > 0
