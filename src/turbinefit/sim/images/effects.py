"""Per-frame camera effects on a rendered image: auto-exposure, white balance, colour and
gamma jitter, vignetting, motion blur, defocus, sensor noise, tone curve and a JPEG round
trip, with strengths drawn up to a scene's :class:`~turbinefit.sim.images.scene.CameraEffects`.
"""

from __future__ import annotations

import io
import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from PIL import Image
from scipy import ndimage
from scipy.special import ndtri

from turbinefit.sim.images.arrays import F32
from turbinefit.sim.images.scene import CameraEffects

#: Standard normal quantiles of 65536 equal-probability bins: indexing with uniform 16-bit
#: integers draws (quantised) Gaussian sensor noise ~3x faster than ``standard_normal``.
_NORMAL_TABLE = ndtri((np.arange(65536) + 0.5) / 65536).astype(np.float32)
#: Tone curve input resolution: intensities 0..2 in steps of 1/_TONE_STEPS.
_TONE_STEPS = 1024


@lru_cache(maxsize=64)
def _tone_lut(gamma: float, contrast: float) -> NDArray[np.uint8]:
    """uint8 output of intensities ``k / _TONE_STEPS``: linear up to 0.8, then a soft
    shoulder (highlights roll off instead of clipping), then gamma and contrast."""
    x = np.arange(2 * _TONE_STEPS + 1) / _TONE_STEPS
    y = np.where(x < 0.8, x, 0.8 + 0.2 * (1.0 - np.exp(-(x - 0.8) / 0.2)))
    y = y**gamma
    y = (y - 0.5) * contrast + 0.5
    return np.clip(y * 255.0 + 0.5, 0.0, 255.0).astype(np.uint8)


def _motion_blur(img: F32, length: float, angle: float) -> F32:
    """(3, H, W) averaged over shifted copies along a line of ``length`` px."""
    n = max(2, math.ceil(length) + 1)
    pad = math.ceil(length / 2) + 2
    P = np.pad(img, ((0, 0), (pad, pad), (pad, pad)), mode="edge")
    h, w = img.shape[1:]
    out = np.zeros_like(img)
    for k in range(n):
        off = (k / (n - 1) - 0.5) * length
        dx, dy = off * math.cos(angle), off * math.sin(angle)
        ix, iy = math.floor(dx), math.floor(dy)
        fx, fy = dx - ix, dy - iy
        for oy, wy in ((iy, 1 - fy), (iy + 1, fy)):
            for ox, wx in ((ix, 1 - fx), (ix + 1, fx)):
                wgt = wx * wy
                if wgt < 1e-3:
                    continue
                out += np.float32(wgt / n) * P[:, pad + oy:pad + oy + h, pad + ox:pad + ox + w]
    return out


def apply_effects(img: F32, rn: F32, eff: CameraEffects, rng: np.random.Generator
                   ) -> NDArray[np.uint8]:
    """Per-frame camera effects on a (3, H, W) float32 image -> (H, W, 3) uint8."""
    h, w = img.shape[1:]
    u = rng.uniform(size=12)
    z = rng.normal(size=4)
    scale = 0.1 if u[0] < eff.clean_prob else 1.0
    # auto exposure towards a mid-grey mean, with jitter, and white balance
    lum = float(np.mean(img[:, ::4, ::4]))
    gain = (0.45 / max(lum, 0.05)) ** 0.6 * math.exp(scale * eff.exposure_sigma * z[0])
    wb = np.exp(scale * eff.white_balance_sigma * z[1:4])
    g = (gain * wb / wb.mean()).astype(np.float32)[:, None, None]
    vig = scale * eff.vignetting * u[1]
    if vig > 0.005:
        img = img * g * (1.0 - np.float32(vig) * rn.reshape(h, w))[None]
    else:
        img = img * g
    cj = scale * eff.colour_jitter
    sat = 1.0 + 1.5 * cj * (2 * u[2] - 1)
    if abs(sat - 1.0) > 0.02:
        grey = img.mean(axis=0, keepdims=True)
        img = grey + (img - grey) * np.float32(sat)
    blur = scale * eff.motion_blur_px * u[3]
    if blur > 0.3:
        img = _motion_blur(img, blur, float(u[4] * math.pi))
    sigma = scale * eff.defocus_px * u[5]
    if sigma > 0.2:
        img = ndimage.gaussian_filter(img, (0.0, sigma, sigma), truncate=2.5)
    noise = scale * eff.noise * u[6]
    if noise > 0.001:
        n = _NORMAL_TABLE[rng.integers(0, 65536, (3, h, w), dtype=np.uint16)]
        img = img + n * (np.float32(noise) * (0.5 + 0.5 * img))
    q = np.clip(img * np.float32(_TONE_STEPS), 0.0, 2 * _TONE_STEPS).astype(np.uint16)
    gamma = round(math.exp(cj * (2 * u[7] - 1)), 2)
    contrast = round(1.0 + cj * (2 * u[8] - 1), 2)
    out = np.ascontiguousarray(_tone_lut(gamma, contrast)[q].transpose(1, 2, 0))
    if eff.jpeg_quality is not None:
        lo, hi = eff.jpeg_quality
        quality = round(lo + (hi - lo) * u[9]) if scale == 1.0 else max(hi, 90)
        buf = io.BytesIO()
        Image.fromarray(out).save(buf, format="JPEG", quality=int(np.clip(quality, 1, 95)))
        buf.seek(0)
        with Image.open(buf) as im:
            out = np.asarray(im.convert("RGB"), dtype=np.uint8).copy()
    return out
