"""Contact sheets: a grid of photos (with their overlays) and a caption under each, as one
PNG image (Pillow only, no matplotlib), e.g. the worst photos of ``turbinefit evaluate``."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw

#: Width [px] of each tile of a contact sheet; the caption band's height.
TILE_WIDTH, CAPTION_PX = 320, 28


def draw_outline(image: NDArray[np.uint8], outline: NDArray[np.bool_],
                 colour: tuple[int, int, int] = (255, 255, 255)) -> NDArray[np.uint8]:
    """``image`` (H, W, 3) with the border pixels of the boolean region ``outline`` (any
    size; enlarged to the image's, nearest) painted in ``colour``."""
    h, w = image.shape[:2]
    big = np.asarray(Image.fromarray(outline.astype(np.uint8) * 255).resize(
        (w, h), Image.Resampling.NEAREST)) > 0
    edge = big.copy()
    edge[1:-1, 1:-1] &= ~(big[:-2, 1:-1] & big[2:, 1:-1] & big[1:-1, :-2] & big[1:-1, 2:])
    out = image.copy()
    out[edge] = colour
    return out


def contact_sheet(images: Sequence[NDArray[np.uint8]], captions: Sequence[str],
                  columns: int = 4) -> NDArray[np.uint8]:
    """One RGB image: ``images`` resized to :data:`TILE_WIDTH` px wide (each tile as high
    as the tallest), ``columns`` a row, each with its caption below in white on black."""
    tiles = []
    for img in images:
        h, w = img.shape[:2]
        th = max(1, round(h * TILE_WIDTH / w))
        tiles.append(Image.fromarray(img).resize((TILE_WIDTH, th), Image.Resampling.BILINEAR))
    cols = max(1, min(columns, len(tiles)))
    rows = max(1, -(-len(tiles) // cols))
    tile_h = max((t.height for t in tiles), default=1) + CAPTION_PX
    sheet = Image.new("RGB", (cols * TILE_WIDTH, rows * tile_h))
    draw = ImageDraw.Draw(sheet)
    for k, (tile, text) in enumerate(zip(tiles, captions, strict=True)):
        x, y = (k % cols) * TILE_WIDTH, (k // cols) * tile_h
        sheet.paste(tile, (x, y))
        draw.text((x + 4, y + tile.height + 4), text[:52], fill=(255, 255, 255))
    return np.asarray(sheet)
