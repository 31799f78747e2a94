"""Image files: reading photos with clear errors, writing PNGs atomically, resizing.

Images are ``uint8`` RGB arrays (H, W, 3); element ``[i, j]`` is pixel ``u = j, v = i``
(pixel (0, 0) is the centre of the top-left pixel, as everywhere in turbinefit). Pillow
decodes and encodes (PNG, JPEG and whatever else it reads); grey, palette, 16-bit and
alpha images are converted to 8-bit RGB, and EXIF orientation is applied, so a photo is
seen the way a viewer shows it.

**JPEG photos whatever their structure.** Many cameras (most DJI drones: Mavic, Zenmuse
H20/H20T/H20N, M30T ...) write an ordinary JPEG followed by a second, preview image, announced
by a Multi-Picture Format (MPF) APP2 segment; Pillow opens such a file as format ``MPO``
with two frames. Every reader here (:func:`open_photo`, and through it :func:`read_image`,
:func:`image_size`, :func:`check_image` and :func:`turbinefit.io.dji.read_dji_photo`)
takes it as the JPEG it is: metadata (EXIF, XMP) from the primary image, pixels from the
first frame. Other APP segments (a thermal camera's raw data, FLIR records) are skipped.

A JPEG photo that is only used at a reduced size is decoded at that size:
``read_image(path, reduce_to=(w, h))`` asks Pillow for a DCT-scaled decode
(:meth:`PIL.Image.Image.draft`: 1/2, 1/4 or 1/8 of the size, the smallest scale that is
still at least ``w`` x ``h``; a 20 MP JPEG decodes several times faster at 1/4, in a
sixteenth of the memory) and then resizes exactly to ``w`` x ``h`` (:func:`resize_image`).
Other formats (PNG) have no such decode and are read at full size as they are, so their
pixels do not change. :func:`image_size` gives the upright size from the header, to
choose ``reduce_to`` with
(:func:`turbinefit.geometry.camera.reduced_size`).

Resizing (:func:`resize_image`) uses Pillow's resampling, which keeps pixel centres
aligned (the convention of :meth:`turbinefit.geometry.camera.PinholeCamera.resized`) and
low-pass filters when it shrinks (an area-weighted triangle filter), so a downsized photo
shows no aliasing; heat-maps are resized the same way by
:func:`turbinefit.heatmaps.resize.resize_maps`.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import warnings
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageOps, UnidentifiedImageError

from turbinefit.errors import InputError
from turbinefit.io.atomic import StrPath, write_bytes_atomic
from turbinefit.io.limits import MAX_IMAGE_PIXELS, check_image_size, open_input

#: File name suffixes taken as images when a folder is listed (lower case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
#: Pillow's formats of a JPEG file: plain, or with MPF images appended (``MPO``).
JPEG_FORMATS = frozenset({"JPEG", "MPO"})
#: What a file Pillow cannot identify is called, by default.
NOT_AN_IMAGE = "not an image file (Pillow cannot identify it)"

# Pillow's own bomb guard (89 M pixels by default) is only a backstop above our limit,
# MAX_IMAGE_PIXELS (checked with our message from the header): it warns at 1 G pixels,
# which _image_errors turns into an error, and refuses beyond 2 G pixels.
Image.MAX_IMAGE_PIXELS = 1_000_000_000

U8Image = NDArray[np.uint8]


@contextlib.contextmanager
def _image_errors(p: Path, unidentified: str = NOT_AN_IMAGE) -> Iterator[None]:
    """Turn Pillow's and the OS's failures on image file ``p`` into one-line InputErrors
    (``unidentified``: the message for a file Pillow cannot identify)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            yield
    except FileNotFoundError as e:
        raise InputError("image file not found", path=p) from e
    except IsADirectoryError as e:
        raise InputError("is a directory, not an image file", path=p) from e
    except UnidentifiedImageError as e:
        raise InputError(unidentified, path=p) from e
    except OSError as e:
        raise InputError(f"cannot read image: {e.strerror or e}", path=p) from e
    except (Image.DecompressionBombWarning, Image.DecompressionBombError) as e:
        raise InputError(f"image larger than the {MAX_IMAGE_PIXELS / 1e6:g} MP limit ({e})",
                         path=p) from e
    except (ValueError, SyntaxError) as e:
        raise InputError(f"cannot decode image: {e}", path=p) from e


@contextlib.contextmanager
def open_photo(path: StrPath, min_side: bool = False, jpeg_only: str | None = None,
               unidentified: str = NOT_AN_IMAGE) -> Iterator[Image.Image]:
    """The one way turbinefit opens an image file: lazily (header only), errors as
    one-line InputErrors naming the file; only a regular file
    (:func:`~turbinefit.io.limits.open_input`), of at most
    :data:`~turbinefit.io.limits.MAX_IMAGE_PIXELS` pixels (and, with ``min_side``, at
    least :data:`~turbinefit.io.limits.MIN_IMAGE_SIDE` px a side) by its header, before
    any pixel is decoded. A JPEG with MPF images appended is its first frame (module
    docstring).

    Args:
        jpeg_only: if given, anything but a JPEG (:data:`JPEG_FORMATS`) is refused with
            this message followed by `` (FORMAT image)``.
        unidentified: the message for a file Pillow cannot identify.
    """
    p = Path(path)
    with (open_input(p, missing="image file not found") as f, _image_errors(p, unidentified),
          Image.open(f) as im):
        if jpeg_only is not None and im.format not in JPEG_FORMATS:
            raise InputError(f"{jpeg_only} ({im.format or 'unknown'} image)", path=p)
        if getattr(im, "n_frames", 1) > 1:
            im.seek(0)  # the primary image of an MPF file (Pillow opens it there too)
        w, h = int(im.width), int(im.height)
        if w * h > MAX_IMAGE_PIXELS or min_side:
            check_image_size(w, h, p, what="image")
        yield im


def is_jpeg(im: Image.Image) -> bool:
    """Whether an opened image is a JPEG (with or without MPF images appended)."""
    return im.format in JPEG_FORMATS


#: EXIF orientations that swap width and height (a rotation by 90 degrees).
_TRANSPOSING = frozenset({5, 6, 7, 8})


def _swaps_axes(im: Image.Image) -> bool:
    """Whether the image's EXIF orientation turns it by 90 degrees."""
    try:
        return int(im.getexif().get(0x0112, 1)) in _TRANSPOSING
    except Exception:  # a broken EXIF block: exif_transpose ignores it too
        return False


def read_image(path: StrPath, reduce_to: tuple[int, int] | None = None) -> U8Image:
    """Read an image file as RGB uint8 (H, W, 3), upright (EXIF orientation applied).

    ``reduce_to`` = (width, height): a JPEG is decoded at the smallest DCT scale (1/1,
    1/2, 1/4, 1/8) that is at least that large and resized to exactly that size (module
    docstring); other formats are read at their full size. None = full size.

    Raises:
        InputError: naming the file if it is missing, not a regular file, unreadable, not
            an image Pillow can decode (also a truncated file) or, by its header, larger
            than :data:`~turbinefit.io.limits.MAX_IMAGE_PIXELS` (refused before decoding).
    """
    p = Path(path)
    with open_photo(p) as im:
        jpeg = reduce_to is not None and is_jpeg(im)
        if reduce_to is not None and jpeg:
            w, h = (reduce_to[1], reduce_to[0]) if _swaps_axes(im) else reduce_to
            im.draft("RGB", (int(w), int(h)))
        im.load()
        upright: Image.Image = ImageOps.exif_transpose(im) or im
        rgb = upright.convert("RGB")
        if reduce_to is not None and jpeg and rgb.size != tuple(reduce_to) and min(rgb.size):
            # as resize_image does, without a round trip through numpy
            rgb = rgb.resize((int(reduce_to[0]), int(reduce_to[1])), Image.Resampling.BILINEAR)
    arr = np.asarray(rgb, dtype=np.uint8)
    if arr.ndim != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InputError(f"image has no pixels (shape {arr.shape})", path=p)
    return np.ascontiguousarray(arr)


def image_size(path: StrPath) -> tuple[int, int]:
    """(width, height) of an image file as :func:`read_image` returns it (upright: EXIF
    orientation applied), from its header, without decoding the pixels.

    Raises:
        InputError: as :func:`read_image`, for a missing file or one that is not an image.
    """
    p = Path(path)
    with open_photo(p, min_side=True) as im:
        w, h = int(im.width), int(im.height)
        return (h, w) if _swaps_axes(im) else (w, h)


def check_image(path: StrPath) -> tuple[int, int]:
    """(width, height) of an image file from its header, without decoding the pixels.

    Raises:
        InputError: as :func:`read_image`, for a missing file or one that is not an image.
    """
    p = Path(path)
    with open_photo(p, min_side=True) as im:
        return int(im.width), int(im.height)


def encode_png(image: U8Image, compress_level: int = 3) -> bytes:
    """PNG bytes of an RGB uint8 (H, W, 3) image (zlib ``compress_level`` 0-9: 1 is
    fastest, a few per cent larger than 3)."""
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image, dtype=np.uint8), "RGB").save(
        buf, format="PNG", compress_level=compress_level)
    return buf.getvalue()


def encode_jpeg(image: U8Image, quality: int = 85) -> bytes:
    """JPEG bytes of an RGB uint8 (H, W, 3) image (``quality`` 1-95, Pillow's scale)."""
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image, dtype=np.uint8), "RGB").save(
        buf, format="JPEG", quality=int(quality))
    return buf.getvalue()


def write_png(path: StrPath, image: U8Image, fsync: bool = True) -> Path:
    """Write an RGB uint8 (H, W, 3) image as PNG, atomically."""
    return write_bytes_atomic(path, encode_png(image), fsync=fsync)


def to_grey(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Grey levels (H, W) uint8 of an RGB uint8 (H, W, 3) image (ITU-R 601 luma, as
    Pillow's ``convert("L")``); a grey image is returned as it is."""
    if image.ndim == 2:
        return image
    luma = image.astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
    return np.round(luma).clip(0, 255).astype(np.uint8)


def resize_image(image: U8Image, width: int, height: int,
                 box: tuple[float, float, float, float] | None = None) -> U8Image:
    """An RGB uint8 image resized to ``width`` x ``height`` (bilinear, antialiased).

    ``box`` = (left, top, right, bottom) [px, pixel edges: (0, 0) is the top-left
    corner of the top-left pixel]: resize that part of the image only (a crop, by
    fractional pixels if need be); None = the whole image.
    """
    if box is None and image.shape[1] == width and image.shape[0] == height:
        return image
    im = Image.fromarray(np.ascontiguousarray(image, dtype=np.uint8), "RGB")
    return np.asarray(im.resize((int(width), int(height)), Image.Resampling.BILINEAR, box=box))


def list_images(inputs: Iterable[Path],
                suffixes: tuple[str, ...] = IMAGE_SUFFIXES) -> list[Path]:
    """Image files named by ``inputs``: files as given, folders listed (not recursively,
    lower-cased suffixes in ``suffixes``, sorted by name).

    A symbolic link among them is followed; one that leads nowhere (dangling, or a loop)
    is an error naming it, never skipped in silence.

    Raises:
        InputError: for a path that does not exist, a folder with no image files, or a
            symbolic link that cannot be followed.
    """
    out: list[Path] = []
    for p in inputs:
        if p.is_dir():
            found = []
            for q in sorted(p.iterdir()):
                if q.suffix.lower() not in suffixes:
                    continue
                _check_link(q)
                if q.is_file():
                    found.append(q)
            if not found:
                raise InputError(f"no image files ({', '.join(suffixes)}) in folder",
                                 path=p)
            out.extend(found)
        elif p.exists():
            out.append(p)
        else:
            _check_link(p)
            raise InputError("no such file or folder", path=p)
    return out


def _check_link(p: Path) -> None:
    """Refuse a symbolic link that leads nowhere (its target missing, or a loop)."""
    if not p.is_symlink():
        return
    try:
        p.resolve(strict=True)
    except RuntimeError:  # Python < 3.13: a loop
        raise InputError("symbolic link loop", path=p) from None
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise InputError("symbolic link loop", path=p) from None
        raise InputError(f"symbolic link to {os.readlink(p)!r}, which does not exist",
                         path=p) from None
