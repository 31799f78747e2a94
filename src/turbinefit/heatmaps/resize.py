"""Resizing heat-maps: float maps (C, H, W) to another pixel size.

Bilinear with pixel centres aligned (the convention of
:meth:`turbinefit.geometry.camera.PinholeCamera.resized`), low-pass filtered when it
shrinks (Pillow's area-weighted triangle filter), one channel at a time. Pillow is
imported when maps are resized, not with the package.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def resize_maps(maps: NDArray[np.float32], width: int, height: int) -> NDArray[np.float32]:
    """Float maps (C, H, W) resized to (C, ``height``, ``width``), bilinear, per channel."""
    if maps.shape[2] == width and maps.shape[1] == height:
        return np.ascontiguousarray(maps, dtype=np.float32)
    from PIL import Image

    out = np.empty((maps.shape[0], int(height), int(width)), dtype=np.float32)
    for c in range(maps.shape[0]):
        im = Image.fromarray(np.ascontiguousarray(maps[c], dtype=np.float32), "F")
        out[c] = np.asarray(im.resize((int(width), int(height)), Image.Resampling.BILINEAR))
    return out
