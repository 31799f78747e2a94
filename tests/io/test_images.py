"""Image files (turbinefit.io.images): PNG round trips and modes, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from turbinefit.errors import InputError
from turbinefit.geometry.camera import reduced_size
from turbinefit.io.images import (
    check_image,
    image_size,
    list_images,
    read_image,
    resize_image,
    write_png,
)


def test_png_round_trip_and_modes(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, size=(7, 9, 3), dtype=np.uint8)
    write_png(tmp_path / "a.png", img)
    np.testing.assert_array_equal(read_image(tmp_path / "a.png"), img)
    with pytest.raises(InputError, match=r"a\.png: image is 9x7 px; each side must be at least 24"):
        check_image(tmp_path / "a.png")  # a photo to detect on: too small
    write_png(tmp_path / "b.png", np.zeros((25, 30, 3), np.uint8))
    assert check_image(tmp_path / "b.png") == (30, 25)
    Image.fromarray(img[..., 0]).save(tmp_path / "grey.png")
    Image.fromarray(np.dstack([img, img[..., :1]])).save(tmp_path / "rgba.png")
    for name in ("grey.png", "rgba.png"):
        out = read_image(tmp_path / name)
        assert out.shape == (7, 9, 3) and out.dtype == np.uint8
    # EXIF orientation 6 (rotate 90 degrees clockwise for display) is applied
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(img).save(tmp_path / "rot.jpg", exif=exif, quality=95)
    assert read_image(tmp_path / "rot.jpg").shape == (9, 7, 3)


def test_jpeg_decoded_at_reduced_size(tmp_path: Path) -> None:
    # a smooth 2000 x 1500 picture: a DCT-scaled decode matches the full decode resized
    v, u = np.mgrid[0:1500, 0:2000].astype(np.float32)
    img = np.dstack([u / 2000 * 255, v / 1500 * 255, 128 + 100 * np.sin(u / 90) * np.cos(v / 70)])
    Image.fromarray(img.astype(np.uint8)).save(tmp_path / "big.jpg", quality=92)
    assert image_size(tmp_path / "big.jpg") == (2000, 1500)
    assert reduced_size(2000, 1500, 320) == (320, 240)
    assert reduced_size(200, 150, 320) == (200, 150)
    small = read_image(tmp_path / "big.jpg", reduce_to=(320, 240))
    assert small.shape == (240, 320, 3) and small.dtype == np.uint8
    full = resize_image(read_image(tmp_path / "big.jpg"), 320, 240)
    assert np.abs(small.astype(int) - full.astype(int)).mean() < 2.0
    with Image.open(tmp_path / "big.jpg") as im:  # Pillow decodes it at 1/4 (500 x 375)
        im.draft("RGB", (320, 240))
        assert im.size == (500, 375)
    # PNG: no reduced decode, the full image as it is
    write_png(tmp_path / "big.png", img.astype(np.uint8))
    np.testing.assert_array_equal(read_image(tmp_path / "big.png", reduce_to=(320, 240)),
                                  img.astype(np.uint8))
    # EXIF orientation 6: the size asked for is the upright one
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(img.astype(np.uint8)).save(tmp_path / "rot.jpg", exif=exif, quality=92)
    assert image_size(tmp_path / "rot.jpg") == (1500, 2000)
    assert read_image(tmp_path / "rot.jpg", reduce_to=(150, 200)).shape == (200, 150, 3)


def test_bad_files(tmp_path: Path) -> None:
    (tmp_path / "x.png").write_text("text")
    with pytest.raises(InputError, match=r"x\.png: not an image"):
        read_image(tmp_path / "x.png")
    with pytest.raises(InputError, match="not found"):
        check_image(tmp_path / "none.png")
    with pytest.raises(InputError, match="no image files"):
        (tmp_path / "d").mkdir()
        list_images([tmp_path / "d"])
    write_png(tmp_path / "d" / "b.png", np.zeros((2, 2, 3), np.uint8))
    (tmp_path / "d" / "notes.txt").write_text("x")
    assert list_images([tmp_path / "d"]) == [tmp_path / "d" / "b.png"]
