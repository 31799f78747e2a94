"""Image files (turbinefit.io.images): PNG round trips and modes, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from turbinefit.errors import InputError
from turbinefit.io.images import check_image, list_images, read_image, write_png


def test_png_round_trip_and_modes(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, size=(7, 9, 3), dtype=np.uint8)
    write_png(tmp_path / "a.png", img)
    np.testing.assert_array_equal(read_image(tmp_path / "a.png"), img)
    assert check_image(tmp_path / "a.png") == (9, 7)
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
