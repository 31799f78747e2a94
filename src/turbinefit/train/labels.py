"""Training samples from labelled real photos (COCO keypoints, :mod:`turbinefit.io.coco`).

A photo is scaled (bilinear, antialiased) so that it covers the model's input size
(``image_scale`` times the heat-map size ``width`` x ``height``) and centre-cropped to it
(a 4:3 photo is only scaled); the labelled keypoints follow the same transform (pixel
centres preserved) and the targets are drawn from them at the heat-map size by
:func:`turbinefit.heatmaps.targets.render_keypoint_heatmaps`: a blob per labelled point, a
ridge per model line whose two ends are labelled. Every labelled turbine of a photo is a
target.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from turbinefit.heatmaps.targets import render_keypoint_heatmaps
from turbinefit.io.coco import LabelledImage
from turbinefit.io.images import read_image, resize_image


def labelled_sample(item: LabelledImage, width: int, height: int, sigma_px: float,
                    image_scale: int = 1) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """(image (s height, s width, 3) uint8, targets (7, height, width) uint8 x 255),
    s = ``image_scale``; ``sigma_px`` at the heat-map size."""
    img = read_image(item.path)
    iw, ih = width * image_scale, height * image_scale  # the model's input size
    h0, w0 = img.shape[:2]
    item.check_size(w0, h0)
    s = max(iw / w0, ih / h0)
    sw, sh = max(iw, round(w0 * s)), max(ih, round(h0 * s))
    big = resize_image(img, sw, sh)
    x0, y0 = (sw - iw) // 2, (sh - ih) // 2
    crop = big[y0:y0 + ih, x0:x0 + iw]
    # pixel centre u maps to (u + 0.5) * (sw / w0) - 0.5 in the resized image, and u in
    # the crop to (u + 0.5) / image_scale - 0.5 in the heat-maps
    fx, fy = sw / w0, sh / h0
    uvs, labs = [], []
    for t in item.turbines:
        uv = np.stack([((t.uv[:, 0] + 0.5) * fx - x0) / image_scale - 0.5,
                       ((t.uv[:, 1] + 0.5) * fy - y0) / image_scale - 0.5], -1)
        uvs.append(uv)
        labs.append(t.visibility > 0)
    maps = render_keypoint_heatmaps(height, width, uvs, labs, sigma_px)
    return np.ascontiguousarray(crop), np.rint(maps * 255.0).astype(np.uint8)
